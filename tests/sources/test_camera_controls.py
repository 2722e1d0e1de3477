"""Camera controls through OpenCV's capture properties, against fake devices that answer as a
V4L2, a DirectShow, a Media Foundation and an AVFoundation webcam do (tests/fake_cameras.py).
No real camera is involved: these check our conventions and read-back logic, not a driver."""

from __future__ import annotations

import cv2
import pytest

import stereo_gui.sources.cameras as cameras
from stereo_gui.core.camera_settings import CameraSettings, PairSettings
from stereo_gui.sources.camera_controls import CameraControls, convention_for
from stereo_gui.sources.cameras import TwoCameraSource

from fake_cameras import FakeCapture, FakeControlDevice, unplug


def _controls(device: FakeControlDevice, backend: int, side: str = "left") -> CameraControls:
    return CameraControls(device, backend, side)


def _written(device: FakeControlDevice, prop: int) -> list[float]:
    return [v for p, v, _ok in device.sets if p == prop]


# ---- V4L2 -------------------------------------------------------------------------------------
def test_v4l2_reads_every_control_in_its_own_units():
    state = _controls(FakeControlDevice.v4l2(), cv2.CAP_V4L2).read()
    assert state.backend == "V4L2"
    s = state.settings()
    assert s == CameraSettings("V4L2", focus_auto=True, focus=30.0, exposure_auto=True,
                               exposure=156.0, gain=0.0, wb_auto=True, wb_temperature=4600.0,
                               brightness=128.0)
    assert state.reading("exposure").unit == "x100 us"
    assert all(r.available for r in state.readings)


def test_v4l2_auto_exposure_is_written_1_for_manual_and_3_for_automatic():
    dev = FakeControlDevice.v4l2()
    c = _controls(dev, cv2.CAP_V4L2)
    assert c.write("exposure_auto", False).outcome == "took"
    assert c.write("exposure_auto", True).outcome == "took"
    assert _written(dev, cv2.CAP_PROP_AUTO_EXPOSURE) == [1.0, 3.0]


def test_v4l2_a_value_held_by_its_automatic_mode_is_refused_but_not_lost():
    dev = FakeControlDevice.v4l2()
    c = _controls(dev, cv2.CAP_V4L2)
    r = c.write("focus", 45)
    assert r.outcome == "refused" and "automatic mode is on" in r.message
    assert c.read_one("focus").available  # the camera has a focus: it is only held now
    assert c.write("focus_auto", False).ok
    r = c.write("focus", 47)  # the device takes focus in steps of 5
    assert r.outcome == "adjusted" and r.read_back == 45.0 and "rounds or limits" in r.message
    assert c.read().settings().focus == 45.0


def test_v4l2_lock_holds_the_focus_where_it_is():
    dev = FakeControlDevice.v4l2(values={cv2.CAP_PROP_FOCUS: 55.0})
    c = _controls(dev, cv2.CAP_V4L2)
    results = c.lock("focus")
    assert [r.outcome for r in results] == ["took", "took"]
    s = c.read().settings()
    assert s.focus_auto is False and s.focus == 55.0


def test_a_fixed_focus_webcam_shows_focus_as_unavailable_and_nothing_is_written():
    dev = FakeControlDevice.v4l2(focus=False)
    c = _controls(dev, cv2.CAP_V4L2)
    state = c.read()
    for name in ("focus_auto", "focus"):
        r = state.reading(name)
        assert not r.available and r.value is None and "does not have" in r.note
    assert c.write("focus", 40).outcome == "unavailable"
    assert not _written(dev, cv2.CAP_PROP_FOCUS)
    assert state.settings().focus is None


def test_a_control_that_says_yes_and_does_nothing_becomes_unavailable():
    dev = FakeControlDevice.v4l2(ignores={cv2.CAP_PROP_GAIN})
    c = _controls(dev, cv2.CAP_V4L2)
    r = c.write("gain", 100)
    assert r.outcome == "ignored" and "shown as unavailable" in r.message
    assert not c.read().reading("gain").available  # never a slider that does nothing


