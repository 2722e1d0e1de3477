"""The job runner: results and failures come back by signal with the job's id."""

from __future__ import annotations

from stereo_gui.qt.workers.job_runner import JobRunner


def test_job_runner_delivers_results_with_ids(qtbot):
    jobs = JobRunner()
    try:
        with qtbot.waitSignal(jobs.finished, timeout=30000) as sig:
            job_id = jobs.submit(lambda: 6 * 7)
        assert sig.args == [job_id, 42]
        with qtbot.waitSignal(jobs.failed, timeout=30000) as sig:
            bad_id = jobs.submit(lambda: 1 / 0)
        assert sig.args[0] == bad_id and "division" in sig.args[1]
    finally:
        assert jobs.stop(2000)


def test_a_queued_job_can_be_cancelled_a_running_one_not(qtbot):
    import threading

    jobs = JobRunner()
    gate = threading.Event()
    ran = []
    try:
        running = threading.Event()
        first = jobs.submit(lambda: (running.set(), gate.wait(30))[1])
        assert running.wait(30)
        second = jobs.submit(lambda: ran.append("second"))
        assert not jobs.cancel(first)  # running: it goes on
        assert jobs.cancel(second) and not jobs.cancel(second)
        done = []
        jobs.finished.connect(lambda job_id, result: done.append((job_id, result)))
        third = jobs.submit(lambda: 3)
        gate.set()
        qtbot.waitUntil(lambda: len(done) == 2, timeout=30000)
        assert done == [(first, True), (third, 3)] and ran == []
    finally:
        gate.set()
        assert jobs.stop(2000)


def test_a_result_that_ends_after_stop_is_disposed_not_delivered(qtbot):
    """An opened source that comes back after the window closed is handed to `dispose`."""
    import threading

    disposed, delivered = [], []
    jobs = JobRunner("opener", dispose=disposed.append)
    jobs.finished.connect(lambda job_id, result: delivered.append(result))
    running, gate = threading.Event(), threading.Event()
    try:
        jobs.submit(lambda: (running.set(), gate.wait(30), "an opened source")[2])
        assert running.wait(30)
        assert not jobs.stop(1)  # the job is still running: left to end on its own
        gate.set()
        qtbot.waitUntil(lambda: disposed == ["an opened source"], timeout=30000)
    finally:
        gate.set()
        qtbot.waitUntil(lambda: not jobs.is_running(), timeout=30000)
    assert delivered == []
