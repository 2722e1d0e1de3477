"""Detection of every target type on the simulated rig's renderings: circle grids, asymmetric
circle grids and ChArUco boards (also partly visible, matched by id between the cameras)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import detect_board, detect_pair
from stereo_gui.sources.sim import RigConfig, SimRig

SEED = 913  # not used while tuning
BOARDS = {
    "chessboard": BoardSpec(),
    "circles": BoardSpec(7, 6, 25.0, "circles"),
    "acircles": BoardSpec(4, 11, 20.0, "acircles"),
    "charuco": BoardSpec(7, 5, 30.0, "charuco", 22.0),
}


def _errors(rig, pose, det, cam):
    truth = rig.project(pose.corners_left_mm(rig.config.board)[det.point_ids], cam)
    err = np.linalg.norm(det.corners - truth, axis=1)
    if det.ids is None:  # a grid may be numbered from either end
        err = min(err, np.linalg.norm(det.corners[::-1] - truth, axis=1), key=np.mean)
    return err


@pytest.mark.parametrize("target", sorted(BOARDS))
def test_every_target_is_found_to_a_tenth_of_a_pixel(target):
    board = BOARDS[target]
    rig = SimRig(RigConfig(board=board), seed=SEED)
    rng = np.random.default_rng(1)
    errors, found = [], 0
    poses = rig.board_poses(6)
    for pose in poses:
        left, right = rig.render_board_pair(pose, rng)
        for cam, img in ((0, left), (1, right)):
            det = detect_board(img, board)
            if det is None:
                continue
            found += 1
            assert len(det.corners) >= board.min_points
            errors.append(_errors(rig, pose, det, cam))
    assert found >= 10, found  # of 12 images
    e = np.concatenate(errors)
    assert np.sqrt(np.mean(e ** 2)) < 0.12 and e.max() < 0.5, (e.mean(), e.max())


def test_a_board_not_there_is_not_found():
    blank = np.full((480, 640, 3), 128, np.uint8)
    for board in BOARDS.values():
        assert detect_board(blank, board) is None


def _partial_pose(rig):
    """A pose with the ChArUco board partly outside the right image but seen by both cameras."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        pose = rig.random_board_pose(rng, where=(0.0, 0.5))
        if len(rig.visible_point_ids(pose, 1)) < rig.config.board.point_count - 4:
            return pose
    raise AssertionError("no partly visible pose")


def test_a_partly_visible_charuco_board_counts_and_is_matched_by_id():
    board = BOARDS["charuco"]
    rig = SimRig(RigConfig(board=board), seed=SEED)
    pose = _partial_pose(rig)
    left, right = rig.render_board_pair(pose, np.random.default_rng(2))
    pair = detect_pair("p", left, right, board)
    assert pair.found, pair.reason
    # the right camera sees only part of the board, and every id it reports is really in view
    assert len(pair.right.ids) < board.point_count
    assert set(pair.right.ids) <= set(rig.visible_point_ids(pose, 1))
    assert len(pair.common_ids()) == len(set(pair.left.ids) & set(pair.right.ids))
    ids, pl, pr = pair.common()
    assert len(ids) >= board.min_points and np.all(np.diff(ids) > 0)
    for pts, cam in ((pl, 0), (pr, 1)):
        truth = rig.project(pose.corners_left_mm(board)[ids], cam)
        assert np.abs(pts - truth).max() < 0.5
    np.testing.assert_array_equal(pair.left.object_points(board), board.object_points_mm()[pair.left.ids])


def test_a_partly_hidden_charuco_board_still_gives_its_visible_corners():
    board = BOARDS["charuco"]
    rig = SimRig(RigConfig(board=board), seed=SEED)
    pose = rig.random_board_pose(np.random.default_rng(8), where=(0.5, 0.5))
    left, _ = rig.render_board_pair(pose, np.random.default_rng(3))
    full = detect_board(left, board)
    assert full is not None
    # a hand over the left half of the board
    uv = rig.project(pose.corners_left_mm(board), 0)
    xmid = int(np.median(uv[:, 0]))
    hidden = left.copy()
    hidden[:, : xmid - 5] = 90
    part = detect_board(hidden, board)
    assert part is not None and len(part.ids) < len(full.ids)
    assert set(part.ids) <= set(full.ids)
    truth = rig.project(pose.corners_left_mm(board)[part.ids], 0)
    assert np.abs(part.corners - truth).max() < 0.5


def test_a_pair_sharing_too_few_corners_says_so():
    board = BOARDS["charuco"]
    rig = SimRig(RigConfig(board=board), seed=SEED)
    pose = rig.random_board_pose(np.random.default_rng(8), where=(0.5, 0.5))
    left, right = rig.render_board_pair(pose, np.random.default_rng(3))
    uv = rig.project(pose.corners_left_mm(board), 1)
    # the right camera sees only the top row of squares' corners
    cut = right.copy()
    cut[int(np.sort(uv[:, 1])[8]) + 3:, :] = 90
    pair = detect_pair("p", left, cut, board)
    if pair.right is None:
        assert "not found in the right image" in pair.reason
    else:
        assert not pair.found and "share only" in pair.reason