def test_a_value_beyond_the_cameras_range_at_its_limit_is_not_taken_for_a_missing_control():
    dev = FakeControlDevice.v4l2(values={cv2.CAP_PROP_AUTO_EXPOSURE: 1.0,
                                         cv2.CAP_PROP_EXPOSURE: 2047.0})
    dev.ranges[cv2.CAP_PROP_EXPOSURE] = (3, 2047, 1)
    c = _controls(dev, cv2.CAP_V4L2)
    r = c.write("exposure", 3000)
    assert r.outcome in ("ignored", "refused") and "stays at 2047" in r.message
    assert c.read().reading("exposure").available
    assert c.read().settings().exposure == 2047.0  # the probe put it back


def test_apply_writes_switches_off_before_the_values_they_free():
    dev = FakeControlDevice.v4l2()
    c = _controls(dev, cv2.CAP_V4L2)
    want = CameraSettings("V4L2", focus_auto=False, focus=40.0, exposure_auto=False,
                          exposure=200.0, gain=12.0, wb_auto=False, wb_temperature=5000.0,
                          brightness=120.0)
    results = c.apply(want)
    assert all(r.ok for r in results), [r.message for r in results]
    assert c.read().settings() == want
    props = [p for p, _v, _ok in dev.sets]
    assert props.index(cv2.CAP_PROP_AUTOFOCUS) < props.index(cv2.CAP_PROP_FOCUS)
    assert props.index(cv2.CAP_PROP_AUTO_EXPOSURE) < props.index(cv2.CAP_PROP_EXPOSURE)


def test_apply_leaves_a_value_to_its_automatic_mode():
    dev = FakeControlDevice.v4l2(values={cv2.CAP_PROP_AUTOFOCUS: 0.0})
    c = _controls(dev, cv2.CAP_V4L2)
    c.apply(CameraSettings("V4L2", focus_auto=True, focus=80.0))
    assert not _written(dev, cv2.CAP_PROP_FOCUS)
    assert c.read().settings().focus_auto is True


def test_settings_of_another_backend_are_not_restored():
    dev = FakeControlDevice.v4l2()
    c = _controls(dev, cv2.CAP_V4L2)
    (r,) = c.apply(CameraSettings("DirectShow", focus_auto=False, exposure=-6.0))
    assert r.outcome == "skipped" and "other units" in r.message
    assert dev.sets == []


# ---- DirectShow -------------------------------------------------------------------------------
def test_dshow_auto_exposure_is_unavailable_but_a_manual_exposure_is_written_in_log2_seconds():
    dev = FakeControlDevice.dshow()
    c = _controls(dev, cv2.CAP_DSHOW)
    state = c.read()
    assert not state.reading("exposure_auto").available
    assert state.reading("exposure").unit == "log2 s" and state.value("exposure") == -6.0
    assert state.freed("exposure")  # no switch to hold it: the value is written directly
    r = c.write("exposure_auto", False)
    assert r.outcome == "unavailable"
    assert c.write("exposure", -7).outcome == "took"


def test_dshow_auto_exposure_would_be_written_as_a_quarter_and_three_quarters():
    conv = convention_for(cv2.CAP_DSHOW)
    spec = conv.specs["exposure_auto"]
    assert (spec.off, spec.on) == (0.25, 0.75)


def test_dshow_autofocus_reads_back_directshows_flags():
    dev = FakeControlDevice.dshow()
    c = _controls(dev, cv2.CAP_DSHOW)
    assert c.read().value("focus_auto") is True  # flags 1: automatic
    assert c.write("focus_auto", False).outcome == "took"
    assert dev.get(cv2.CAP_PROP_AUTOFOCUS) == 2.0  # flags 2: manual
    assert _written(dev, cv2.CAP_PROP_AUTOFOCUS) == [0.0]


def test_dshow_has_no_automatic_white_balance_but_a_temperature():
    dev = FakeControlDevice.dshow()
    c = _controls(dev, cv2.CAP_DSHOW)
    state = c.read()
    assert not state.reading("wb_auto").available
    assert "no automatic white balance" in state.reading("wb_auto").note
    assert c.write("wb_temperature", 5200).outcome == "took"
    assert _written(dev, cv2.CAP_PROP_WHITE_BALANCE_BLUE_U) == [5200.0]


