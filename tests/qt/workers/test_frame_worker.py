"""The frame worker: newest frame wins, processor swaps apply, errors reach the user, stop joins."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from PySide6.QtWidgets import QApplication

from stereo_gui.qt.workers.frame_worker import FrameWorker, ProcessedFrame, StreamState
from stereo_gui.sources.base import FrameSource


def test_delivers_processed_frames_off_the_ui_thread(qtbot, worker, array_source):
    ui_thread = threading.get_ident()
    seen_threads = []

    def proc(frame):
        seen_threads.append(threading.get_ident())
        return float(frame.left.mean())

    worker.set_processor(proc)
    src = array_source()
    # armed before the source starts: frameReady comes once until latest() is taken
    with qtbot.waitSignal(worker.frameReady, timeout=30000):
        worker.set_source(src)
    pf = worker.latest()
    assert isinstance(pf, ProcessedFrame)
    assert pf.output == pytest.approx(float(src.left.mean()))
    assert seen_threads and ui_thread not in seen_threads
    qtbot.waitUntil(lambda: worker.status().camera_fps > 0 and worker.status().processing_fps > 0, timeout=30000)


def test_each_result_carries_when_the_reader_got_its_frame(qtbot, worker, array_source):
    """`read_at` is taken in the reader when the source's read returned: after the source gave
    the frame, before a lane began to process it (the start of the latency to the screen)."""
    import time

    returned: dict[int, float] = {}
    started: dict[int, float] = {}
    src = array_source(fps=60)
    plain_read = src.read

    def read():
        frame = plain_read()
        returned[frame.index] = time.monotonic()
        return frame

    src.read = read

    def proc(frame):
        started[frame.index] = time.monotonic()
        return frame.index

    worker.set_processor(proc)
    with qtbot.waitSignal(worker.frameReady, timeout=30000):
        worker.set_source(src)
    qtbot.waitUntil(lambda: (pf := worker.latest()) is not None and pf.frame.index >= 3,
                    timeout=30000)
    pf = worker.latest()
    i = pf.frame.index
    assert returned[i] <= pf.read_at <= started[i]


def test_frame_ready_is_coalesced_while_the_ui_thread_is_busy(qtbot, worker, array_source):
    """However many results are made while the UI thread handles no events, one notification
    waits for it, not a backlog; and one that nobody answered with latest() (the tab shown draws
    no frames) does not silence the worker for the tab shown next."""
    count = []
    worker.frameReady.connect(lambda: count.append(1))
    calls = []
    published = threading.Event()
    gate = threading.Event()  # holds the 21st call, so no result arrives while we count

    def proc(frame):
        calls.append(frame.index)
        if len(calls) == 21:  # the 20th result was published before this call
            published.set()
            gate.wait(30)
        return frame.index

    worker.set_processor(proc)
    worker.set_source(array_source(fps=500))
    try:
        assert published.wait(30)  # the UI thread (this one) handled no events meanwhile
        QApplication.processEvents()
        assert len(count) == 1
    finally:
        gate.set()
    # nobody called latest(): the notifications go on all the same
    qtbot.waitUntil(lambda: len(count) >= 3, timeout=30000)
    first = worker.latest()
    qtbot.waitUntil(lambda: worker.latest().frame.index > first.frame.index, timeout=30000)


def test_a_frame_of_the_previous_source_in_processing_is_not_published(qtbot, worker,
                                                                       array_source):
    """A frame of source A still being processed when source B is chosen must not become the
    newest result (Capture would freeze a stale pair of the old source)."""
    a = array_source(left=np.zeros((48, 64, 3), np.uint8))
    b = array_source(left=np.full((48, 64, 3), 200, np.uint8))
    inside_a, inside_b = threading.Event(), threading.Event()
    gate_a, gate_b = threading.Event(), threading.Event()

    def proc(frame):
        mean = float(frame.left.mean())
        if mean == 0.0 and not inside_a.is_set():
            inside_a.set()
            gate_a.wait(30)  # held in processing while the source changes
        elif mean == 200.0 and not inside_b.is_set():
            inside_b.set()  # the one processor thread is done with A's frame
            gate_b.wait(30)
        return mean

    worker.set_processor(proc)
    worker.set_source(a)
    try:
        assert inside_a.wait(30)
        worker.set_source(b)
        gate_a.set()
        assert inside_b.wait(30)
        assert worker.latest() is None  # A's result was dropped
    finally:
        gate_a.set()
        gate_b.set()
    qtbot.waitUntil(lambda: worker.latest() is not None, timeout=30000)
    assert worker.latest().output == 200.0


def test_processor_change_applies_to_next_frame(qtbot, worker, array_source):
    worker.set_processor(lambda f: "a")
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: worker.latest() is not None and worker.latest().output == "a",
                    timeout=30000)
    worker.pause()  # nothing new is processed: the last result is "a"'s
    worker.set_processor(lambda f: "b")
    # a result of the processor replaced is never handed out (a frame of the calibration before)
    assert worker.latest() is None
    worker.resume()
    qtbot.waitUntil(lambda: (worker.latest() is not None and worker.latest().output == "b"),
                    timeout=30000)


def test_processor_error_is_reported_once_and_loop_goes_on(qtbot, worker, array_source):
    errors = []
    worker.errorOccurred.connect(errors.append)

    def bad(frame):
        raise ValueError("broken processor")

    worker.set_processor(bad)
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: len(errors) >= 1, timeout=30000)
    assert "broken processor" in errors[0]
    worker.set_processor(lambda f: 1)
    qtbot.waitUntil(lambda: worker.latest() is not None and worker.latest().output == 1,
                    timeout=30000)
    assert len(errors) == 1


def test_a_replaced_processor_that_fails_is_not_reported(qtbot, worker, array_source):
    """The Live tab closes the processor it replaces while a frame may be in it; the frame
    failing there is no news (the new processor's frames go on)."""
    import threading

    errors = []
    worker.errorOccurred.connect(errors.append)
    entered, release = threading.Event(), threading.Event()

    def closing(frame):
        entered.set()
        release.wait(10)
        raise RuntimeError("the live processor is closed")

    worker.set_processor(closing)
    worker.set_source(array_source())
    assert entered.wait(30)
    worker.set_processor(lambda f: "new")
    release.set()
    qtbot.waitUntil(lambda: worker.latest() is not None and worker.latest().output == "new",
                    timeout=30000)
    # an error would have been emitted in the lane before the result, so it would arrive in
    # this thread before the next result's notification
    with qtbot.waitSignal(worker.frameReady, timeout=30000):
        worker.latest()
    assert errors == []


def test_failing_source_is_reported_and_closed(qtbot, worker, array_source):
    src = array_source()
    src.close()  # read() now raises SourceError
    with qtbot.waitSignal(worker.errorOccurred, timeout=30000) as sig:
        worker.set_source(src)
    assert "closed" in sig.args[0]


def test_new_source_closes_the_old_one(qtbot, worker, array_source):
    a, b = array_source(), array_source(left=np.zeros((48, 64, 3), np.uint8))
    worker.set_processor(lambda f: int(f.left.max()))
    worker.set_source(a)
    qtbot.waitUntil(lambda: worker.latest() is not None, timeout=30000)
    worker.set_source(b)
    qtbot.waitUntil(lambda: a.closed.is_set(), timeout=30000)
    qtbot.waitUntil(lambda: worker.latest() is not None and worker.latest().output == 0,
                    timeout=30000)
    worker.stop()
    assert b.closed.is_set()


def test_pause_stops_processing(qtbot, worker, array_source):
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: worker.status().frames_processed > 2, timeout=30000)
    worker.pause()
    assert worker.paused and worker.status().paused
    n = worker.status().frames_processed
    # after pausing, at most the frame being processed at that moment is added; the reader
    # runs tasks while paused, and answers them in order (three round trips while paused)
    answered = []
    worker.sourceTaskDone.connect(lambda tid, result: answered.append(tid))
    for _ in range(3):
        with qtbot.waitSignal(worker.sourceTaskDone, timeout=30000):
            worker.run_on_source(lambda source, frame: None)
    assert worker.status().frames_processed <= n + 1 and len(answered) == 3
    worker.resume()
    qtbot.waitUntil(lambda: worker.status().frames_processed > n + 2, timeout=30000)


