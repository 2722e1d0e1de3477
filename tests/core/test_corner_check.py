"""Each point of a detected target against where its neighbours on the board put it."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.corner_check import MISPLACED_RATIO, check_points
from stereo_gui.core.detect import detect_pair
from stereo_gui.sources.sim import RigConfig, SimRig

CHARUCO = BoardSpec(target="charuco", cols=7, rows=5, square_mm=30.0, marker_mm=22.0)


@pytest.fixture(scope="module")
def rig():
    return SimRig(RigConfig(supersample=2), seed=0)


def _views(rig, board, n):
    rig.set_board(board)
    try:
        out = []
        for i, pose in enumerate(rig.board_poses(n, seed=11)):
            left, right = rig.render_board_pair(pose, np.random.default_rng(i))
            det = detect_pair(f"pose {i}", left, right, board)
            if det.found:
                out.append((pose, left, right, det))
        return out
    finally:
        rig.set_board(BoardSpec())


@pytest.mark.parametrize("board", [BoardSpec(), CHARUCO], ids=["chessboard", "charuco"])
def test_well_placed_points_pass_and_a_moved_one_is_found(rig, board):
    """Rendered views at every place of a calibration set pass; a point moved by 1 px or by
    0.6 px (the corner auto-capture kept against a 0.076 px mean) is found, and named, wherever
    the move stands out from how far its neighbours lie from the view's fit."""
    views = _views(rig, board, 9)
    assert len(views) >= 8
    found = {1.0: 0, 0.6: 0}
    for _pose, _l, _r, det in views:
        for d in (det.left, det.right):
            check = check_points(d, board)
            assert check is not None and not check.misplaced, check
            k = len(d.corners) // 2
            for shift in found:
                corners = d.corners.copy()
                corners[k] += np.float32([shift * np.cos(0.7), shift * np.sin(0.7)])
                moved = check_points(dataclasses.replace(d, corners=corners), board)
                if moved.judged and shift > 1.3 * MISPLACED_RATIO * moved.median_px:
                    assert moved.misplaced and moved.worst_index == k, (shift, moved)
                    found[shift] += 1
    assert found[1.0] >= len(views) and found[0.6] >= len(views) // 2, found


def test_a_speck_beside_a_corner_makes_it_misplaced(rig):
    """A white speck 3 px beside a corner pulls it about 1.6 px aside; the check finds it."""
    board = BoardSpec()
    _pose, left, right, det = _views(rig, board, 5)[-1]
    k = len(det.left.corners) // 2
    x, y = det.left.corners[k]
    specked = left.copy()
    cv2.circle(specked, (int(round(x + 3)), int(round(y + 1))), 2, (255, 255, 255), -1)
    again = detect_pair("specked", specked, right, board)
    assert again.found
    check = check_points(again.left, board)
    assert check.misplaced and check.worst_index == k
    assert not check_points(again.right, board).misplaced
