"""The generator worker: progress, result, errors as signals, cooperative cancel."""

from __future__ import annotations

import threading

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import JobState, Progress
from stereo_gui.qt.workers.job_worker import JobWorker


def _counting_job(n):
    def job(cancel):
        for i in range(n):
            yield Progress(i, n, f"step {i}")
        return "result"
    return job


def test_job_reports_progress_and_result(qtbot):
    worker = JobWorker(_counting_job(5), "count")
    assert worker.outcome is None
    seen = []
    worker.progress.connect(seen.append)
    with qtbot.waitSignal(worker.finished_ok, timeout=30000) as blocker:
        worker.start()
    assert blocker.args == ["result"]
    qtbot.waitUntil(lambda: len(seen) == 5)
    assert [p.done for p in seen] == [0, 1, 2, 3, 4]
    assert seen[-1].percent == 80
    assert worker.wait(2000) and worker.outcome is JobState.FINISHED


def test_error_becomes_failed_signal(qtbot):
    def job(cancel):
        yield Progress(0, 1, "reading")
        raise InputError("folder /nowhere does not exist")

    worker = JobWorker(job, "calibration")
    with qtbot.waitSignal(worker.failed, timeout=30000) as blocker:
        worker.start()
    assert blocker.args == ["folder /nowhere does not exist"]
    assert worker.wait(2000) and worker.outcome is JobState.FAILED


def test_unexpected_error_is_named(qtbot):
    def job(cancel):
        yield Progress(0, 1)
        raise ValueError("boom")

    worker = JobWorker(job, "export")
    with qtbot.waitSignal(worker.failed, timeout=30000) as blocker:
        worker.start()
    assert "export failed" in blocker.args[0] and "boom" in blocker.args[0]
    assert worker.wait(2000)


def test_cancel_stops_at_next_step(qtbot):
    gate = threading.Event()
    steps = []

    def job(cancel):
        for i in range(1000):
            steps.append(i)
            if i == 2:
                gate.wait(5)  # hold here until the test has asked to cancel
            yield Progress(i, 1000)
        return "never"

    worker = JobWorker(job, "slow")
    results = []
    worker.finished_ok.connect(results.append)
    def on_progress(p):
        if p.done == 1:
            worker.cancel()
            gate.set()

    worker.progress.connect(on_progress)
    with qtbot.waitSignal(worker.cancelled, timeout=30000):
        worker.start()
    assert worker.wait(2000) and worker.outcome is JobState.CANCELLED
    assert results == []
    assert len(steps) < 10


def test_control_reports_progress_from_inside_a_step(qtbot):
    def core_like(progress, cancel):  # a core function with progress= and cancel= callbacks
        for i in range(3):
            progress(i + 1, 3, f"stage {i}")
        return 42

    def job(control):
        yield Progress(0, 3, "start")
        return core_like(control.report, control)

    worker = JobWorker(job, "core")
    seen = []
    def on_progress(p):
        seen.append(p.text)

    worker.progress.connect(on_progress)
    with qtbot.waitSignal(worker.finished_ok, timeout=30000) as blocker:
        worker.start()
    assert blocker.args == [42]
    qtbot.waitUntil(lambda: len(seen) == 4)
    assert seen == ["start", "stage 0", "stage 1", "stage 2"]
    assert worker.wait(2000)


def test_core_cancelled_error_counts_as_cancel(qtbot):
    from stereo_gui.core.detect import check_cancel

    gate = threading.Event()

    def job(control):
        yield Progress(0, 1)
        gate.wait(5)
        check_cancel(control)  # raises the core's Cancelled
        return "never"

    worker = JobWorker(job, "core")
    def on_progress(p):
        worker.cancel()
        gate.set()

    worker.progress.connect(on_progress)
    failures = []
    worker.failed.connect(failures.append)
    with qtbot.waitSignal(worker.cancelled, timeout=30000):
        worker.start()
    assert worker.wait(2000)
    assert failures == []


def test_a_worker_runs_once_and_its_thread_ends_with_its_job(qtbot):
    worker = JobWorker(_counting_job(2), "once")
    done = []
    worker.done.connect(lambda: done.append(worker.outcome))
    worker.start()
    with pytest.raises(RuntimeError, match="already started"):
        worker.start()
    qtbot.waitUntil(lambda: done == [JobState.FINISHED], timeout=30000)
    assert worker.wait(2000) and not worker.isRunning()