def test_the_status_is_one_frozen_snapshot(qtbot, worker, array_source):
    import dataclasses

    assert worker.status().source_name == "" and worker.status().frames_read == 0
    worker.set_processor(lambda f: None)
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: worker.status().frames_processed >= 3, timeout=30000)
    s = worker.status()
    assert s.source_name == "test pair" and s.stream is StreamState.OK and not s.paused
    assert s.frames_read >= s.frames_processed >= 3 and s.pending_frames in (0, 1)
    assert s.skipped_frames == 0 and s.camera_fps > 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.frames_read = 0  # type: ignore[misc]
    worker.pause()
    assert worker.status().paused and not s.paused  # a new snapshot; the old one stays


def test_stop_joins_quickly_and_can_restart(qtbot, worker, array_source):
    worker.set_source(array_source(fps=30))
    qtbot.waitUntil(lambda: worker.status().frames_processed > 0, timeout=30000)
    assert worker.stop(2000)
    assert not worker.is_running()
    worker.set_source(array_source())
    qtbot.waitUntil(lambda: worker.status().frames_processed > 2, timeout=30000)


def test_a_blocked_read_is_reported_and_a_new_source_does_not_wait_for_it(
        qtbot, array_source, monkeypatch):
    import stereo_gui.qt.workers.frame_worker as fw
    from stereo_gui.core.errors import SourceError

    monkeypatch.setattr(fw, "READ_STALL_S", 0.2)
    release = threading.Event()

    class Stuck(FrameSource):
        name = "stuck camera"
        nominal_fps = 30.0
        closed = False

        def read(self):
            release.wait(30)  # a camera that stopped answering, until the test lets it go
            raise SourceError("gone")

        def close(self):
            self.closed = True

    w = FrameWorker()
    stuck = Stuck()
    states = []
    w.streamStatus.connect(states.append)
    try:
        with qtbot.waitSignal(w.errorOccurred, timeout=10000) as sig:
            w.set_source(stuck)
        assert "stuck camera" in sig.args[0] and "not answering" in sig.args[0]
        qtbot.waitUntil(lambda: bool(states), timeout=10000)
        assert (states[0].state, states[0].source_name) == (StreamState.STALLED, "stuck camera")
        assert w.status().stream is StreamState.STALLED
        w.set_source(array_source())
        # read by a new reader; its "frames again" reaches this thread as a queued signal, after
        # the reader has counted the frame
        qtbot.waitUntil(lambda: w.status().frames_read >= 3 and states[-1].state is StreamState.OK,
                        timeout=30000)
        assert w.status().stream is StreamState.OK and states[-1].message == ""  # another source
        assert not stuck.closed  # never closed under its own blocked read
        release.set()
        qtbot.waitUntil(lambda: stuck.closed, timeout=10000)  # by the reader left behind
    finally:
        release.set()
        assert w.stop(2000)


