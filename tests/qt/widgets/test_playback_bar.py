"""Playback in the window: record the simulated rig, open the recording as the source, step to
the frame that was measured live, measure the same point: the same distance."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from stereo_gui.qt.dialogs.source_dialog import SourceChoice


@pytest.mark.slow
def test_record_play_back_step_and_measure_the_same_distance(qtbot, ctx, window, sim_rig,
                                                             tmp_path):
    from stereo_gui.files.recording import open_recording
    from stereo_gui.sources.sim import SimSource

    window.resize(1280, 860)
    live = window.live_tab
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.show_tab("live")
    window.use_source(SimSource(rig=sim_rig, mode="scene", fps=15), SourceChoice("sim:scene"))
    assert not live.playback.isVisibleTo(window)  # a live source has no playback controls
    qtbot.waitUntil(lambda: live.frames_shown >= 1, timeout=60000)

    folder = live.start_recording(tmp_path / "rec")
    assert folder is not None
    qtbot.waitUntil(lambda: ctx.recorder.frames_written >= 3, timeout=60000)
    taken = ctx.recorder.last_frame_taken
    assert taken is not None
    # read while recording: a frame the recording holds is shown (on a loaded machine the
    # frames shown just after the start may still be ones captured before it)
    qtbot.waitUntil(lambda: live.shown_frame is not None
                    and live.shown_frame.t_left >= taken[1], timeout=60000)
    # the status bar's timer says so twice a second
    qtbot.waitUntil(lambda: window.recording_label.isVisibleTo(window)
                    and "REC" in window.recording_label.text()
                    and "frames" in window.recording_label.text(), timeout=10000)
    live.set_paused(True)
    t_measured = live.shown_frame.t_left
    point = (420.0, 215.0)  # the panel at 1.3 m of the demo scene
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        live.measure_at(*point)
    m_live = sig.args[0]
    assert m_live.valid, m_live.reason
    with qtbot.waitSignal(ctx.recorder.stopped, timeout=30000):
        live.stop_recording()
    rec = open_recording(folder)
    times = [f.t_left for f in rec.frames]
    assert t_measured in times
    i = times.index(t_measured)
    n = len(rec.frames)

    # the recording as the source (what File > Choose source… and --source DIR do)
    with qtbot.waitSignal(window.sourceOpened, timeout=60000):
        window.open_source(SourceChoice(str(folder)))
    bar = live.playback
    assert bar.isVisibleTo(window) and bar.slider.maximum() == n - 1
    assert window.capture_tab.playback.source() is bar.source()
    bar.toggle_play()  # pause (it also resumes the paused Live view)
    assert bar.source().paused and bar.play_button.text() == "Play" and not ctx.frames.paused
    # one pause button during playback; the live source's marker went with it; a paused
    # playback shows no camera rate
    assert not live.pause_button.isVisibleTo(window)
    assert live.panels["wls"].marker_count() == 0
    qtbot.waitUntil(lambda: window.camera_fps_label.text() == "Playback: paused", timeout=10000)
    start = i - 1 if i > 0 else 1
    bar.seek(start)
    assert bar.step(i - start) == i  # one frame forward (or back)
    src = bar.source()
    # the recorded time of the frame shown, from the first frame
    assert bar.label.text() == (f"frame {i + 1} of {n}   {src.time_s(i):.3f} s of "
                                f"{src.time_s(n - 1):.1f} s")
    assert src.time_s(i) == pytest.approx(times[i] - times[0])
    assert bar.slider.value() == i
    qtbot.waitUntil(lambda: live.shown_frame is not None and live.shown_frame.index == i
                    and live.shown_frame.t_left == t_measured, timeout=60000)
    live.set_paused(True)
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        live.measure_at(*point)
    m_play = sig.args[0]
    assert m_play.valid
    assert m_play.Z_mm == m_live.Z_mm and m_play.disparity_px == m_live.disparity_px
    assert "Playback of" in window.source_label.text()

    # loop off holds the last frame; stepping back works from there
    live.set_paused(False)
    bar.loop_check.setChecked(False)
    assert not bar.source().loop
    bar.seek(n - 1)
    bar.toggle_play()  # play from the last frame: it ends there
    qtbot.waitUntil(lambda: bar.source().finished, timeout=30000)
    bar.refresh()
    assert bar.label.text().startswith(f"frame {n} of {n} (end)   ")
    assert bar.step(-1) == n - 2
    assert bar.label.text().startswith(f"frame {n - 1} of {n}   ")
    # a source without playback hides the bar again
    window.use_source(SimSource(rig=sim_rig, mode="scene", fps=15), SourceChoice("sim:scene"))
    assert not bar.isVisibleTo(window)


def test_playback_bar_of_a_side_by_side_video(qtbot, ctx, tmp_path):
    import cv2

    from stereo_gui.qt.widgets.playback_bar import PlaybackBar
    from stereo_gui.sources.open import open_source

    video = tmp_path / "sbs.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (64, 24))
    for k in range(4):
        writer.write(np.full((24, 64, 3), 40 * k, np.uint8))
    writer.release()
    bar = PlaybackBar(ctx)
    qtbot.addWidget(bar)
    ctx.frames.set_source(open_source(str(video), swap=True).source)  # swapped: still controls
    assert bar.source() is not None and bar.slider.maximum() == 3
    bar.toggle_play()
    assert bar.step(1) >= 1 and bar.source().paused


def test_source_dir_on_the_command_line_plays_the_recording_with_controls(qtbot, tmp_path):
    """`stereo-gui --source DIR` with a recording: the playback bar is there (build_window is
    what run_app calls)."""
    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.qt.app import build_window
    from stereo_gui.sources.base import StereoFrame

    rng = np.random.default_rng(2)
    with RecordingWriter(tmp_path / "rec", fps=10) as w:
        for k in range(3):
            img = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
            w.write(StereoFrame(img, img, 0.1 * k, 0.1 * k, k))
    ctx, window = build_window(source=str(tmp_path / "rec"))
    qtbot.addWidget(window)
    try:
        qtbot.waitUntil(lambda: window.live_tab.playback.source() is not None, timeout=30000)
        bar = window.live_tab.playback
        assert bar.slider.maximum() == 2 and "of 3" in bar.label.text()
        assert ctx.settings.source == str(tmp_path / "rec")
    finally:
        window.close()


def test_speed_and_a_click_on_the_position_bar(qtbot, ctx, tmp_path):
    """Playback speed reaches the source and paces it; a click on the bar goes to the frame
    there (a plain slider only paged towards it)."""
    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.qt.widgets.playback_bar import PlaybackBar
    from stereo_gui.sources.base import StereoFrame
    from stereo_gui.sources.playback import PlaybackSource

    rng = np.random.default_rng(4)
    with RecordingWriter(tmp_path / "rec", fps=10, background=False) as w:
        for k in range(40):
            img = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
            w.write(StereoFrame(img, img, 0.1 * k, 0.1 * k, k))
    bar = PlaybackBar(ctx)
    qtbot.addWidget(bar)
    bar.resize(900, 40)
    bar.show()
    source = PlaybackSource(tmp_path / "rec")
    ctx.frames.set_source(source)
    assert bar.source() is source and source.speed == 1.0
    bar.set_speed(4.0)
    assert source.speed == 4.0
    bar.toggle_play()  # pause, so that the position is the one clicked
    slider = bar.slider
    x = int(slider.width() * 0.75)
    target = slider.value_at(x)
    assert 25 <= target <= 32
    qtbot.mouseClick(slider, Qt.MouseButton.LeftButton, pos=QPoint(x, slider.height() // 2))
    assert source.position == target and slider.value() == target
