"""Ground truth carried by the simulated rig's frames: what the left camera sees at a pixel."""

import numpy as np
import pytest

from stereo_gui.sources.sim import Scene, SimSource


def test_frame_truth_is_the_scene_where_no_board_is_shown(rig):
    calib = rig.true_calibration()
    frame = SimSource(rig=rig, mode="scene", paced=False).read()
    for x, y in ((320, 240), (100, 400), (600, 50)):
        want = rig.true_point_rectified(calib, frame.truth.scene, x, y)
        got = frame.truth.point_rectified(calib, x, y)
        assert got == pytest.approx(want)


def test_frame_truth_sees_the_board_in_front_of_the_wall(rig):
    calib = rig.true_calibration()
    src = SimSource(rig=rig, mode="mixed", paced=False)
    frame = src.read()
    pose = frame.truth.pose
    # the board's centre, projected into the rectified left image
    b = rig.truth.board
    centre_board = np.array([(b.cols - 1) * b.square_mm / 2, (b.rows - 1) * b.square_mm / 2, 0.0])
    centre = pose.R @ centre_board + pose.t
    rect = np.asarray(calib.R1) @ centre
    uvw = np.asarray(calib.P1)[:, :3] @ rect
    x, y = uvw[0] / uvw[2], uvw[1] / uvw[2]
    got = frame.truth.point_rectified(calib, x, y)
    assert got[2] == pytest.approx(rect[2], rel=1e-6)  # the board, not the wall behind it
    wall = rig.true_point_rectified(calib, Scene.demo(), x, y)
    assert wall is None or wall[2] > got[2]