def test_exit_while_a_read_blocks_does_not_abort(tmp_path):
    """A source stuck in read() past the stop timeout must not crash the process at exit
    (a QThread destroyed while running aborts it; workers/threads.py keeps ours alive and leaves
    the process before PySide would delete them)."""
    import subprocess
    import sys

    code = (
        "import threading, time\n"
        "from PySide6.QtWidgets import QApplication\n"
        "from stereo_gui.qt.workers.frame_worker import FrameWorker\n"
        "from stereo_gui.sources.base import FrameSource\n"
        "app = QApplication([])\n"
        "entered = threading.Event()\n"
        "class Stuck(FrameSource):\n"
        "    name = 'stuck camera'; nominal_fps = 30.0\n"
        "    def read(self):\n"
        "        entered.set(); time.sleep(30)\n"
        "    def close(self): pass\n"
        "w = FrameWorker()\n"
        "w.set_source(Stuck())\n"
        "assert entered.wait(10)\n"
        "assert w.stop(200) is False\n"
        "print('stopped-late')\n"
        "raise SystemExit(3)\n"  # the script's own status survives the blocked thread
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, env={**__import__("os").environ,
                                           "QT_QPA_PLATFORM": "offscreen"})
    assert proc.returncode == 3, proc.stderr
    assert "stopped-late" in proc.stdout
    assert "QThread: Destroyed" not in proc.stderr and "Abort" not in proc.stderr


class FlakySource(FrameSource):
    """Frames, then SourceUnavailable while `unavailable` is set (a camera being reconnected),
    then frames again; `fail` makes the next read raise a plain SourceError."""

    name = "flaky cameras"
    nominal_fps = 200.0

    def __init__(self, array_source):
        self._inner = array_source()
        self.unavailable = threading.Event()
        self.fail = threading.Event()
        self.unavailable_reads = 0
        self.closed = self._inner.closed

    def read(self):
        from stereo_gui.core.errors import SourceError, SourceUnavailable

        if self.fail.is_set():
            raise SourceError("the device is gone for good")
        if self.unavailable.is_set():
            self.unavailable_reads += 1
            raise SourceUnavailable("Reconnecting to right camera 2…")
        return self._inner.read()

    def close(self):
        self._inner.close()


