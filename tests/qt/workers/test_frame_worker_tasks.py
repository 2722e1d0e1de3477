"""The frame worker's reader thread runs tasks on the source (the cameras' controls) and keeps the
skew between the two cameras' frame times."""

from __future__ import annotations

import threading

import pytest

from stereo_gui.core.errors import SourceError
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource


def _run(qtbot, worker, fn, after_frames=0):
    """Run `fn` on the worker's source and return what the reader thread answered."""
    answers = {}

    def done(tid, result):
        answers[tid] = result

    worker.sourceTaskDone.connect(done)
    tid = worker.run_on_source(fn, after_frames)
    qtbot.waitUntil(lambda: tid in answers, timeout=30000)
    worker.sourceTaskDone.disconnect(done)
    return answers[tid]


def test_a_task_runs_in_the_reader_thread_with_the_source_and_its_newest_frame(
        qtbot, worker, array_source):
    ui = threading.get_ident()
    src = array_source()
    worker.set_source(src)
    seen = _run(qtbot, worker, lambda s, f: (s, f, threading.get_ident()), after_frames=2)
    source, frame, thread = seen
    assert source is src and frame is not None and thread != ui


def test_a_task_runs_while_the_worker_is_paused(qtbot, worker, array_source):
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: worker.status().frames_read > 0, timeout=30000)
    worker.pause()
    read = worker.status().frames_read
    assert _run(qtbot, worker, lambda s, f: "done") == "done"
    assert worker.status().frames_read <= read + 1  # (a read under way when pausing may end)


def test_a_failing_task_returns_its_exception_and_reading_goes_on(qtbot, worker, array_source):
    worker.set_source(array_source())

    def boom(source, frame):
        raise ValueError("no such control")

    result = _run(qtbot, worker, boom)
    assert isinstance(result, ValueError)
    read = worker.status().frames_read
    qtbot.waitUntil(lambda: worker.status().frames_read > read + 2, timeout=30000)


def test_without_a_source_a_task_is_told_so(qtbot, worker):
    result = _run(qtbot, worker, lambda s, f: "ran")
    assert isinstance(result, SourceError)


def test_the_skew_on_the_rig_with_a_20_ms_offset(qtbot, worker):
    """The rig's right camera takes its pictures 20 ms after the left: the worker's figures
    over the last second say 20 ms, median and worst, and whether it exceeds a third of the
    frame interval."""
    rig = SimRig(RigConfig(supersample=1, time_offset_s=0.020))
    worker.set_source(SimSource(rig, mode="board", paced=True, fps=30.0))
    qtbot.waitUntil(lambda: worker.timing().frames >= 10, timeout=60000)
    t = worker.timing()
    assert t.median_ms == pytest.approx(20.0, abs=0.01)
    assert t.worst_ms == pytest.approx(20.0, abs=0.01)
    # the interval is the frames' own (about 33 ms; longer or shorter on a busy machine, whose
    # frames come late and then catch up), and the warning follows from it
    assert t.interval_ms > 0 and t.too_large == (20.0 > t.interval_ms / 3)
    assert "20.0 ms median" in t.text() and "right after left" in t.text()


def test_the_skew_is_forgotten_when_the_source_changes(qtbot, worker, array_source):
    rig = SimRig(RigConfig(supersample=1, time_offset_s=0.020))
    worker.set_source(SimSource(rig, mode="scene", paced=False))
    qtbot.waitUntil(lambda: worker.timing().frames >= 3, timeout=60000)
    worker.set_source(array_source())
    assert worker.timing().frames == 0 or worker.timing().median_ms == 0.0
    qtbot.waitUntil(lambda: worker.timing().frames >= 3, timeout=30000)
    assert worker.timing().worst_ms == 0.0
