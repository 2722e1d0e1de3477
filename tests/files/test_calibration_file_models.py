"""Calibration files keep the lens model, the target, the origin, the warnings and the 1-sigma
covariance; older files load as before (no uncertainty); ROS export names the distortion model."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.uncertainty import CalibrationUncertainty, CalibrationWarning
from stereo_gui.files.calibration_file import (
    export_ros,
    import_ros,
    load_calibration,
    ros_camera_info_text,
    save_calibration,
)
from stereo_gui.sources.sim import RigConfig, SimRig


def _with_uncertainty(c, model):
    names = ("left.fx", "left.cx", "right.k1", "rvec.y", "T.x")
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 5))
    cov = a @ a.T * 1e-3
    return c.with_updates(
        uncertainty=CalibrationUncertainty(names, cov, 0.0421, "jacobian", model),
        origin="calibrated from 20 pairs (ChArUco 7x5, fisheye model)",
        warnings=(CalibrationWarning("uncovered", "The board never reached the top-left "
                                     "corner of both images.", "capture"),
                  CalibrationWarning("swapped", "The cameras are swapped.", "swap")),
        board=BoardSpec(7, 5, 30.0, "charuco", 22.0, "DICT_5X5_100"))


@pytest.mark.parametrize("model", ["fisheye", "rational", "pinhole"])
def test_model_target_origin_warnings_and_covariance_round_trip(tmp_path, model):
    cfg = RigConfig.fisheye() if model == "fisheye" else RigConfig()
    c = SimRig(cfg).true_calibration()
    if model == "rational":
        c = c.with_updates(D1=np.concatenate([c.D1, [[0.01, -0.002, 0.0003]]], 1),
                           D2=np.concatenate([c.D2, [[0.02, 0.001, 0.0]]], 1), model="rational")
    c = _with_uncertainty(c, model)
    back = load_calibration(save_calibration(c, tmp_path / "c.yaml"))
    assert back.model == model and back.D1.shape == c.D1.shape
    assert back.board == c.board and back.origin == c.origin
    assert back.warnings == c.warnings
    u, v = c.uncertainty, back.uncertainty
    assert v.names == u.names and np.array_equal(v.covariance, u.covariance)
    assert v.sigma_px == u.sigma_px and v.method == "jacobian" and v.model == model


def test_a_file_without_the_new_fields_loads_without_uncertainty(tmp_path):
    c = SimRig().true_calibration()
    path = save_calibration(c, tmp_path / "c.yaml")
    text = "\n".join(line for line in path.read_text().splitlines()
                     if not line.startswith(("lens_model", "origin")))
    path.write_text(text + "\n")
    back = load_calibration(path)
    assert back.model == "pinhole" and back.uncertainty is None and back.warnings == ()


def test_unknown_or_inconsistent_lens_models_are_refused(tmp_path):
    c = SimRig().true_calibration()
    path = save_calibration(c, tmp_path / "c.yaml")
    path.write_text(path.read_text().replace("lens_model: pinhole", "lens_model: kaleidoscope"))
    with pytest.raises(CalibrationFileError, match="unknown lens_model 'kaleidoscope'"):
        load_calibration(path)
    path.write_text(path.read_text().replace("lens_model: kaleidoscope", "lens_model: fisheye"))
    with pytest.raises(CalibrationFileError, match="fisheye calibration needs 4"):
        load_calibration(path)


def test_ros_export_writes_the_matching_distortion_model(tmp_path):
    pin = SimRig().true_calibration()
    fish = SimRig(RigConfig.fisheye()).true_calibration()
    assert "distortion_model: plumb_bob" in ros_camera_info_text(pin, "left")
    text = ros_camera_info_text(fish, "right")
    assert "distortion_model: equidistant" in text
    assert "cols: 4" in text.split("distortion_coefficients")[1].split("rectification")[0]
    left, right = export_ros(fish, tmp_path)
    back = import_ros(left, right)
    assert back.model == "fisheye"
    np.testing.assert_allclose(back.D2, fish.D2)
    assert back.baseline_mm == pytest.approx(fish.baseline_mm, rel=1e-9)
