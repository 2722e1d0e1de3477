"""Corner helpers the simulated rig's tests share."""

from __future__ import annotations

import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import detect_board


def detect_corners(img: np.ndarray, board: BoardSpec) -> np.ndarray | None:
    """(N, 2) corners found by the application's own detector, or None."""
    found = detect_board(img, board)
    return None if found is None else found.corners


def match_order(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """OpenCV may report the corners in reverse order; compare in the order that fits."""
    fwd = np.sqrt(np.mean(np.sum((found - truth) ** 2, 1)))
    rev = np.sqrt(np.mean(np.sum((found[::-1] - truth) ** 2, 1)))
    return found if fwd <= rev else found[::-1]