def _start_flaky(qtbot, worker, array_source, frames: int):
    """A FlakySource in use once `frames` frames were read; (source, errors, source names,
    stream states) the worker reported from the start."""
    src = FlakySource(array_source)
    errors, names, states = [], [], []
    worker.errorOccurred.connect(errors.append)
    worker.sourceChanged.connect(names.append)
    worker.streamStatus.connect(states.append)
    worker.set_source(src)
    qtbot.waitUntil(lambda: worker.status().frames_read > frames, timeout=30000)
    return src, errors, names, states


def test_a_reconnecting_source_is_kept_said_once_and_resumes(qtbot, worker, array_source):
    src, errors, _names, states = _start_flaky(qtbot, worker, array_source, 2)
    with qtbot.waitSignal(worker.streamStatus, timeout=30000) as sig:
        src.unavailable.set()
    assert sig.args[0].state is StreamState.RECONNECTING
    assert sig.args[0].source_name == "flaky cameras"
    assert "Reconnecting to right camera 2" in sig.args[0].message
    qtbot.waitUntil(lambda: src.unavailable_reads >= 5, timeout=30000)
    assert worker.source() is src and not src.closed.is_set()  # kept, read again
    assert errors == ["flaky cameras: Reconnecting to right camera 2…"]  # said once
    n = worker.status().frames_read
    with qtbot.waitSignal(worker.streamStatus, timeout=30000) as sig:
        src.unavailable.clear()
    assert sig.args[0].state is StreamState.OK
    assert sig.args[0].message == "flaky cameras: frames again"
    qtbot.waitUntil(lambda: worker.status().frames_read > n + 2, timeout=30000)
    assert [s.state for s in states] == [StreamState.RECONNECTING, StreamState.OK]
    assert len(errors) == 1


def test_a_source_that_fails_is_dropped_by_name(qtbot, worker, array_source):
    src, _errors, names, states = _start_flaky(qtbot, worker, array_source, 0)
    with qtbot.waitSignal(worker.streamStatus, timeout=30000) as sig:
        src.fail.set()
    assert sig.args[0].state is StreamState.FAILED and "gone for good" in sig.args[0].message
    assert names == ["flaky cameras", ""] and worker.source() is None
    assert src.closed.is_set() and worker.status().stream is StreamState.FAILED
    # another source: its first frame ends the failed state (no "frames again" for it)
    with qtbot.waitSignal(worker.streamStatus, timeout=30000) as sig:
        worker.set_source(array_source())
    assert (sig.args[0].state, sig.args[0].message) == (StreamState.OK, "")


def test_the_rate_falls_to_zero_when_no_frame_arrives(qtbot, worker, array_source,
                                                     monkeypatch):
    """A read that does not return must not keep showing the last rate."""
    import stereo_gui.qt.workers.frame_status as fs

    monkeypatch.setattr(fs, "RATE_STALE_S", 0.3)  # the test need not wait 2 s
    release = threading.Event()
    inner = array_source(fps=100)

    class Hanging(FrameSource):
        name = "hanging camera"
        nominal_fps = 100.0
        hang = threading.Event()

        def read(self):
            if self.hang.is_set():
                release.wait(30)
            return inner.read()

        def close(self):
            inner.close()

    src = Hanging()
    worker.set_source(src)
    try:
        qtbot.waitUntil(lambda: worker.status().camera_fps > 0, timeout=30000)
        src.hang.set()
        qtbot.waitUntil(lambda: worker.status().camera_fps == 0.0, timeout=30000)
        assert worker.status().stream is StreamState.OK  # (not yet for READ_STALL_S)
    finally:
        release.set()


def test_frame_ready_is_emitted_in_the_ui_thread_only(qtbot, worker, array_source):
    """A direct connection runs in the emitting thread: it must be the UI thread's (PySide
    crashed when a receiver disconnected while the processing thread emitted)."""
    from PySide6.QtCore import Qt

    ui_thread = threading.get_ident()
    emitted_in = []
    worker.frameReady.connect(lambda: emitted_in.append(threading.get_ident()),
                              Qt.ConnectionType.DirectConnection)
    worker.set_source(array_source(fps=200))
    qtbot.waitUntil(lambda: len(emitted_in) >= 5, timeout=30000)
    assert set(emitted_in) == {ui_thread}