# ---- Media Foundation and AVFoundation ----------------------------------------------------------
def test_msmf_auto_exposure_is_0_and_1_never_a_quarter_which_would_mean_automatic():
    dev = FakeControlDevice.msmf()
    c = _controls(dev, cv2.CAP_MSMF)
    assert c.write("exposure_auto", False).outcome == "took"
    assert _written(dev, cv2.CAP_PROP_AUTO_EXPOSURE) == [0.0]
    assert c.read().value("exposure_auto") is False


def test_avfoundation_offers_no_controls_and_writes_nothing():
    dev = FakeControlDevice.avfoundation()
    c = _controls(dev, cv2.CAP_AVFOUNDATION)
    state = c.read()
    assert not any(r.available for r in state.readings)
    assert "macOS" in state.reading("focus").note
    assert c.apply(CameraSettings("AVFoundation", focus_auto=False, focus=30.0)) == []
    assert dev.sets == []


@pytest.mark.parametrize("platform, backend", [("linux", "V4L2"), ("win32", "MSMF"),
                                               ("darwin", "AVFoundation")])
def test_the_backend_opencv_chooses_is_the_platforms_default(platform, backend):
    assert convention_for(None, platform).backend == backend


# ---- the two-camera source ----------------------------------------------------------------------
@pytest.fixture
def control_cams(monkeypatch):
    FakeCapture.devices = {0: {"value": 10, "controls": FakeControlDevice.v4l2()},
                           1: {"value": 100, "controls": FakeControlDevice.v4l2(focus=False)}}
    FakeCapture.log = []
    monkeypatch.setattr(cameras.cv2, "VideoCapture", FakeCapture)
    return FakeCapture


def test_two_camera_source_gives_each_cameras_controls(control_cams):
    src = TwoCameraSource(0, 1, backends=(cv2.CAP_V4L2, cv2.CAP_V4L2))
    pair = src.camera_controls()
    left, right = pair.read()
    assert (left.side, right.side) == ("left", "right")
    assert left.reading("focus").available and not right.reading("focus").available
    results = pair.write("gain", 20)
    assert [r.ok for r in results] == [True, True]
    assert pair.settings().left.gain == pair.settings().right.gain == 20.0
    src.close()


def test_swapped_cameras_swap_their_controls_too(control_cams):
    src = TwoCameraSource(0, 1, swap=True, backends=(cv2.CAP_V4L2, cv2.CAP_V4L2))
    left, right = src.camera_controls().read()
    assert not left.reading("focus").available  # device 1 is the left camera now
    assert right.reading("focus").available
    src.close()


def test_a_camera_plugged_in_again_gets_its_controls_back(control_cams, monkeypatch):
    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    src = TwoCameraSource(0, 1, backends=(cv2.CAP_V4L2, cv2.CAP_V4L2))
    src.reconnect_interval_s = 0.0
    pair = src.camera_controls()
    pair.left.lock("focus")
    pair.left.write("focus", 60)
    unplug(control_cams.devices, 0)
    with pytest.raises(cameras.SourceUnavailable):
        for _ in range(cameras.MAX_FAILED_GRABS + 1):
            src.read()
    assert src.camera_controls() is None  # no controls while a camera is missing
    fresh = FakeControlDevice.v4l2()  # plugged in again: autofocus on, focus 30
    control_cams.devices[0] = {"value": 10, "controls": fresh}
    src.read()
    s = src.camera_controls().settings().left
    assert s.focus_auto is False and s.focus == 60.0
    src.close()


def test_pair_settings_survive_json():
    s = PairSettings(CameraSettings("V4L2", focus_auto=False, focus=30.0),
                     CameraSettings("V4L2", exposure=120.0))
    assert PairSettings.from_json(s.to_json()) == s
    with pytest.raises(ValueError, match="focus should be a finite number"):
        PairSettings.from_json({"left": {"focus": "near"}})
