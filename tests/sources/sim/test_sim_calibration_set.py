"""Calibration sets on disk: the files, truth.json, and images that match the recorded poses."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from corners import detect_corners, match_order

from stereo_gui.sources.sim import (
    BoardPose,
    RigTruth,
    SimRig,
    write_calibration_set,
)


def test_write_calibration_set(tmp_path):
    (tmp_path / "set").mkdir()
    out = write_calibration_set(tmp_path / "set", n_pairs=2, seed=4)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["chessboard-L1.png", "chessboard-L2.png", "chessboard-R1.png",
                     "chessboard-R2.png", "truth.json"]
    data = json.loads((out / "truth.json").read_text())
    assert data["seed"] == 4 and data["board"] == {"cols": 9, "rows": 6, "square_mm": 25.0}
    truth = RigTruth.from_json(data)
    assert truth.baseline_mm == pytest.approx(110.0)
    img = cv2.imread(str(out / "chessboard-L1.png"))
    assert img.shape == (480, 640, 3)
    # the written image is the rig's rendering of the recorded pose
    pose = BoardPose(np.array(data["pairs"][0]["R_left_board"]), np.array(data["pairs"][0]["t_left_board_mm"]))
    found = detect_corners(img, truth.board)
    truth_px = SimRig(seed=4).project(pose.corners_left_mm(truth.board), 0)
    assert np.abs(match_order(found, truth_px) - truth_px).max() < 0.5


def test_a_late_right_camera_sees_the_hand_held_board_where_it_has_moved(tmp_path):
    """`simulate --time-offset`: the right camera grabs later, and the board held by hand has
    moved by then (about 100 mm/s, 10 deg/s): truth.json records where each camera saw it, and
    the right image is the rig's rendering of its own pose, not of the left one's."""
    from stereo_gui.sources.sim import RigConfig

    (tmp_path / "set").mkdir()
    out = write_calibration_set(tmp_path / "set", n_pairs=3, seed=4,
                                config=RigConfig(time_offset_s=0.05))
    data = json.loads((out / "truth.json").read_text())
    assert data["time_offset_s"] == 0.05
    rig = SimRig(seed=4)
    truth = RigTruth.from_json(data)
    moved = []
    for k, pair in enumerate(data["pairs"], start=1):
        left = BoardPose(np.array(pair["R_left_board"]), np.array(pair["t_left_board_mm"]))
        seen = pair["right_camera_board"]
        right = BoardPose(np.array(seen["R_left_board"]), np.array(seen["t_left_board_mm"]))
        moved.append(float(np.linalg.norm(right.t - left.t)))
        found = detect_corners(cv2.imread(str(out / f"chessboard-R{k}.png")), truth.board)
        own = rig.project(right.corners_left_mm(truth.board), 1)
        assert np.abs(match_order(found, own) - own).max() < 0.5
    assert 0.0 < max(moved) < 30.0  # mm in 50 ms: a hand, not a throw
    # synchronised (the default): the right camera sees the left one's pose, and truth.json
    # says so by recording no other
    (tmp_path / "still").mkdir()
    still = write_calibration_set(tmp_path / "still", n_pairs=1, seed=4)
    data = json.loads((still / "truth.json").read_text())
    assert data["time_offset_s"] == 0.0 and "right_camera_board" not in data["pairs"][0]
