"""The calibration target: a chessboard described by its inner corners and square size."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.errors import InputError


MIN_BOARD_CORNERS = 3  # inner corners a side
MAX_BOARD_CORNERS = 100
MIN_SQUARE_MM = 0.01
MAX_SQUARE_MM = 10_000.0


@dataclass(frozen=True)
class BoardSpec:
    """A chessboard with `cols` x `rows` inner corners and squares of `square_mm` millimetres."""

    cols: int = 9
    rows: int = 6
    square_mm: float = 25.0

    def __post_init__(self) -> None:
        if self.cols < MIN_BOARD_CORNERS or self.rows < MIN_BOARD_CORNERS:
            # OpenCV's chessboard detectors need more than 2 corners a side
            raise InputError(f"a chessboard needs at least {MIN_BOARD_CORNERS}x{MIN_BOARD_CORNERS} "
                             f"inner corners, not {self.cols}x{self.rows}")
        if self.cols > MAX_BOARD_CORNERS or self.rows > MAX_BOARD_CORNERS:
            raise InputError(f"a chessboard of {self.cols}x{self.rows} inner corners is not "
                             f"plausible (at most {MAX_BOARD_CORNERS} a side)")
        if not np.isfinite(self.square_mm) or self.square_mm <= 0:
            raise InputError(f"square size must be a positive number of millimetres, not {self.square_mm}")
        if not MIN_SQUARE_MM <= self.square_mm <= MAX_SQUARE_MM:
            # beyond these, millimetres overflow or vanish in the calibration's arithmetic
            raise InputError(f"square size {self.square_mm:g} mm is not plausible (give "
                             f"{MIN_SQUARE_MM:g} to {MAX_SQUARE_MM:g} mm)")

    @property
    def pattern_size(self) -> tuple[int, int]:
        """(cols, rows) as OpenCV's chessboard functions take it."""
        return (self.cols, self.rows)

    @property
    def corner_count(self) -> int:
        return self.cols * self.rows

    def object_points_mm(self) -> np.ndarray:
        """Corner positions on the board plane (Z = 0), shape (rows*cols, 3), float32, mm.

        Order matches OpenCV's detections: row by row, `cols` corners per row.
        """
        grid = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2)
        pts = np.zeros((self.corner_count, 3), np.float32)
        pts[:, :2] = grid * self.square_mm
        return pts

    def label(self) -> str:
        return f"{self.cols}x{self.rows}, {self.square_mm:g} mm"


_BOARD_RE = re.compile(r"^\s*(\d+)\s*[xX*,]\s*(\d+)\s*$")


def parse_board(text: str, square_mm: float = 25.0) -> BoardSpec:
    """Parse '9x6' (inner corners, columns x rows) into a BoardSpec; raise InputError if it cannot."""
    m = _BOARD_RE.match(text or "")
    if not m:
        raise InputError(
            f"board size {text!r} does not parse: give inner corners as COLSxROWS, for example 9x6"
        )
    return BoardSpec(int(m.group(1)), int(m.group(2)), float(square_mm))
