"""Calibration health and drift: a turned right camera is found from the scene and the rotation
refined back, keeping intrinsics and baseline; swapped cameras show as negative disparities."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.health import (DRIFT_WARN_PX, calibration_health, health_detect_scale,
                                    refine_rotation)
from stereo_gui.sources.sim import Scene, SimRig

SEED = 17  # not used while tuning


@pytest.fixture(scope="module")
def rig_and_calib():
    rig = SimRig(seed=SEED)
    return rig, rig.true_calibration()


def _rectified(calib, left, right):
    m = calib.rectify_maps()
    return (cv2.remap(left, m.left_x, m.left_y, cv2.INTER_LINEAR),
            cv2.remap(right, m.right_x, m.right_y, cv2.INTER_LINEAR))


def _health(rig, calib, seed=0):
    left, right = rig.render_scene(Scene.demo(), np.random.default_rng(seed))
    return calibration_health(*_rectified(calib, left, right)), left, right


def test_a_fresh_calibration_is_healthy(rig_and_calib):
    rig, calib = rig_and_calib
    h, _, _ = _health(rig, calib)
    assert h.measured and not h.drifted and not h.swapped
    assert h.vertical_px < 0.25 and h.matches > 200
    assert "OK" in h.text()


def test_a_turned_right_camera_is_detected_and_refined_back(rig_and_calib):
    """A 0.3 degree turn of the right camera is detected and refined back to an
    epipolar error below 0.2 px, intrinsics and baseline kept."""
    import dataclasses

    rig, calib = rig_and_calib
    # made a while ago: the refined calibration must carry a time of its own (the fixture's
    # calibration can be made within the same second as the refinement)
    calib = dataclasses.replace(calib, created="2026-01-01T00:00:00+00:00")
    rig.turn_right_camera(0.3, "tilt")
    try:
        h, left, right = _health(rig, calib, 1)
        assert h.drifted and h.vertical_px > DRIFT_WARN_PX
        assert "moved since calibration" in h.text()
        ref = refine_rotation(calib, left, right, "a test frame")
        new = ref.calibration
        assert ref.before_px > DRIFT_WARN_PX and ref.after_px < 0.2
        # a new frame, rectified with the refined calibration
        h2, _, _ = _health(rig, new, 2)
        assert h2.vertical_px < 0.2 and not h2.drifted
        # metric: intrinsics and the baseline as calibrated; the rotation as the rig's now
        for name in ("M1", "D1", "M2", "D2"):
            assert np.array_equal(getattr(new, name), getattr(calib, name))
        assert new.baseline_mm == pytest.approx(calib.baseline_mm, rel=1e-12)
        err = np.degrees(np.linalg.norm(cv2.Rodrigues(new.R @ rig.truth.R.T)[0]))
        assert err < 0.02
        assert ref.turn_deg[0] == pytest.approx(0.3, abs=0.02)
        assert "refined from the scene" in new.origin and "a test frame" in new.origin
        assert new.created != calib.created
    finally:
        rig.reset_turn()
    assert rig.turned_deg == 0.0


@pytest.mark.parametrize("turn_deg", [0.0, 0.3])
def test_the_live_check_on_half_size_features_gives_the_same_figure(rig_and_calib, turn_deg):
    """The live check finds its features on images at most HEALTH_DETECT_WIDTH wide and places
    them at full size: the figure agrees with the full-size one to 0.06 px, fresh and with a
    turned camera."""
    rig, calib = rig_and_calib
    rig.turn_right_camera(turn_deg, "tilt") if turn_deg else None
    try:
        left, right = rig.render_scene(Scene.demo(), np.random.default_rng(3))
        rl, rr = _rectified(calib, left, right)
        full = calibration_health(rl, rr)
        live = calibration_health(rl, rr, health_detect_scale(rl.shape[1]))
    finally:
        rig.reset_turn()
    assert health_detect_scale(rl.shape[1]) == 0.5 and live.matches > 200
    assert live.vertical_px == pytest.approx(full.vertical_px, abs=0.06)
    assert live.drifted == full.drifted == (turn_deg > 0)


def test_swapped_cameras_show_as_negative_disparities(rig_and_calib):
    rig, calib = rig_and_calib
    left, right = rig.render_scene(Scene.demo(), np.random.default_rng(4))
    a, b = _rectified(calib, left, right)
    h = calibration_health(b, a)
    assert h.swapped and "swapped" in h.text()


def test_a_scene_without_texture_cannot_refine(rig_and_calib):
    _, calib = rig_and_calib
    flat = np.full((480, 640, 3), 120, np.uint8)
    with pytest.raises(CalibrationError, match="feature matches"):
        refine_rotation(calib, flat, flat)
    h = calibration_health(flat, flat)
    assert not h.measured and "too few feature matches" in h.text()


@pytest.mark.parametrize("turn_deg", [0.0, 0.3])
def test_the_live_check_of_a_wide_camera_finds_its_features_at_a_quarter(turn_deg):
    """1280x720: features found at a quarter (0.12 s of CPU a check instead of 0.40 s at half
    size), the figure within 0.06 px of the full-size one."""
    from stereo_gui.sources.sim import RigConfig

    rig = SimRig(RigConfig.for_size((1280, 720)), seed=SEED)
    calib = rig.true_calibration()
    if turn_deg:
        rig.turn_right_camera(turn_deg, "tilt")
    left, right = rig.render_scene(Scene.demo(), np.random.default_rng(5))
    rl, rr = _rectified(calib, left, right)
    assert health_detect_scale(rl.shape[1]) == 0.25
    full = calibration_health(rl, rr)
    live = calibration_health(rl, rr, health_detect_scale(rl.shape[1]))
    assert live.matches > 200
    assert live.vertical_px == pytest.approx(full.vertical_px, abs=0.06)
    assert live.drifted == full.drifted == (turn_deg > 0)


def _bf_pairs(dl, dr, ratio=0.75):
    """The pairs of OpenCV's BFMatcher: knnMatch(k=2) with the ratio test, and match() back."""
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    back = {m.queryIdx: m.trainIdx for m in matcher.match(dr, dl)}
    return sorted((m.queryIdx, m.trainIdx) for m, n in matcher.knnMatch(dl, dr, k=2)
                  if m.distance < ratio * n.distance and back.get(m.trainIdx) == m.queryIdx)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mutual_ratio_matches_are_the_pairs_bfmatcher_gives(seed):
    """One distance matrix for both directions gives BFMatcher's pairs: descriptors that have a
    noisy twin on the other side, ones without, and near-twins where the ratio test decides."""
    from stereo_gui.core.util import mutual_ratio_matches

    rng = np.random.default_rng(seed)
    n = 600
    dl = rng.random((n, 128), np.float32) * 40
    twins = rng.permutation(n)[:400]
    dr = np.concatenate([dl[twins] + rng.normal(0, 8, (400, 128)),  # noisy twins
                         rng.random((300, 128)) * 40]).astype(np.float32)  # no twin
    dr[400:450] = dl[twins[:50]] + rng.normal(0, 8, (50, 128))  # second twins: the ratio test
    il, ir = mutual_ratio_matches(dl, dr)
    got = sorted(zip(il.tolist(), ir.tolist()))
    assert got == _bf_pairs(dl, dr)
    assert 100 < len(got) < 400  # the test has pairs that pass and pairs that fail


def test_mutual_ratio_matches_on_the_rig_scene(rig_and_calib):
    from stereo_gui.core.util import mutual_ratio_matches

    rig, calib = rig_and_calib
    left, right = rig.render_scene(Scene.demo(), np.random.default_rng(3))
    sift = cv2.SIFT_create(nfeatures=1500)
    _, dl = sift.detectAndCompute(cv2.cvtColor(left, cv2.COLOR_BGR2GRAY), None)
    _, dr = sift.detectAndCompute(cv2.cvtColor(right, cv2.COLOR_BGR2GRAY), None)
    il, ir = mutual_ratio_matches(dl, dr)
    assert sorted(zip(il.tolist(), ir.tolist())) == _bf_pairs(dl, dr)
    assert len(il) > 300
