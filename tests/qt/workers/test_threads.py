"""The workers run in QThreads of ours; closing during a blocked read neither aborts nor hangs;
a fast source and a slow processor build no backlog."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest
from PySide6.QtCore import QCoreApplication, QThread

from stereo_gui.core.jobs import Progress
from stereo_gui.qt.workers.frame_worker import LANES, FrameWorker
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.job_worker import JobWorker
from stereo_gui.qt.workers.threads import WorkerThread, live_threads
from stereo_gui.sources.base import FrameSource


class _Recording(FrameSource):
    """A source wrapper that records the thread each read runs in."""

    def __init__(self, source) -> None:
        self._source = source
        self.name = source.name
        self.nominal_fps = source.nominal_fps
        self.read_threads: list = []

    def read(self):
        self.read_threads.append(QThread.currentThread())
        return self._source.read()

    def close(self) -> None:
        self._source.close()


def _main_thread():
    return QCoreApplication.instance().thread()


def test_frames_are_read_and_processed_in_our_qthreads(qtbot, array_source):
    assert QThread.currentThread() is _main_thread()  # the test itself runs in the UI thread
    worker = FrameWorker()
    source = _Recording(array_source())
    seen = []

    def processor(frame):
        seen.append(QThread.currentThread())
        return frame.index

    try:
        worker.set_processor(processor)
        worker.set_source(source)
        qtbot.waitUntil(lambda: worker.status().frames_processed >= 3, timeout=30000)
        reader, *lanes = worker.threads()
        assert {type(t) for t in (reader, *lanes)} == {WorkerThread}
        assert len(lanes) == LANES and reader not in lanes and _main_thread() not in lanes
        assert set(source.read_threads) == {reader}
        assert set(seen) == {lanes[0]}  # a processor without `lanes` runs in the first lane only
        assert all(t in live_threads() for t in (reader, *lanes))
    finally:
        assert worker.stop(2000)
    assert not any(t in live_threads() or t.isRunning() for t in (reader, *lanes))


def test_jobs_and_generator_jobs_run_in_our_qthreads(qtbot):
    jobs = JobRunner("test-jobs")
    try:
        with qtbot.waitSignal(jobs.finished, timeout=30000) as sig:
            jobs.submit(lambda _control: QThread.currentThread())
        ran_in = sig.args[1]
        assert isinstance(ran_in, WorkerThread) and ran_in is jobs.worker_thread()
        assert ran_in is not _main_thread()
    finally:
        assert jobs.stop(2000)

    def job(control):
        yield Progress(0, 1, "where am I")
        return QThread.currentThread()

    w = JobWorker(job, "where")
    with qtbot.waitSignal(w.finished_ok, timeout=30000) as sig:
        w.start()
    assert sig.args[0] is w.worker_thread() and isinstance(sig.args[0], WorkerThread)
    assert sig.args[0] is not _main_thread()
    assert w.wait(2000)


def test_a_fast_source_and_a_slow_processor_build_no_backlog(qtbot, array_source):
    """The processor holds each frame until the test lets it go; meanwhile the reader goes on
    reading: only the newest frame waits, the ones between are skipped, the UI is told at most
    once a result."""
    worker = FrameWorker()
    gate = threading.Event()
    processed: list[int] = []
    pending_seen: list[int] = []

    def slow(frame):
        pending_seen.append(worker.status().pending_frames)
        gate.wait(10)  # the test opens the gate; a bound so that a failure cannot hang it
        gate.clear()
        processed.append(frame.index)
        return frame.index

    notified = []
    worker.frameReady.connect(lambda: notified.append(1))
    try:
        worker.set_processor(slow)
        worker.set_source(array_source(fps=1000.0))
        qtbot.waitUntil(lambda: worker.status().frames_read >= 1 and bool(pending_seen), timeout=30000)
        first_read = worker.status().frames_read
        qtbot.waitUntil(lambda: worker.status().frames_read >= first_read + 30, timeout=30000)
        assert worker.status().pending_frames == 1  # one slot, not a queue
        for _ in range(3):
            n = len(processed)
            gate.set()
            qtbot.waitUntil(lambda n=n: len(processed) > n, timeout=30000)
            read_now = worker.status().frames_read
            qtbot.waitUntil(lambda r=read_now: worker.status().frames_read >= r + 10, timeout=30000)
        assert all(p <= 1 for p in pending_seen)
        # frames were skipped: each processed frame is far newer than the one before
        assert all(b - a >= 10 for a, b in zip(processed, processed[1:], strict=False))
        assert worker.status().frames_processed <= len(processed) < worker.status().frames_read / 5
        qtbot.waitUntil(lambda: bool(notified), timeout=30000)
        # never more notifications than results: nothing queues up in the UI thread
        assert 1 <= len(notified) <= worker.status().frames_processed
        assert worker.latest().output == processed[-1]
    finally:
        gate.set()
        worker.set_processor(None)
        assert worker.stop(2000)


CLOSE_WHILE_BLOCKED = r"""
import sys, threading, time
import stereo_gui.sources.open as opening
from stereo_gui.sources.base import FrameSource

