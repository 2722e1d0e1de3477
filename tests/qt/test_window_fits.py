"""The window fits a laptop screen whatever the Live tab shows."""

from __future__ import annotations

import itertools

from PySide6.QtWidgets import QApplication

from stereo_gui.qt.tabs.live_views import VIEWS

SCREEN = (1280, 720)  # the smallest screen the application is used on
TITLE_BAR_PX = 32  # what a window manager's frame takes of the height


def test_showing_more_views_never_makes_the_window_taller(qtbot, ctx, window, sim_rig):
    ctx.set_calibration(sim_rig.true_calibration(), None, note="simulated rig's TRUE calibration")
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


def test_save_calibration_is_in_view_after_a_calibration_at_1366x768(qtbot, ctx, window,
                                                                      tmp_path):
    """The Calibration tab's Save calibration… is on screen, whole, once a calibration with
    warnings fills the figures (it was below the fold of the left pane at 1366x768)."""
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=12, seed=11)
    window.resize(1366, 768 - TITLE_BAR_PX)
    window.show_tab("calibration")
    tab = window.calibration_tab
    tab.folder_edit.setText(str(folder))
    with qtbot.waitSignal(tab.calibrationFinished, timeout=120000):
        assert tab.start_calibration()
    try:
        qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
        QApplication.processEvents()
        button = tab.save_button
        assert button.isVisible() and button.isEnabled()
        assert button.visibleRegion().boundingRect() == button.rect()
    finally:
        # saved, so that closing asks nothing; closing joins the tabs' threads
        assert window.save_calibration(str(tmp_path / "calibration.yaml"))
        window.close()
