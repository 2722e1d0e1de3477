"""The calibration target: a chessboard, a symmetric or asymmetric circle grid, or a ChArUco board.

How `cols` x `rows` counts, per target (each as OpenCV's own functions count it):

- chessboard: inner corners (a 9x6 board has 10x7 squares); `square_mm` is a square's side.
- circles: circles per row x rows; `square_mm` is the distance between neighbouring centres;
  `marker_mm` the circle diameter (default half the spacing).
- acircles: OpenCV's asymmetric grid, points per row x rows (for example 4x11); rows are
  `square_mm` apart and every other row is shifted by `square_mm`, so centres in a row are
  2 x `square_mm` apart; `marker_mm` the circle diameter (default 0.7 x `square_mm`).
- charuco: squares (a 7x5 board has 6x4 inner corners, the points used); `square_mm` is a
  square's side, `marker_mm` the side of the ArUco markers in the white squares (default 0.75
  x `square_mm`), `dictionary` the ArUco dictionary (OpenCV's name, e.g. DICT_4X4_50).

Object points are numbered by id: every point of the target has one (row by row), a detection
says which ids it found (all of them for chessboards and circle grids, any subset for ChArUco).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.params import check_all, param

TARGETS = ("chessboard", "circles", "acircles", "charuco")
TARGET_NAMES = {"chessboard": "chessboard", "circles": "circle grid",
                "acircles": "asymmetric circle grid", "charuco": "ChArUco board"}
DEFAULT_DICTIONARY = "DICT_4X4_50"
# the ArUco dictionaries a ChArUco board may use (OpenCV's names)
DICTIONARIES = tuple(f"DICT_{b}X{b}_{n}" for b in (4, 5, 6, 7) for n in (50, 100, 250, 1000)) + (
    "DICT_ARUCO_ORIGINAL",)
# a ChArUco view needs this many corners (and two rows and columns of them) to count
CHARUCO_MIN_CORNERS = 8


def dictionary_size(name: str) -> int:
    """Number of markers in an ArUco dictionary (by OpenCV's name)."""
    if name == "DICT_ARUCO_ORIGINAL":
        return 1024
    return int(name.rsplit("_", 1)[1])


MIN_BOARD_CORNERS = 3  # inner corners a side (circle grids: 2 circles)
MAX_BOARD_CORNERS = 100
# beyond these, millimetres overflow or vanish in the calibration's arithmetic
MIN_SQUARE_MM = 0.01
MAX_SQUARE_MM = 10_000.0


@dataclass(frozen=True)
class BoardSpec:
    """A calibration target; see the module docstring for what `cols` and `rows` count. Each
    field's range is declared with it (the command line's options take theirs from here); what
    one field asks of another is checked when it is built."""

    cols: int = param(9, lo=2, hi=MAX_BOARD_CORNERS,
                      help="inner corners (chessboard), circles, or squares (ChArUco) a row")
    rows: int = param(6, lo=2, hi=MAX_BOARD_CORNERS)
    square_mm: float = param(25.0, lo=MIN_SQUARE_MM, hi=MAX_SQUARE_MM, unit="mm",
                             help="square side, or the spacing of a circle grid")
    target: str = param("chessboard", choices=TARGETS)
    # ChArUco: marker side; circle grids: circle diameter; 0: the target's default
    marker_mm: float = param(0.0, lo=0.0, hi=MAX_SQUARE_MM, unit="mm")
    dictionary: str = param(DEFAULT_DICTIONARY, choices=DICTIONARIES,
                            help="ChArUco only: the ArUco dictionary")

    def __post_init__(self) -> None:
        if self.target != "charuco":
            object.__setattr__(self, "dictionary", DEFAULT_DICTIONARY)
        check_all(self)
        # OpenCV's chessboard and ChArUco detectors need more than 2 corners a side
        least = 2 if self.target in ("circles", "acircles") else MIN_BOARD_CORNERS
        if self.cols < least or self.rows < least:
            what = "squares" if self.target == "charuco" else (
                "inner corners" if self.target == "chessboard" else "circles")
            raise InputError(f"a {TARGET_NAMES[self.target]} needs at least {least}x{least} "
                             f"{what}, not {self.cols}x{self.rows}")
        if self.target == "chessboard":
            object.__setattr__(self, "marker_mm", 0.0)
        elif self.marker_mm == 0.0:
            share = {"circles": 0.5, "acircles": 0.7, "charuco": 0.75}[self.target]
            object.__setattr__(self, "marker_mm", round(share * self.square_mm, 3))
        if self.target == "charuco":
            if self.marker_mm >= self.square_mm:
                raise InputError(f"the markers ({self.marker_mm:g} mm) must be smaller than the "
                                 f"squares ({self.square_mm:g} mm)")
            need = (self.cols * self.rows) // 2
            if need > dictionary_size(self.dictionary):
                raise InputError(f"a {self.cols}x{self.rows} ChArUco board needs {need} markers; "
                                 f"{self.dictionary} has only {dictionary_size(self.dictionary)}")
        elif self.target in ("circles", "acircles"):
            gap = self.square_mm * (math.sqrt(2.0) if self.target == "acircles" else 1.0)
            if self.marker_mm >= gap:
                raise InputError(f"circles of {self.marker_mm:g} mm overlap at a spacing of "
                                 f"{self.square_mm:g} mm")

    # ---- points --------------------------------------------------------------------------------
    @property
    def pattern_size(self) -> tuple[int, int]:
        """(cols, rows) as OpenCV's chessboard, circle grid and ChArUco functions take it."""
        return (self.cols, self.rows)

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(rows, cols) of the target's points: for ChArUco the inner corners."""
        if self.target == "charuco":
            return (self.rows - 1, self.cols - 1)
        return (self.rows, self.cols)

    @property
    def point_count(self) -> int:
        r, c = self.grid_shape
        return r * c

    @property
    def corner_count(self) -> int:
        return self.point_count

    @property
    def partial(self) -> bool:
        """True when a view may show part of the target (ChArUco: its corners carry ids)."""
        return self.target == "charuco"

    @property
    def min_points(self) -> int:
        """Fewest points a view must show to count."""
        return CHARUCO_MIN_CORNERS if self.partial else self.point_count

    def object_points_mm(self) -> np.ndarray:
        """Point positions on the board plane (Z = 0), shape (point_count, 3), float32, mm,
        indexed by id (row by row, as OpenCV orders its detections)."""
        return _object_points(self).copy()

    def outline_mm(self) -> tuple[float, float, float, float]:
        """The printed target with its white border on the board plane: (a0, b0, a1, b1) mm
        (a along a row, b down the rows, in the object points' frame)."""
        s = self.square_mm
        if self.target == "chessboard":
            return (-2.0 * s, -2.0 * s, (self.cols + 1) * s, (self.rows + 1) * s)
        if self.target == "circles":
            return (-s, -s, self.cols * s, self.rows * s)
        if self.target == "acircles":
            return (-s, -s, 2.0 * self.cols * s, self.rows * s)
        m = 0.25 * s  # ChArUco: the squares reach the board's edge; a quarter square of white
        return (-m, -m, self.cols * s + m, self.rows * s + m)

    def label(self) -> str:
        if self.target == "chessboard":
            return f"{self.cols}x{self.rows}, {self.square_mm:g} mm"
        if self.target == "charuco":
            return (f"ChArUco {self.cols}x{self.rows}, {self.square_mm:g}/{self.marker_mm:g} mm, "
                    f"{self.dictionary}")
        return (f"{TARGET_NAMES[self.target]} {self.cols}x{self.rows}, {self.square_mm:g} mm "
                f"spacing, {self.marker_mm:g} mm circles")

    def aruco_board(self) -> cv2.aruco.CharucoBoard:
        """The cv2.aruco.CharucoBoard of a ChArUco target (cached)."""
        if self.target != "charuco":
            raise ValueError("only a ChArUco target has an ArUco board")
        return _charuco_board(self.cols, self.rows, float(self.square_mm), float(self.marker_mm),
                              self.dictionary)

    def to_json(self) -> dict[str, object]:
        """The board as the session manifest and other JSON records keep it."""
        out: dict[str, object] = {"cols": self.cols, "rows": self.rows, "square_mm": self.square_mm}
        if self.target != "chessboard":
            out.update(target=self.target, marker_mm=self.marker_mm)
        if self.target == "charuco":
            out["dictionary"] = self.dictionary
        return out

    @staticmethod
    def from_json(data: dict[str, Any]) -> BoardSpec:
        """Inverse of to_json (a record without `target` is a chessboard)."""
        return BoardSpec(int(data["cols"]), int(data["rows"]), float(data["square_mm"]),
                         str(data.get("target", "chessboard")), float(data.get("marker_mm", 0.0)),
                         str(data.get("dictionary", DEFAULT_DICTIONARY)))


@functools.lru_cache(maxsize=32)
def _object_points_cached(board: BoardSpec) -> np.ndarray:
    s = board.square_mm
    if board.target == "charuco":
        pts = np.asarray(board.aruco_board().getChessboardCorners(), np.float32).reshape(-1, 3)
        return pts
    rows, cols = board.grid_shape
    i, j = np.mgrid[0:rows, 0:cols]
    pts = np.zeros((rows * cols, 3), np.float32)
    if board.target == "acircles":
        pts[:, 0] = ((2 * j + i % 2) * s).ravel()
    else:
        pts[:, 0] = (j * s).ravel()
    pts[:, 1] = (i * s).ravel()
    return pts


def _object_points(board: BoardSpec) -> np.ndarray:
    return _object_points_cached(board)


@functools.lru_cache(maxsize=16)
def _charuco_board(cols: int, rows: int, square_mm: float, marker_mm: float, dictionary: str
                   ) -> cv2.aruco.CharucoBoard:
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    return cv2.aruco.CharucoBoard((cols, rows), square_mm, marker_mm, d)


_BOARD_RE = re.compile(r"^\s*(\d+)\s*[xX*,]\s*(\d+)\s*$")


def parse_board(text: str, square_mm: float = 25.0, target: str = "chessboard",
                marker_mm: float = 0.0, dictionary: str = DEFAULT_DICTIONARY) -> BoardSpec:
    """Parse '9x6' (COLSxROWS as the target counts them) into a BoardSpec; raise InputError if it
    cannot."""
    m = _BOARD_RE.match(text or "")
    if not m:
        unit = "squares" if target == "charuco" else (
            "inner corners" if target == "chessboard" else "circles")
        raise InputError(
            f"board size {text!r} does not parse: give {unit} as COLSxROWS, for example "
            f"{'7x5' if target == 'charuco' else '9x6'}")
    return BoardSpec(int(m.group(1)), int(m.group(2)), float(square_mm), target,
                     float(marker_mm), dictionary)
