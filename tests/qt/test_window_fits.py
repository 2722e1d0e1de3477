"""The window fits a laptop screen whatever the Live tab shows."""

from __future__ import annotations

import dataclasses
import itertools

import pytest
from PySide6.QtWidgets import QApplication

from stereo_gui.qt.tabs.capture_state import CaptureState
from stereo_gui.qt.tabs.live_views import VIEWS

SCREEN = (1280, 720)  # the smallest screen the application is used on
TITLE_BAR_PX = 32  # what a window manager's frame takes of the height


def test_showing_more_views_never_makes_the_window_taller(qtbot, ctx, window, sim_rig):
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.show_tab("live")
    # everything that can stand above and below the views at once
    window.banner.show_text("Running on the SIMULATED stereo rig: a long banner " * 3)
    window.error_bar.show_text("Something went wrong, and the message says so at length " * 3)
    window.live_tab.playback.show()
    w, h = SCREEN[0], SCREEN[1] - TITLE_BAR_PX
    window.resize(w, h)
    qtbot.waitUntil(lambda: window.height() == h)
    live = window.live_tab
    keys = list(VIEWS)
    for n in range(1, len(keys) + 1):
        for shown in itertools.combinations(keys, n):
            for key, check in live.view_checks.items():
                check.setChecked(key in shown)
            QApplication.processEvents()  # the layouts apply the change as posted events
            assert window.minimumSizeHint().height() <= h, shown
            assert window.minimumSizeHint().width() <= w, shown
            assert (window.width(), window.height()) == (w, h), shown


def _calibrated(qtbot, window, tmp_path, screen):
    """The Calibration tab after calibrating 12 simulated pairs in a window filling `screen`
    (less the title bar)."""
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=12, seed=11)
    window.resize(screen[0], screen[1] - TITLE_BAR_PX)
    window.show_tab("calibration")
    tab = window.calibration_tab
    tab.folder_edit.setText(str(folder))
    with qtbot.waitSignal(tab.calibrationFinished, timeout=120000):
        assert tab.start_calibration()
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
    QApplication.processEvents()
    return tab


@pytest.mark.slow
def test_save_calibration_is_in_view_after_a_calibration_at_1366x768(qtbot, ctx, window,
                                                                      tmp_path):
    """The Calibration tab's Save calibration… is on screen, whole, once a calibration with
    warnings fills the figures (it was below the fold of the left pane at 1366x768)."""
    tab = _calibrated(qtbot, window, tmp_path, (1366, 768))
    try:
        button = tab.save_button
        assert button.isVisible() and button.isEnabled()
        assert button.visibleRegion().boundingRect() == button.rect()
    finally:
        # saved, so that closing asks nothing; closing joins the tabs' threads
        assert window.save_calibration(str(tmp_path / "calibration.yaml"))
        window.close()


def test_the_saved_pairs_list_shows_several_pairs_at_1280x720(qtbot, ctx, window, tmp_path):
    """At 1280x720 the coverage guidance took the side pane's height and the list showed
    about one thumbnail: four are in view now, whole."""
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=6, seed=3)
    window.resize(SCREEN[0], SCREEN[1] - TITLE_BAR_PX)
    window.show_tab("capture")
    tab = window.capture_tab
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=30000)
    QApplication.processEvents()
    assert "Not ready yet" in tab.coverage.readiness_label.text()  # the long guidance is shown
    lst = tab.pair_list
    assert lst.count() == 6
    view = lst.viewport().rect()
    assert all(view.contains(lst.visualItemRect(lst.item(i))) for i in range(4))


def test_capture_views_keep_their_height_whatever_the_prompt_says(qtbot, ctx, window):
    """At 1280x720 and 1366x768 a prompt of one line ("Live") and the longest one (a pair
    under review, the regions it reaches, the ask for a session) leave the views where they
    are (they jumped by about 20 px)."""
    from stereo_gui.core.board import BoardSpec
    from stereo_gui.pipeline.capture import make_capture_processor
    from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    try:
        frame = src.read()
        out = proc(frame)
    finally:
        src.close()
    assert out.detection.found
    window.show_tab("capture")
    tab = window.capture_tab
    for w, h in ((1280, 720), (1366, 768)):
        window.resize(w, h - TITLE_BAR_PX)
        tab.go_live()
        # the board out of one view first: the same pose may freeze again
        tab.show_output(dataclasses.replace(out, detection=dataclasses.replace(
            out.detection, right=None)), frame)
        QApplication.processEvents()
        live_height = tab.view.height()
        tab.show_output(out, frame)  # frozen: the long review prompt (no session: it asks)
        assert tab.state is CaptureState.REVIEW
        assert "Save asks for a session folder" in tab.prompt.text()
        QApplication.processEvents()
        assert tab.view.height() == live_height, (w, h)


def test_the_camera_controls_and_their_warning_leave_the_window_on_the_screen(qtbot, ctx,
                                                                            window, sim_rig):
    """Unfolding the camera controls raised the window's minimum height to 735 px, the
    autofocus warning to 772, on a 720 px screen; folded, it stayed so."""
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.show_tab("live")
    window.banner.show_text("Running on the SIMULATED stereo rig: a long banner " * 3)
    w, h = SCREEN[0], SCREEN[1] - TITLE_BAR_PX
    window.resize(w, h)
    qtbot.waitUntil(lambda: window.height() == h)
    panel = window.live_tab.camera_controls
    panel.set_unfolded(True)
    panel.warning.setText("Autofocus is on (left and right): the lens refocuses when the scene "
                          "changes, and with it the focal length: distances read so will be "
                          "wrong when it refocuses. Lock the focus where it is (last read: left "
                          "0, right 0).")
    panel.warning_row.show()
    QApplication.processEvents()
    assert window.minimumSizeHint().height() <= h
    assert (window.width(), window.height()) == (w, h)
    panel.set_unfolded(False)
    panel.warning_row.hide()
    QApplication.processEvents()
    assert window.minimumSizeHint().height() <= h


@pytest.mark.slow
def test_the_calibration_results_fit_their_pane_at_1280x720(qtbot, ctx, window, tmp_path):
    """At the default divider position the results box was cut off on the right (the epipolar
    error, the baseline's difference, the cameras' cy) with no scroll bar: its values wrap."""
    from stereo_gui.qt.widgets.helpers import VerticalScroll

    tab = _calibrated(qtbot, window, tmp_path, SCREEN)
    try:
        pane = next(s for s in tab.findChildren(VerticalScroll) if s.widget().isAncestorOf(
            tab.figures))
        assert tab.figures.width() <= pane.viewport().width()
        assert "after rectification" in tab.figures.epipolar_label.text()
        assert tab.figures.epipolar_label.width() <= tab.figures.width()
    finally:
        assert window.save_calibration(str(tmp_path / "calibration.yaml"))
        window.close()
