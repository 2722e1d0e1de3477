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
