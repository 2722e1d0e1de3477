"""Recording the live stream from the Live tab: raw frames with timestamps, written by the
writer's thread with the frames handed over in the frame worker's reader thread; a write error
stops recording with a message and keeps what was written."""

from __future__ import annotations

import errno
import threading

import numpy as np

from stereo_gui.files.recording import open_recording
from stereo_gui.qt.widgets.record_button import RECORD_TEXT


def _pair():
    rng = np.random.default_rng(5)
    left = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
    return left, np.ascontiguousarray(left[:, ::-1])


def test_record_button_writes_raw_frames_with_timestamps(qtbot, ctx, live, array_source,
                                                         tmp_path, monkeypatch):
    from stereo_gui.files import recording

    left, right = _pair()
    writers = []
    real_write = recording.RecordingWriter.write

    def spy(self, frame):  # which thread hands the frames over
        writers.append(threading.current_thread())
        return real_write(self, frame)

    monkeypatch.setattr(recording.RecordingWriter, "write", spy)
    ctx.update_settings(recordings_dir=str(tmp_path / "recs"))
    ctx.frames.set_source(array_source(left, right, fps=100))
    with qtbot.waitSignal(ctx.recorder.started, timeout=5000) as sig:
        live.record_button.click()  # a toggle: on
    folder = sig.args[0]
    assert folder.startswith(str(tmp_path / "recs")) and "rec-" in folder
    assert live.record_button.isChecked() and ctx.recorder.is_recording
    qtbot.waitUntil(lambda: ctx.recorder.frames_written >= 4, timeout=20000)
    # the button says how long and how much it has recorded (updated by its own timer)
    qtbot.waitUntil(lambda: live.record_button.text().startswith("■ Stop 0:"), timeout=20000)
    assert "frames written" in live.record_button.toolTip()
    with qtbot.waitSignal(ctx.recorder.stopped, timeout=20000) as sig:
        live.record_button.click()  # off: the writer closes on its own thread
    result = sig.args[0]
    assert not live.record_button.isChecked() and live.record_button.text() == RECORD_TEXT
    assert not result.error and result.frames >= 4
    assert threading.main_thread() not in writers  # never copied on the UI thread

    rec = open_recording(folder)
    assert rec.complete and len(rec.frames) == result.frames and rec.size == (32, 24)
    t = [f.t_left for f in rec.frames]
    assert all(b > a for a, b in zip(t, t[1:], strict=False))  # the source's own clock
    import cv2

    for f in rec.frames[:2]:
        assert np.array_equal(cv2.imread(str(f.left)), left)
        assert np.array_equal(cv2.imread(str(f.right)), right)


def test_a_full_disk_stops_recording_with_a_message_and_keeps_the_frames(
        qtbot, ctx, live, array_source, tmp_path, monkeypatch):
    from stereo_gui.files import recording

    real = recording.write_bytes_atomic
    calls = {"n": 0}

    def disk_fills_up(path, data):
        calls["n"] += 1
        if calls["n"] > 6:  # three frames of two images fit
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, data)

    monkeypatch.setattr(recording, "write_bytes_atomic", disk_fills_up)
    left, right = _pair()
    ctx.frames.set_source(array_source(left, right, fps=100))
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert live.start_recording(tmp_path / "rec") == tmp_path / "rec"
    with qtbot.waitSignal(ctx.recorder.stopped, timeout=20000) as sig:
        pass
    result = sig.args[0]
    assert "No space left on device" in result.error and result.frames == 3
    assert not ctx.recorder.is_recording and not live.record_button.isChecked()
    assert errors and "No space left on device" in errors[-1] and "kept" in errors[-1]
    rec = open_recording(tmp_path / "rec")  # what was written before stays readable
    assert len(rec.frames) == 3 and not rec.complete


def test_recording_into_a_used_folder_is_refused(qtbot, ctx, live, array_source, tmp_path):
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "keep.txt").write_text("x")
    ctx.frames.set_source(array_source())
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert live.start_recording(tmp_path / "used") is None
    assert "never overwrites" in errors[-1] and not live.record_button.isChecked()


def test_changing_the_source_stops_the_recording(qtbot, ctx, live, array_source, tmp_path):
    ctx.frames.set_source(array_source())
    live.start_recording(tmp_path / "rec")
    qtbot.waitUntil(lambda: ctx.recorder.frames_written >= 1, timeout=20000)
    with qtbot.waitSignal(ctx.recorder.stopped, timeout=20000) as sig:
        ctx.frames.set_source(array_source())
    assert "source changed" in sig.args[0].note and not sig.args[0].error


def test_new_recording_folder_names(tmp_path):
    import datetime as dt

    from stereo_gui.qt.workers.recorder import format_elapsed, new_recording_folder

    now = dt.datetime(2026, 5, 4, 3, 2, 1)
    first = new_recording_folder(tmp_path, now)
    assert first.name == "rec-20260504-030201"
    first.mkdir()
    assert new_recording_folder(tmp_path, now).name == "rec-20260504-030201-2"
    assert format_elapsed(75.4) == "1:15" and format_elapsed(3725) == "1:02:05"


def test_closing_the_application_while_recording_keeps_a_complete_recording(
        qtbot, ctx, array_source, tmp_path):
    ctx.frames.set_source(array_source())
    ctx.recorder.start(tmp_path / "rec", source_name="test pair", fps=200)
    qtbot.waitUntil(lambda: ctx.recorder.frames_written >= 2, timeout=20000)
    assert ctx.shutdown(2000)  # what the window does when it closes
    rec = open_recording(tmp_path / "rec")
    assert rec.complete and len(rec.frames) >= 2 and rec.source_name == "test pair"
    assert not ctx.recorder.is_recording
