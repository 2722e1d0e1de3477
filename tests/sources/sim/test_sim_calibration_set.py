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