entered = threading.Event()

class Stuck(FrameSource):
    name = "stuck camera"
    nominal_fps = 30.0
    def read(self):
        entered.set()
        threading.Event().wait()  # a camera that never answers
    def close(self):
        pass

opening.open_source = lambda *a, **k: opening.OpenedSource(Stuck())

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from stereo_gui.qt.app import run_app

def stuck_job(control):
    yield from ()
    threading.Event().wait()  # an OpenCV call that does not return

def close_when_blocked():
    if not entered.is_set():
        QTimer.singleShot(20, close_when_blocked)
        return
    from stereo_gui.qt.workers.job_worker import JobWorker

    window = next(w for w in QApplication.topLevelWidgets() if hasattr(w, "ctx"))
    window.ctx.jobs.submit(lambda _c: threading.Event().wait())  # a click's job that hangs too
    worker = JobWorker(stuck_job, "stuck")  # and a calibration stuck in one call
    window.ctx.register_worker(worker)
    worker.start()
    time.sleep(0.2)  # well inside the read and the jobs
    print("closing at", time.time(), flush=True)
    window.close()

QTimer.singleShot(0, close_when_blocked)
sys.exit(run_app(source="sim"))
"""


@pytest.mark.slow
def test_closing_during_a_blocked_read_exits_0_within_3_s(tmp_path):
    """A read, a job and a generator job that never return: closing shares one 2 s deadline
    among them and leaves; no abort, exit status 0."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen",
           "STEREO_GUI_CONFIG_DIR": str(tmp_path / "cfg")}
    proc = subprocess.Popen([sys.executable, "-c", CLOSE_WHILE_BLOCKED], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    ended = time.time()
    assert proc.returncode == 0, err
    assert "QThread: Destroyed" not in err and "Abort" not in err and "Traceback" not in err
    closing = [line for line in out.splitlines() if line.startswith("closing at")]
    assert closing, out + err
    took = ended - float(closing[0].split()[-1])
    assert took < 3.0, f"closing took {took:.2f} s"


_POOL_PROBE = """
import os, sys
import cv2, numpy as np
from stereo_gui.pipeline.concurrency import use_opencv_threads_beside_lanes
before = set(os.listdir("/proc/self/task"))
if sys.argv[1] == "calling":
    use_opencv_threads_beside_lanes()
for _ in range(3):  # parallel OpenCV calls, as the frame lanes and the UI thread make
    cv2.resize(np.zeros((720, 1280), np.uint8), (640, 360))
print(len(set(os.listdir("/proc/self/task")) - before), cv2.getNumThreads())
"""


def test_opencv_threads_leave_the_cpus_to_the_frame_lanes_as_run_app_sets_them():
    """run_app sets OpenCV's thread count to the CPUs the frame lanes leave, plus one: on 2
    CPUs every call runs in its calling thread and no pool of OpenCV's own (which ran beside
    the UI thread, at its priority) is started. Without the call OpenCV starts its pool."""
    import cv2
    import pytest

    from stereo_gui.pipeline.concurrency import opencv_threads_beside_lanes

    assert [opencv_threads_beside_lanes(n) for n in (1, 2, 4, 8)] == [1, 1, 3, 7]
    if not sys.platform.startswith("linux") or os.cpu_count() != 2 or cv2.getNumThreads() < 2:
        pytest.skip("counting threads in /proc on a 2-CPU Linux machine, OpenCV with its pool")

    def new_threads_and_count(mode: str) -> list[int]:
        out = subprocess.run([sys.executable, "-c", _POOL_PROBE, mode], capture_output=True,
                             text=True, timeout=60, check=True)
        return [int(v) for v in out.stdout.split()]

    assert new_threads_and_count("calling") == [0, 1]
    started, count = new_threads_and_count("default")
    assert started >= 1 and count >= 2
