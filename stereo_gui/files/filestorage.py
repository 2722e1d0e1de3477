"""Reading matrices from cv2.FileStorage without trusting the file.

`FileNode.mat()` of OpenCV 5.0 creates the matrix its `rows` and `cols` announce and then copies
every number of `data` into it before it checks that they agree: a matrix node whose header
disagrees with its data (a `cols` line lost, a hand edit) writes past the buffer and corrupts
the heap; the process aborts later, somewhere else ("free(): invalid next size"). So the header
is checked against the data here first, and only a node that agrees is handed to OpenCV.
"""

from __future__ import annotations

import re

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import CalibrationFileError

_DT = re.compile(r"^\s*(\d*)\s*([ucwsifdh])\s*$")
MAX_ELEMENTS = 1_000_000  # far above any calibration matrix; keeps a hostile header harmless


def _whole(node: cv2.FileNode) -> int | None:
    if node.empty() or not (node.isInt() or node.isReal()):
        return None
    v = node.real()
    return int(v) if v == int(v) else None


def read_matrix(node: cv2.FileNode, name: str, where: str) -> NDArray[np.float64]:
    """The float64 matrix in FileStorage node `node` (an `!!opencv-matrix`, or a plain sequence
    of numbers as a column); CalibrationFileError naming `name` and `where` when the node is not
    a matrix or its header (rows, cols, dt) disagrees with its data."""
    try:
        if node.isSeq():
            values = [node.at(i) for i in range(node.size())]
            if not values or not all(v.isInt() or v.isReal() for v in values):
                raise CalibrationFileError(f"{where}: {name} should be a matrix or a list of "
                                           "numbers")
            return np.array([v.real() for v in values], np.float64).reshape(-1, 1)
        if not node.isMap():
            raise CalibrationFileError(f"{where}: {name} is not a matrix")
        rows, cols = _whole(node.getNode("rows")), _whole(node.getNode("cols"))
        dt, data = node.getNode("dt"), node.getNode("data")
        if rows is None or cols is None or rows < 1 or cols < 1:
            raise CalibrationFileError(f"{where}: matrix {name} needs rows and cols, whole "
                                       "numbers of at least 1")
        found = _DT.match(dt.string()) if dt.isString() else None
        if found is None:
            raise CalibrationFileError(f"{where}: matrix {name} has no valid dt (element type)")
        channels = int(found.group(1) or 1)
        if not data.isSeq():
            raise CalibrationFileError(f"{where}: matrix {name} has no data list")
        expected = rows * cols * channels
        if expected > MAX_ELEMENTS or data.size() != expected:
            raise CalibrationFileError(
                f"{where}: matrix {name} announces {rows}x{cols}"
                f"{f'x{channels}' if channels > 1 else ''} values but holds {data.size()}")
        m = node.mat()
    except (cv2.error, SystemError) as exc:
        raise CalibrationFileError(f"{where}: matrix {name} cannot be read "
                                   f"({str(exc).strip().splitlines()[-1] if str(exc) else exc})"
                                   ) from None
    if m is None:
        raise CalibrationFileError(f"{where}: {name} is not a matrix")
    out = np.asarray(m, np.float64)
    if channels > 1:
        out = out.reshape(rows, cols * channels)
    return out
