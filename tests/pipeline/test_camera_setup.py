"""Setting up the two cameras: the calibration's controls restored and what still differs said,
focus locked, and the right camera's exposure matched to the left's. On the simulated rig's
cameras (which answer as V4L2 webcams do) and on fake devices: no real camera is involved."""

from __future__ import annotations

import cv2
import pytest

from stereo_gui.core.camera_settings import CameraSettings, PairSettings
from stereo_gui.pipeline.camera_setup import (
    MATCH_MAX_STEPS,
    MATCH_SETTLE_FRAMES,
    begin_exposure_matching,
    exposure_match_step,
    lock_focus,
    overlap_brightness,
    read_controls,
    restore_calibration_controls,
)
from stereo_gui.sources.camera_controls import CameraControls, PairControls
from stereo_gui.sources.sim import TRUE_FOCUS, RigConfig, SimRig, SimSource

from factories import make_calibration
from fake_cameras import FakeControlDevice


def _sim(**config) -> SimSource:
    return SimSource(SimRig(RigConfig(supersample=1, **config)), mode="scene", paced=False)


def test_restore_writes_the_calibrations_focus_back_and_then_nothing_differs():
    src = _sim(auto_modes=True)
    for _ in range(10):
        src.read()  # autofocus has wandered off the calibration's focus
    calib = make_calibration(rig=src.rig, focus=TRUE_FOCUS)
    before = read_controls(src.camera_controls(), calib, (640, 480))
    assert {m.what for m in before.mismatches} == {"autofocus"}
    report = restore_calibration_controls(src.camera_controls(), calib, (640, 480))
    assert report.mismatches == ()
    assert report.settings.left.focus == TRUE_FOCUS and report.settings.left.focus_auto is False
    assert src.read().truth.focal_scale == (1.0, 1.0)  # the lens is where it was calibrated


def test_a_focus_the_camera_will_not_take_is_warned_about_in_the_technicians_words():
    left = FakeControlDevice.v4l2(values={cv2.CAP_PROP_AUTOFOCUS: 0.0,
                                          cv2.CAP_PROP_FOCUS: 45.0},
                                  ignores={cv2.CAP_PROP_FOCUS})
    right = FakeControlDevice.v4l2(values={cv2.CAP_PROP_AUTOFOCUS: 0.0})
    pair = PairControls(CameraControls(left, cv2.CAP_V4L2, "left"),
                        CameraControls(right, cv2.CAP_V4L2, "right"))
    held = CameraSettings("V4L2", focus_auto=False, focus=30.0)
    src = _sim()
    calib = make_calibration(rig=src.rig, camera_controls=PairSettings(held, held))
    report = restore_calibration_controls(pair, calib, (640, 480))
    (m,) = report.mismatches
    assert m.what == "focus" and m.side == "left" and m.restorable
    assert m.message == ("the calibration was made at focus 30; the left camera is at 45: "
                         "distances will be wrong")
    assert any(r.outcome == "ignored" for r in report.failures)


def test_another_resolution_is_said_and_cannot_be_restored_by_writing_controls():
    src = _sim()
    calib = make_calibration(rig=src.rig, focus=TRUE_FOCUS)
    report = read_controls(src.camera_controls(), calib, (1280, 720))
    (m,) = report.mismatches
    assert m.what == "resolution" and not m.restorable and "640x480" in m.message


def test_a_calibration_of_swapped_cameras_restores_each_camera_its_own_focus():
    src = _sim()
    left_cal = CameraSettings("simulated", focus_auto=False, focus=40.0)
    right_cal = CameraSettings("simulated", focus_auto=False, focus=50.0)
    calib = make_calibration(rig=src.rig, camera_controls=PairSettings(left_cal, right_cal),
                             swapped_inputs=True)
    report = restore_calibration_controls(src.camera_controls(), calib, (640, 480))
    # the calibration's left camera is the source's right one
    assert report.settings.right.focus == 40.0 and report.settings.left.focus == 50.0
    assert report.mismatches == ()


def test_lock_focus_turns_autofocus_off_where_the_lens_is():
    src = _sim(auto_modes=True)
    for _ in range(6):
        src.read()
    before = read_controls(src.camera_controls())
    assert before.autofocus_on() == ("left", "right")
    focus = before.settings.left.focus
    report = lock_focus(src.camera_controls(), ("left",))
    assert report.autofocus_on() == ("right",)
    assert report.settings.left.focus == focus


def _match(src: SimSource, max_exposure=None):
    pair = src.camera_controls()
    begin_exposure_matching(pair)
    steps = []
    for _ in range(MATCH_MAX_STEPS):
        for _ in range(MATCH_SETTLE_FRAMES):
            f = src.read()
        step = exposure_match_step(pair, f.left, f.right, max_exposure)
        steps.append(step)
        if step.done:
            break
    return steps, src.read()


def test_exposure_matching_brings_the_right_image_to_the_lefts_brightness_and_holds_it():
    src = _sim(auto_modes=True)
    for _ in range(20):
        f = src.read()
    lm, rm = overlap_brightness(f.left, f.right)
    assert abs(lm / rm - 1) > 0.08  # two webcams left to themselves differ
    steps, f = _match(src)
    assert steps[-1].done and "matched" in steps[-1].message, [s.message for s in steps]
    lm, rm = overlap_brightness(f.left, f.right)
    assert lm / rm == pytest.approx(1.0, abs=0.03)
    left, right = src.camera_controls().read()
    assert left.value("exposure_auto") is False and right.value("exposure_auto") is False
    for _ in range(10):
        f = src.read()  # held: the automatic exposure does not undo it
    lm, rm = overlap_brightness(f.left, f.right)
    assert lm / rm == pytest.approx(1.0, abs=0.03)


def test_exposure_matching_uses_the_gain_when_the_exposure_is_at_its_limit():
    src = _sim()
    pair = src.camera_controls()
    pair.left.write("gain", 40)  # the left is brighter through its gain...
    steps, f = _match(src, max_exposure=150)  # ...and the right's exposure may not go higher
    assert steps[-1].done
    lm, rm = overlap_brightness(f.left, f.right)
    assert lm / rm == pytest.approx(1.0, abs=0.05)
    assert pair.right.read().value("gain") > 0


def test_a_camera_without_exposure_or_gain_says_it_cannot_be_matched():
    src = _sim()
    f = src.read()
    dev = FakeControlDevice.avfoundation()
    pair = PairControls(CameraControls(dev, cv2.CAP_AVFOUNDATION, "left"),
                        CameraControls(FakeControlDevice.avfoundation(), cv2.CAP_AVFOUNDATION,
                                       "right"))
    darker = (f.right * 0.7).astype(f.right.dtype)
    step = exposure_match_step(pair, f.left, darker)
    assert step.done and "cannot be brought closer" in step.message
