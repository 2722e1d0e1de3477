"""The simulated rig's camera controls: exposure and gain per camera, autofocus that drifts the
focal length, automatic modes that make the two cameras differ, and the cameras' time offset."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim import (
    FOCAL_CHANGE_PER_STEP,
    TRUE_FOCUS,
    RigConfig,
    SimRig,
    SimSource,
)


def _source(mode="board", **config) -> SimSource:
    rig = SimRig(RigConfig(supersample=1, **config))
    return SimSource(rig, mode=mode, paced=False, seed=3, frames_per_move=20)


def _mean(img) -> float:
    return float(img.mean())


def test_the_rig_as_built_holds_its_controls_where_its_truth_was_made():
    src = _source()
    left, right = src.camera_controls().read()
    for state in (left, right):
        s = state.settings()
        assert s.backend == "simulated"
        assert s.focus_auto is False and s.focus == TRUE_FOCUS
        assert s.exposure_auto is False and s.wb_auto is False
    f = src.read()
    assert f.truth.focal_scale == (1.0, 1.0) and f.t_left == f.t_right
    assert all(d.look().neutral for d in src.devices)


def test_the_same_frames_as_before_the_controls_existed():
    """With its controls as built the source renders exactly what the rig renders."""
    src = _source(mode="board")
    f = src.read()
    rig2 = SimRig(RigConfig(supersample=1))
    rng = np.random.default_rng(3 + 1000003)
    left, right = rig2.render_board_pair(f.truth.pose, rng)
    assert np.array_equal(left, f.left) and np.array_equal(right, f.right)


def test_exposure_and_gain_act_on_each_camera_alone():
    src = _source(mode="scene", noise_sigma=0.0)
    f0 = src.read()
    pair = src.camera_controls()
    assert pair.right.write("exposure", 75).outcome == "took"  # half the exposure
    f1 = src.read()
    assert _mean(f1.right) == pytest.approx(_mean(f0.right) / 2, rel=0.05)
    assert _mean(f1.left) == pytest.approx(_mean(f0.left), abs=0.5)
    assert pair.right.write("gain", 64).outcome == "took"  # 64 steps of gain double it
    f2 = src.read()
    assert _mean(f2.right) == pytest.approx(_mean(f0.right), rel=0.05)


def test_in_their_automatic_modes_the_two_cameras_expose_differently():
    src = _source(mode="scene", auto_modes=True)
    for _ in range(25):
        f = src.read()
    left, right = src.camera_controls().read()
    assert left.value("exposure_auto") is True
    assert left.value("exposure") != right.value("exposure")
    assert abs(_mean(f.left) - _mean(f.right)) > 8  # the brightness differs between the images


def test_autofocus_drifts_the_focal_length_and_locking_it_stops_the_drift():
    src = _source(mode="board", auto_modes=True)
    scales = [src.read().truth.focal_scale[0] for _ in range(30)]
    assert max(abs(s - 1.0) for s in scales) > 0.004  # it refocused on the board
    assert len(set(scales)) > 3  # and went on moving with it
    pair = src.camera_controls()
    pair.left.lock("focus")
    locked = [src.read().truth.focal_scale[0] for _ in range(15)]
    assert len(set(locked)) == 1


def test_a_manual_focus_moves_the_focal_length_and_the_image():
    src = _source(mode="scene", noise_sigma=0.0)
    f0 = src.read()
    assert src.camera_controls().left.write("focus", TRUE_FOCUS + 15).outcome == "took"
    f1 = src.read()
    assert f1.truth.focal_scale[0] == pytest.approx(1 + 15 * FOCAL_CHANGE_PER_STEP)
    assert f1.truth.focal_scale[1] == 1.0
    assert np.abs(f1.left.astype(int) - f0.left).mean() > 1.0
    assert np.array_equal(f1.right, f0.right)


def test_focus_cannot_be_written_while_autofocus_holds_it_as_on_a_v4l2_webcam():
    src = _source(mode="scene", auto_modes=True)
    left = src.camera_controls().left
    r = left.write("focus", 60)
    assert r.outcome == "refused" and left.read_one("focus").available


def test_the_white_balance_tints_the_image():
    src = _source(mode="scene", noise_sigma=0.0)
    f0 = src.read()
    src.camera_controls().right.write("wb_temperature", 6500)
    f1 = src.read()
    b0, r0 = f0.right[..., 0].mean(), f0.right[..., 2].mean()
    b1, r1 = f1.right[..., 0].mean(), f1.right[..., 2].mean()
    assert r1 / b1 > r0 / b0 * 1.1


def test_the_right_camera_takes_its_picture_later_and_sees_the_board_moved():
    src = _source(mode="board", time_offset_s=0.020)
    frames = [src.read() for _ in range(8)]
    for f in frames:
        assert f.t_right - f.t_left == pytest.approx(0.020, abs=1e-9)
    moving = frames[5]  # between two resting poses
    assert not np.allclose(moving.truth.pose.t, moving.truth.pose_right.t)


def test_a_time_offset_of_a_second_or_more_is_refused():
    with pytest.raises(InputError, match="under a second"):
        RigConfig(time_offset_s=1.5)
