"""A recording just made is in File > Open recent at once."""

from __future__ import annotations

import numpy as np


def test_a_recording_just_made_is_in_open_recent(qtbot, ctx, window, array_source, tmp_path):
    """Record, Stop: the recording is the first of File > Open recent, and opens from there
    (it appeared only after it had been played once)."""
    rng = np.random.default_rng(2)
    img = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
    ctx.frames.set_source(array_source(img, img, fps=100))
    folder = tmp_path / "rec-new"
    window.show_tab("live")
    assert window.live_tab.start_recording(folder) == folder
    qtbot.waitUntil(lambda: ctx.recorder.frames_written >= 3, timeout=20000)
    with qtbot.waitSignal(ctx.recorder.stopped, timeout=20000):
        window.live_tab.stop_recording()
    assert ctx.settings.recent_files[0] == str(folder.resolve())
    window.recent_menu.aboutToShow.emit()  # what opening the menu does
    first = window.recent_menu.actions()[0]
    assert first.text().startswith("Recording: rec-new") and first.isEnabled()
    with qtbot.waitSignal(window.sourceOpened, timeout=60000) as opened:
        first.trigger()
    assert opened.args == [str(folder.resolve())]
