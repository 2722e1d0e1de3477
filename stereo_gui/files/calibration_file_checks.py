"""The checks of a calibration file before and while OpenCV's FileStorage reads it: a file too
large or nested too deeply for OpenCV's parser is refused before it is parsed, the parser's own
words are given instead of the binding's, and every node is read by its expected type with the
file's name in front of what is wrong (a CalibrationFileError)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import NoReturn

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.files.atomic import os_error_text


def parse_error(exc: BaseException) -> str:
    """The parser's own words ('line 3: Invalid or unsupported syntax'): the binding raises a
    SystemError whose text only names the binding, with OpenCV's error as its cause."""
    cause = exc.__cause__ or exc.__context__
    if isinstance(exc, SystemError) and isinstance(cause, cv2.error):
        exc = cause
    text = str(exc).strip()
    found = re.search(r"\((\d+)\): ([^']+)'?\s*$", text)
    if found:
        return f"line {found.group(1)}: {found.group(2).strip()}"
    return text.splitlines()[-1] if text else type(exc).__name__


MAX_FILE_BYTES = 4 << 20  # a calibration with a thousand pairs is a few hundred kB
MAX_NESTING = 64


def check_parsable(path: Path, where: str) -> None:
    """Refuse what would crash OpenCV's parser: it recurses per nesting level and a file with
    100,000 nested brackets overflows the C stack (a segmentation fault, not an error)."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise CalibrationFileError(f"{where} is {size} bytes: too large for a calibration")
        data = path.read_bytes()
    except OSError as exc:
        raise CalibrationFileError(f"{where} cannot be read: {os_error_text(exc)}") from None
    depth = deepest = 0
    quote = 0
    for byte in data:
        if quote:
            if byte == quote:
                quote = 0
        elif byte in (0x22, 0x27):  # " '
            quote = byte
        elif byte in (0x5B, 0x7B):  # [ {
            depth += 1
            deepest = max(deepest, depth)
        elif byte in (0x5D, 0x7D):  # ] }
            depth = max(0, depth - 1)
        elif byte == 0x0A:
            quote = 0
    indent = max((len(line) - len(line.lstrip(b" \t")) for line in data.splitlines()),
                 default=0)
    if deepest > MAX_NESTING or indent > 40 * MAX_NESTING:
        raise CalibrationFileError(f"{where} is nested too deeply to be a calibration file")


def open_filestorage(path: Path) -> cv2.FileStorage:
    if not path.exists():
        raise CalibrationFileError(f"calibration file {path} does not exist")
    if not path.is_file():
        raise CalibrationFileError(f"calibration file {path} is not a file")
    try:  # opened by Python first: OpenCV would call an unreadable file "not FileStorage"
        with open(path, "rb"):
            pass
    except OSError as exc:
        raise CalibrationFileError(f"calibration file {path} cannot be read: "
                                   f"{os_error_text(exc)}") from None
    check_parsable(path, f"calibration file {path}")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        raise CalibrationFileError(
            f"{path} is not an OpenCV FileStorage file ({parse_error(exc)})") from None
    if not fs.isOpened():
        raise CalibrationFileError(f"{path} is not an OpenCV FileStorage file")
    return fs


def fail(where: str, text: str) -> NoReturn:
    raise CalibrationFileError(f"{where}: {text}")


def read_real(fs: cv2.FileStorage, name: str, where: str, default: float | None = None) -> float:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        if default is not None:
            return default
        raise CalibrationFileError(f"{where}: {name} is missing")
    if not (node.isReal() or node.isInt()):
        raise CalibrationFileError(f"{where}: {name} should be a number")
    return float(node.real())


def read_int(fs: cv2.FileStorage, name: str, where: str) -> int:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        raise CalibrationFileError(f"{where}: {name} is missing")
    if not node.isInt():
        raise CalibrationFileError(f"{where}: {name} should be a whole number")
    return int(node.real())


def read_string(fs: cv2.FileStorage, name: str, default: str) -> str:
    node = fs.getNode(name)
    return node.string() if node.isString() else default


def read_mat(fs: cv2.FileStorage, name: str, where: str,
             max_side: int = 16) -> NDArray[np.float64] | None:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        return None
    # check the header against the data before OpenCV reads it: a huge rows x cols makes
    # FileNode.mat() abort the process instead of raising
    rows, cols, dt, data = (node.getNode(k) for k in ("rows", "cols", "dt", "data"))
    if not node.isMap() or rows.empty() or cols.empty() or data.empty():
        raise CalibrationFileError(f"{where}: {name} is not a matrix")
    if not (rows.isInt() and cols.isInt() and 1 <= rows.real() <= max_side
            and 1 <= cols.real() <= max_side):
        raise CalibrationFileError(f"{where}: matrix {name} should have 1 to {max_side} rows and "
                                   "columns")
    if not (dt.isString() and dt.string() in ("d", "f", "i", "u", "s", "c", "w")):
        raise CalibrationFileError(f"{where}: matrix {name} has an unknown element type")
    if not data.isSeq() or data.size() != int(rows.real()) * int(cols.real()):
        raise CalibrationFileError(f"{where}: matrix {name} says {int(rows.real())}x"
                                   f"{int(cols.real())} but holds {data.size()} values")
    try:
        m = node.mat()
    except (cv2.error, SystemError) as exc:  # a header that disagrees with its data, ...
        raise CalibrationFileError(f"{where}: matrix {name} is not readable "
                                   f"({parse_error(exc)})") from None
    if m is None:
        raise CalibrationFileError(f"{where}: {name} is not a matrix")
    return np.asarray(m, np.float64)
