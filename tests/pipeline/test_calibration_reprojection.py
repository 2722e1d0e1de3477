"""The Calibration tab's review: each used pair's corners reprojected through the calibration.
The board pose is fitted to both images as the joint refinement did, so the errors are the
chart's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.jobs import JobControl
from stereo_gui.pipeline.calibration import calibration_job, reproject_pair
from stereo_gui.sources.sim import write_calibration_set


def _run(job):
    gen = job(JobControl())
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        return stop.value


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    return write_calibration_set(tmp_path_factory.mktemp("reproj"), n_pairs=8, seed=11)


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_reprojected_corners_give_the_charts_per_pair_errors(pairs, model):
    run = _run(calibration_job(pairs, BoardSpec(), 0.0, "bouguet", model))
    calib = run.result.calibration
    assert set(run.reprojections) == {p.name for p in calib.per_pair}
    for p in calib.per_pair:
        rp = run.reprojections[p.name]
        assert rp.detected_left.shape == rp.reprojected_left.shape
        assert rp.rms_left_px == pytest.approx(p.error_left, rel=1e-4)
        assert rp.rms_right_px == pytest.approx(p.error_right, rel=1e-4)
        assert rp.rms_left_px < 0.5  # the rig's corners, not a pose gone astray


def test_a_wrong_calibration_reprojects_far_from_the_corners(pairs):
    run = _run(calibration_job(pairs, BoardSpec(), 0.0, "bouguet"))
    calib = run.result.calibration
    name = calib.per_pair[0].name
    good = reproject_pair(calib, run.detections[name], BoardSpec())
    T = np.asarray(calib.T, float).copy()
    T[1] += 5.0  # the right camera 5 mm lower than calibrated
    bad = reproject_pair(dataclasses.replace(calib, T=T), run.detections[name], BoardSpec())
    assert bad.rms_right_px > 10 * good.rms_right_px
