"""Reading image files: sizes checked before anything is decoded, the decoders' own complaints
kept off the terminal.

Left to OpenCV, a file of gigabytes, or a 69-byte PNG whose header claims 100000 x 100000
pixels, fails with OpenCV's own assertion or decodes for minutes. So the file's size is checked
first, then the width and height its header gives (PNG, JPEG, BMP, TIFF, WebP, PNM: read from the
header, without decoding), both against limits stated in the error; what the header does not
tell is checked after decoding. libpng and libjpeg write warnings straight to the
process's stderr ("libpng warning: iCCP: ..."); while a file is decoded they are caught and
logged, and the first of them names what is wrong in our error.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import struct
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol, SupportsIndex, overload

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import os_error_text

log = logging.getLogger(__name__)

MAX_IMAGE_BYTES = 1 << 30  # a 10000 x 10000 16-bit colour TIFF is 600 MB
MAX_IMAGE_SIDE_PX = 10_000
MAX_IMAGE_PIXELS = 50_000_000  # a 50 megapixel image decodes in about a second
LIMITS_TEXT = (f"at most {MAX_IMAGE_SIDE_PX} px a side and {MAX_IMAGE_PIXELS // 1_000_000} "
               "megapixels")


# ---- the size a header gives ---------------------------------------------------------------
class _Header(Protocol):
    """What the parsers below read: a length, single bytes as ints, slices as `bytes`."""

    def __len__(self) -> int: ...

    @overload
    def __getitem__(self, key: SupportsIndex) -> int: ...

    @overload
    def __getitem__(self, key: slice) -> bytes: ...


class _Bytes:
    """A file's bytes as the parsers below read them: slices are small `bytes`, taken from a
    buffer that may be a gigabyte (a TIFF keeps its header wherever it likes, often at the end)."""

    def __init__(self, view: memoryview) -> None:
        self._view = view

    def __len__(self) -> int:
        return len(self._view)

    @overload
    def __getitem__(self, key: SupportsIndex) -> int: ...

    @overload
    def __getitem__(self, key: slice) -> bytes: ...

    def __getitem__(self, key: SupportsIndex | slice) -> int | bytes:
        if isinstance(key, slice):
            return bytes(self._view[key])
        return self._view[key]


def _png(data: _Header) -> tuple[int, int] | None:
    if data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR" and len(data) >= 24:
        return struct.unpack(">II", data[16:24])
    return None


def _jpeg(data: _Header) -> tuple[int, int] | None:
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 9 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7 or marker == 0xFF:
            i += 1 if marker == 0xFF else 2
            continue
        length = struct.unpack(">H", data[i + 2:i + 4])[0]
        # start of frame: every SOFn except DHT (C4), JPG (C8) and DAC (CC)
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return w, h
        i += 2 + length
    return None


def _bmp(data: _Header) -> tuple[int, int] | None:
    if data[:2] == b"BM" and len(data) >= 26:
        header = struct.unpack("<I", data[14:18])[0]
        if header == 12:
            w, h = struct.unpack("<HH", data[18:22])
        else:
            w, h = struct.unpack("<ii", data[18:26])
        return abs(w), abs(h)
    return None


def _tiff(data: _Header) -> tuple[int, int] | None:
    order = {b"II": "<", b"MM": ">"}.get(data[:2])
    if order is None or len(data) < 8 or struct.unpack(order + "H", data[2:4])[0] != 42:
        return None
    ifd = struct.unpack(order + "I", data[4:8])[0]
    if ifd + 2 > len(data):
        return None
    n = struct.unpack(order + "H", data[ifd:ifd + 2])[0]
    size = {}
    for k in range(min(n, 512)):
        at = ifd + 2 + 12 * k
        if at + 12 > len(data):
            break
        tag, kind = struct.unpack(order + "HH", data[at:at + 4])
        if tag in (256, 257):  # ImageWidth, ImageLength: SHORT or LONG
            fmt = "H" if kind == 3 else "I"
            size[tag] = struct.unpack(order + fmt, data[at + 8:at + 8 + struct.calcsize(fmt)])[0]
    return (size[256], size[257]) if len(size) == 2 else None


def _webp(data: _Header) -> tuple[int, int] | None:
    if data[:4] != b"RIFF" or data[8:12] != b"WEBP" or len(data) < 30:
        return None
    kind = data[12:16]
    if kind == b"VP8X":
        w = 1 + int.from_bytes(data[24:27], "little")
        h = 1 + int.from_bytes(data[27:30], "little")
        return w, h
    if kind == b"VP8L":
        bits = int.from_bytes(data[21:25], "little")
        return 1 + (bits & 0x3FFF), 1 + ((bits >> 14) & 0x3FFF)
    if kind == b"VP8 ":
        w, h = struct.unpack("<HH", data[26:30])
        return w & 0x3FFF, h & 0x3FFF
    return None


_PNM = re.compile(rb"^P[1-7]\s+(?:#[^\n]*\s+)*(\d{1,12})\s+(?:#[^\n]*\s+)*(\d{1,12})\s")


def _pnm(data: _Header) -> tuple[int, int] | None:
    m = _PNM.match(data[:512])
    return (int(m.group(1)), int(m.group(2))) if m else None


def header_size(data: bytes | bytearray | memoryview | NDArray[np.uint8]
                ) -> tuple[int, int] | None:
    """(width, height) px the header of an image file claims (`data`: its bytes, or a buffer
    of them, read without copying), or None when it is of a format not read here (the decoded
    image is checked then)."""
    view = data.data if isinstance(data, np.ndarray) else memoryview(data)
    header = _Bytes(view.cast("B"))
    for read in (_png, _jpeg, _bmp, _tiff, _webp, _pnm):
        try:
            size = read(header)
        except (struct.error, ValueError, IndexError):
            size = None
        if size is not None:
            return int(size[0]), int(size[1])
    return None


def _too_large(w: int, h: int) -> bool:
    return w > MAX_IMAGE_SIDE_PX or h > MAX_IMAGE_SIDE_PX or w * h > MAX_IMAGE_PIXELS


# ---- decoding without noise on the terminal ------------------------------------------------
_stderr_lock = threading.Lock()
# what the image libraries write to stderr themselves; anything else caught meanwhile (another
# thread's message) is written to the terminal again
_LIBRARY_LINE = re.compile(r"^(libpng|libjpeg|libtiff|libwebp|OpenJPEG|TIFF\w*|JPEG|Corrupt JPEG|"
                           r"Premature end|Invalid SOS|Not a JPEG|Bogus|Unsupported|Warning|"
                           r"Error)\b|^\[\s*(WARN|ERROR|INFO)")


@contextlib.contextmanager
def library_noise_caught(lines: list[str]) -> Iterator[None]:
    """Within the block, what C libraries write to the process's stderr (file descriptor 2) is
    caught into `lines` instead of reaching the terminal (Python's own sys.stderr is untouched
    when it is not that descriptor)."""
    try:
        fd = sys.__stderr__.fileno() if sys.__stderr__ is not None else 2
    except (AttributeError, ValueError, OSError):
        fd = 2
    with _stderr_lock:
        try:
            saved = os.dup(fd)
        except OSError:  # no stderr at all (a bundled GUI on Windows): nothing to keep off
            yield
            return
        with tempfile.TemporaryFile() as sink:
            try:
                os.dup2(sink.fileno(), fd)
                yield
            finally:
                os.dup2(saved, fd)
                os.close(saved)
                sink.seek(0)
                caught = sink.read(1 << 16).decode("utf-8", "replace")
    for line in caught.splitlines():
        if not line.strip():
            continue
        if _LIBRARY_LINE.search(line):
            lines.append(line.strip())
            log.debug("image decoder: %s", line.strip())
        elif sys.__stderr__ is not None:
            with contextlib.suppress(OSError, ValueError, AttributeError):
                sys.__stderr__.write(line + "\n")
                sys.__stderr__.flush()


def _decoder_said(lines: list[str]) -> str:
    """The decoder's first complaint without its library's name ("IHDR: CRC error")."""
    for line in lines:
        text = re.sub(r"^(libpng|libjpeg|libtiff|libwebp)\s+(warning|error)\s*:\s*", "", line)
        return text.strip()
    return ""


def decode_image(data: np.ndarray, flags: int, name: str) -> np.ndarray:
    """Decode the bytes of an image file (uint8 array) as `cv2.imdecode` does; InputError
    starting with `name` (e.g. "left image x.png") when they are too large or not an image."""
    size = header_size(data)
    if size is not None and _too_large(*size):
        raise InputError(f"{name} is {size[0]}x{size[1]} px: larger than this program reads "
                         f"({LIMITS_TEXT}); nothing was decoded")
    said: list[str] = []
    img = None
    try:
        with library_noise_caught(said):
            img = cv2.imdecode(data, flags) if data.size else None
    except cv2.error as exc:  # a header OpenCV refuses, a buffer it cannot take
        log.debug("imdecode of %s: %s", name, exc)
        img = None
    if img is None:
        why = _decoder_said(said)
        raise InputError(f"{name} cannot be read as an image"
                         + (f" (the decoder says: {why})" if why else ""))
    if _too_large(img.shape[1], img.shape[0]):
        raise InputError(f"{name} is {img.shape[1]}x{img.shape[0]} px: larger than this "
                         f"program reads ({LIMITS_TEXT})")
    return img


def read_image_file(path: str | os.PathLike[str], flags: int = cv2.IMREAD_COLOR,
                    name: str | None = None) -> np.ndarray:
    """The image in `path` (see `decode_image`); InputError starting with `name` (default
    "image PATH") when it cannot be read, is too large, or is not an image."""
    path = Path(path)
    name = name or f"image {path}"
    try:
        size = path.stat().st_size
        if size > MAX_IMAGE_BYTES:
            raise InputError(f"{name} is {size / 2**30:.1f} GiB: larger than any image this "
                             f"program reads (at most {MAX_IMAGE_BYTES / 2**30:g} GiB)")
        data = np.fromfile(str(path), np.uint8)  # works with any characters in the path
    except OSError as exc:
        raise InputError(f"{name} cannot be read: {os_error_text(exc)}") from None
    return decode_image(data, flags, name)
