"""Switching tabs in the window: every tab that shows live frames draws new ones whichever tabs
were shown before it."""

from __future__ import annotations

import pytest

from stereo_gui.qt.dialogs.source_dialog import SourceChoice
from stereo_gui.qt.tabs.capture_state import CaptureState
from stereo_gui.sources.sim import SimSource


def _board_source(sim_rig):
    return SimSource(rig=sim_rig, mode="board", fps=30, frames_per_move=20)


def _frames_pass(qtbot, ctx, n=3):
    """Wait until `n` more frames went through the worker (the tab shown sees them)."""
    done = ctx.frames.status().frames_processed
    qtbot.waitUntil(lambda: ctx.frames.status().frames_processed >= done + n, timeout=30000)


def test_capture_goes_live_again_after_the_calibration_tab(qtbot, ctx, window, sim_rig):
    """Live -> Capture (a pair freezes) -> Calibration -> Capture -> C: new frames are drawn."""
    window.use_source(_board_source(sim_rig), SourceChoice("sim"))
    window.show_tab("live")
    _frames_pass(qtbot, ctx)
    capture = window.capture_tab
    window.show_tab("capture")
    qtbot.waitUntil(lambda: capture.state is CaptureState.REVIEW, timeout=60000)
    window.show_tab("calibration")
    _frames_pass(qtbot, ctx)
    window.show_tab("capture")
    _frames_pass(qtbot, ctx)
    assert capture.state is CaptureState.REVIEW
    capture.cancel_button.click()  # C
    assert capture.prompt.text() == "Live"
    n, index = capture.frames_shown, capture.shown_frame.index
    qtbot.waitUntil(lambda: capture.frames_shown > n, timeout=30000)
    assert capture.shown_frame.index > index


def test_capture_shows_frames_after_measurements_and_calibration(qtbot, ctx, window, sim_rig):
    """After a start: Measurements -> Calibration -> Capture shows the cameras at once, without
    a visit to Live first."""
    window.show_tab("measurements")
    window.use_source(_board_source(sim_rig), SourceChoice("sim"))
    _frames_pass(qtbot, ctx)
    window.show_tab("calibration")
    _frames_pass(qtbot, ctx)
    capture = window.capture_tab
    window.show_tab("capture")
    qtbot.waitUntil(lambda: capture.frames_shown >= 1, timeout=30000)  # (it may freeze at once)


@pytest.mark.slow
def test_live_draws_again_after_capture_froze_a_pair(qtbot, ctx, window, sim_rig):
    """Capture froze a pair (its processor is off) -> Measurements -> Live: Live draws."""
    ctx.calibration_model.set(sim_rig.true_calibration(), None)
    window.use_source(_board_source(sim_rig), SourceChoice("sim"))
    capture = window.capture_tab
    window.show_tab("capture")
    qtbot.waitUntil(lambda: capture.state is CaptureState.REVIEW, timeout=60000)
    window.show_tab("measurements")
    _frames_pass(qtbot, ctx)
    live = window.live_tab
    n = live.frames_shown
    window.show_tab("live")
    qtbot.waitUntil(lambda: live.frames_shown >= n + 2, timeout=60000)


def test_a_paused_live_view_stays_paused_across_a_tab_switch(qtbot, ctx, window, sim_rig):
    """Live, Pause, Measurements, Live: still paused (the button says Resume, no frame is read);
    the other tab got frames meanwhile; Resume goes on."""
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.use_source(_board_source(sim_rig), SourceChoice("sim"))
    live = window.live_tab
    window.show_tab("live")
    qtbot.waitUntil(lambda: live.frames_shown >= 1, timeout=60000)
    live.pause_button.click()
    assert ctx.frames.paused and live.pause_button.text() == "Resume"
    window.show_tab("measurements")
    assert not ctx.frames.paused  # the tab shown now is not held up by the Live tab's pause
    window.show_tab("capture")
    _frames_pass(qtbot, ctx)
    window.show_tab("live")
    assert live.pause_button.isChecked() and live.pause_button.text() == "Resume"
    assert ctx.frames.paused
    shown = live.frames_shown
    live.pause_button.click()
    assert not ctx.frames.paused and live.pause_button.text() == "Pause"
    qtbot.waitUntil(lambda: live.frames_shown > shown, timeout=30000)


@pytest.mark.slow
def test_coming_back_to_a_frozen_pair_says_it_is_from_before(qtbot, ctx, window, sim_rig):
    """Capture (a pair freezes), Measurements, Capture: the pair is still offered, and the
    prompt says it was frozen before the tab was left (it was shown unchanged, without a
    word); Cancel goes live."""
    window.use_source(_board_source(sim_rig), SourceChoice("sim"))
    capture = window.capture_tab
    window.show_tab("capture")
    qtbot.waitUntil(lambda: capture.state is CaptureState.REVIEW, timeout=60000)
    assert capture.prompt.text().startswith("Both cameras see the board")
    window.show_tab("measurements")
    _frames_pass(qtbot, ctx)
    window.show_tab("capture")
    assert capture.state is CaptureState.REVIEW and capture.save_button.isEnabled()
    text = capture.prompt.text()
    assert "This pair was frozen at" in text and "before you left the Capture tab" in text
    capture.cancel_button.click()
    assert capture.prompt.text() == "Live"