class _TwoLanes:
    """A processor for two lanes (two frames at once). The first two calls meet at a barrier (so
    they must run at the same time); the first is held until the test has seen the second's
    result kept, the later calls until the first has ended: the first's result is then older
    than the one kept, and must be dropped."""

    def __init__(self) -> None:
        self.meet = threading.Barrier(2, timeout=30)
        self.lock = threading.Lock()
        self.calls: list[int] = []
        self.active = 0
        self.most_active = 0
        self.second_kept = threading.Event()
        self.first_done = threading.Event()
        self.rest = threading.Event()

    def __call__(self, frame):
        with self.lock:
            self.calls.append(frame.index)
            n = len(self.calls)
            self.active += 1
            self.most_active = max(self.most_active, self.active)
        try:
            if n <= 2:
                self.meet.wait()
            if n == 1:
                self.second_kept.wait(30)
            elif n > 2:
                self.rest.wait(30)
            return frame.index
        finally:
            with self.lock:
                self.active -= 1
            if n == 1:
                self.first_done.set()


def test_a_processor_with_two_lanes_gets_two_frames_at_once_and_the_newest_wins(
        qtbot, worker, array_source):
    proc = _TwoLanes()
    worker.set_processor(proc, lanes=2)
    worker.set_source(array_source(fps=500))
    try:
        qtbot.waitUntil(lambda: worker.latest() is not None, timeout=30000)
        assert proc.most_active == 2  # the barrier let both calls through: they ran at once
        second = worker.latest().frame.index
        assert second == proc.calls[1] > proc.calls[0]
        proc.second_kept.set()  # the first call, an older frame, ends now
        assert proc.first_done.wait(30)
        # its lane has handed its result in once it is in a fourth call (held by `rest`)
        qtbot.waitUntil(lambda: len(proc.calls) >= 4, timeout=30000)
        assert worker.latest().frame.index == second  # not replaced by the older frame
        assert worker.status().pending_frames <= 1 and proc.active <= 2
    finally:
        proc.second_kept.set()
        proc.rest.set()
    qtbot.waitUntil(lambda: worker.latest().frame.index > second, timeout=30000)


def test_a_processor_without_lanes_is_never_called_twice_at_once(qtbot, worker, array_source):
    active, most = [0], [0]
    lock = threading.Lock()

    def proc(frame):
        with lock:
            active[0] += 1
            most[0] = max(most[0], active[0])
        threading.Event().wait(0.005)  # long enough for a second lane to step in, were it let
        with lock:
            active[0] -= 1
        return frame.index

    worker.set_processor(proc)
    worker.set_source(array_source(fps=500))
    qtbot.waitUntil(lambda: worker.status().frames_processed >= 30, timeout=30000)
    assert most[0] == 1


def test_the_status_counts_the_cpu_the_source_spends_in_its_reads(qtbot, worker, array_source):
    """The reader's CPU inside the source's reads is counted (the window bench tells the
    simulated rig's rendering from the pipeline's work with it); a read that waits for its
    camera (sleeps) costs none."""
    import time

    src = array_source(fps=20)  # paced: most of each read is a sleep
    plain_read = src.read
    burnt = []

    def read():
        frame = plain_read()
        if frame.index % 2:  # every other read renders, as it were, for 20 ms of CPU
            t0 = time.thread_time()
            while time.thread_time() - t0 < 0.02:
                pass
            burnt.append(0.02)
        return frame

    src.read = read
    worker.set_processor(lambda f: None)
    assert worker.status().source_cpu_s == 0.0
    worker.set_source(src)
    qtbot.waitUntil(lambda: len(burnt) >= 6, timeout=30000)
    worker.pause()
    s = worker.status()
    # at least what was burnt in the reads counted so far, and not the sleeps (20 fps: 50 ms a
    # read, 25 ms of CPU on average at most beside the pacing's own small cost)
    most = 0.02 * (len(burnt) + 1) + 0.01 * s.frames_read
    assert 0.02 * (len(burnt) - 1) <= s.source_cpu_s <= most
