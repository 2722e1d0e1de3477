"""The camera controls panel on the simulated rig (whose cameras answer as V4L2 webcams do) and
on fake devices: controls read back and written, unavailable ones shown as such, the
calibration's controls restored and what still differs warned about with one click to restore,
autofocus warned about with a lock, exposure matched, the skew shown. No real camera."""

from __future__ import annotations

import cv2
import pytest
from factories import make_calibration
from fake_cameras import FakeCapture, FakeControlDevice

import stereo_gui.sources.cameras as cameras
from stereo_gui.pipeline.camera_setup import overlap_brightness
from stereo_gui.qt.tabs.capture_state import CaptureState
from stereo_gui.qt.widgets.camera_controls import NO_CONTROLS, CameraControlsPanel
from stereo_gui.sources.cameras import TwoCameraSource
from stereo_gui.sources.sim import TRUE_FOCUS, RigConfig, SimRig, SimSource

WAIT = 60000


def _sim(**config) -> SimSource:
    return SimSource(SimRig(RigConfig(supersample=1, **config)), mode="board", fps=30.0)


@pytest.fixture
def panel(qtbot, ctx):
    p = CameraControlsPanel(ctx, "capture")
    qtbot.addWidget(p)
    p.resize(900, 300)
    p.show()
    return p


def _wait_report(qtbot, panel):
    qtbot.waitUntil(lambda: panel.model.report is not None, timeout=WAIT)
    return panel.model.report


def test_the_rigs_controls_are_shown_and_a_write_is_read_back(qtbot, ctx, panel):
    src = _sim()
    ctx.frames.set_source(src)
    report = _wait_report(qtbot, panel)
    assert report.settings.left.exposure == 150.0
    panel.set_unfolded(True)
    cell = panel.cells[("exposure", "right")]
    assert cell.stack.currentIndex() == 0 and cell.slider.isEnabled()
    panel.same_check.setChecked(False)
    cell.spin.setValue(90)  # as typed by the technician
    qtbot.waitUntil(lambda: panel.model.report.settings.right.exposure == 90.0, timeout=WAIT)
    assert panel.model.report.settings.left.exposure == 150.0
    assert src.devices[1].get(cv2.CAP_PROP_EXPOSURE) == 90.0  # on the device itself


def test_same_for_both_cameras_writes_both(qtbot, ctx, panel):
    ctx.frames.set_source(_sim())
    _wait_report(qtbot, panel)
    panel.set_unfolded(True)
    assert panel.same_check.isChecked()
    panel.cells[("gain", "left")].spin.setValue(20)
    qtbot.waitUntil(lambda: panel.model.report.settings.right.gain == 20.0, timeout=WAIT)
    assert panel.model.report.settings.left.gain == 20.0


def test_a_control_the_camera_lacks_is_not_a_slider(qtbot, ctx, panel, monkeypatch):
    FakeCapture.devices = {0: {"value": 10, "controls": FakeControlDevice.v4l2()},
                           1: {"value": 100, "controls": FakeControlDevice.v4l2(focus=False),
                               "period_s": 0.02}}
    FakeCapture.log = []
    monkeypatch.setattr(cameras.cv2, "VideoCapture", FakeCapture)
    ctx.frames.set_source(TwoCameraSource(0, 1, backends=(cv2.CAP_V4L2, cv2.CAP_V4L2)))
    _wait_report(qtbot, panel)
    panel.set_unfolded(True)
    right_focus = panel.cells[("focus", "right")]
    assert right_focus.stack.currentIndex() == 1  # "not available" in the slider's place
    assert right_focus.missing.text() == "not available"
    assert not right_focus.auto.isEnabled()
    left_focus = panel.cells[("focus", "left")]
    assert left_focus.stack.currentIndex() == 0
    assert not left_focus.slider.isEnabled()  # held by its autofocus, shown, not writable
    assert "V4L2" in panel.left_title.text()


def test_a_source_without_controls_says_so(qtbot, ctx, panel, array_source):
    ctx.frames.set_source(array_source(fps=60))
    qtbot.waitUntil(lambda: panel.model.unavailable == NO_CONTROLS, timeout=WAIT)
    panel.set_unfolded(True)
    assert panel.note_label.text() == NO_CONTROLS
    assert not panel.match_button.isEnabled()


def _calibration(src: SimSource, focus: float = TRUE_FOCUS):
    return make_calibration(rig=src.rig, focus=focus)


def test_opening_the_cameras_restores_the_calibrations_controls(qtbot, ctx, panel):
    src = _sim(auto_modes=True)  # fresh webcams: autofocus and auto exposure on
    ctx.calibration_model.set(_calibration(src))
    ctx.frames.set_source(src)
    report = _wait_report(qtbot, panel)
    assert report.settings.left.focus_auto is False and report.settings.left.focus == TRUE_FOCUS
    assert report.mismatches == () and not panel.warning_row.isVisible()


def test_a_changed_focus_is_warned_about_and_one_click_restores_it(qtbot, ctx, panel):
    src = _sim()
    ctx.frames.set_source(src)
    _wait_report(qtbot, panel)
    src.camera_controls().left.write("focus", 45)  # someone turned the focus since
    ctx.calibration_model.set(_calibration(src))
    qtbot.waitUntil(lambda: panel.warning_row.isVisible(), timeout=WAIT)
    assert ("The calibration was made at focus 30; the left camera is at 45: distances will be "
            "wrong.") in panel.warning.text()
    assert panel.restore_button.isVisible()
    panel.restore_button.click()
    qtbot.waitUntil(lambda: not panel.warning_row.isVisible(), timeout=WAIT)
    assert src.devices[0].get(cv2.CAP_PROP_FOCUS) == TRUE_FOCUS


def test_autofocus_is_warned_about_and_locked_in_one_click(qtbot, ctx, panel):
    src = _sim(auto_modes=True)
    ctx.frames.set_source(src)
    _wait_report(qtbot, panel)
    panel.model.refresh()
    qtbot.waitUntil(lambda: "Autofocus is on (left and right cameras)" in panel.warning.text(),
                    timeout=WAIT)
    assert "calibration pairs taken so will not hold" in panel.warning.text()
    assert panel.lock_warning_button.isVisible()
    panel.lock_warning_button.click()
    qtbot.waitUntil(lambda: panel.model.report.autofocus_on() == (), timeout=WAIT)
    assert "Autofocus" not in panel.warning.text()
    assert src.devices[0].get(cv2.CAP_PROP_AUTOFOCUS) == 0.0


def test_autofocus_while_measuring_says_distances_will_be_wrong(qtbot, ctx):
    p = CameraControlsPanel(ctx, "live")
    qtbot.addWidget(p)
    p.show()
    ctx.frames.set_source(_sim(auto_modes=True))
    _wait_report(qtbot, p)
    assert "distances read so will be wrong" in p.warning.text()


def test_match_exposure_makes_the_right_image_as_bright_as_the_left(qtbot, ctx, panel):
    src = _sim(auto_modes=True)
    ctx.frames.set_source(src)
    _wait_report(qtbot, panel)
    panel.set_unfolded(True)
    qtbot.waitUntil(lambda: panel.match_button.isEnabled(), timeout=WAIT)
    panel.match_button.click()
    assert panel.model.matching
    qtbot.waitUntil(lambda: not panel.model.matching, timeout=WAIT)
    assert "matched" in panel.model.note, panel.model.note
    frame = src.read()
    lm, rm = overlap_brightness(frame.left, frame.right)
    assert lm / rm == pytest.approx(1.0, abs=0.04)


def test_the_skew_of_the_rig_with_a_200_ms_offset_is_shown_and_marked(qtbot, ctx, panel):
    # (the mark is for a skew above a third of the frame interval the panel measures: 200 ms
    # is above it down to 1.5 frames a second, as a loaded test machine may run; 20 ms was
    # marked only above 17)
    ctx.frames.set_source(_sim(time_offset_s=0.200))
    qtbot.waitUntil(lambda: "200.0 ms median" in panel.skew_label.text(), timeout=WAIT)
    assert "200.0 ms worst (right after left)" in panel.skew_label.text()
    assert "ffcdd2" in panel.skew_label.styleSheet()
    qtbot.waitUntil(lambda: "hold the board still" in panel.warning.text(), timeout=WAIT)


def test_a_saved_pair_records_the_controls_in_the_session(qtbot, ctx, make_tab, tmp_path):
    from stereo_gui.core.board import BoardSpec
    from stereo_gui.files.session import CaptureSession
    from stereo_gui.pipeline.capture import make_capture_processor
    from stereo_gui.qt.tabs.capture import CaptureTab

    tab = make_tab(CaptureTab)
    src = _sim()
    ctx.frames.set_source(src)
    qtbot.waitUntil(lambda: tab.camera_controls.model.report is not None, timeout=WAIT)
    tab.new_session(tmp_path / "s")
    proc = make_capture_processor(BoardSpec())
    rig_src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False)
    frame = rig_src.read()
    tab.show_output(proc(frame), frame)
    assert tab.state is CaptureState.REVIEW
    with qtbot.waitSignal(tab.pairSaved, timeout=WAIT):
        tab.save_button.click()
    qtbot.waitUntil(lambda: CaptureSession.open(tmp_path / "s").camera_controls is not None,
                    timeout=WAIT)
    kept = CaptureSession.open(tmp_path / "s").camera_controls
    assert kept.left.focus == TRUE_FOCUS and kept.left.backend == "simulated"


def test_both_tabs_panels_share_one_model(qtbot, ctx):
    a, b = CameraControlsPanel(ctx, "capture"), CameraControlsPanel(ctx, "live")
    qtbot.addWidget(a)
    qtbot.addWidget(b)
    assert a.model is b.model
