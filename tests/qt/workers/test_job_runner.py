"""The job runner: results, progress, failures and cancels come back by signal with the job's
id; each job's ticket says where it stands."""

from __future__ import annotations

import threading

from stereo_gui.core.jobs import JobState, Progress
from stereo_gui.qt.workers.job_runner import JobRunner


def test_job_runner_delivers_results_with_ids(qtbot):
    jobs = JobRunner()
    try:
        with qtbot.waitSignal(jobs.finished, timeout=30000) as sig:
            job_id = jobs.submit(lambda _control: 6 * 7).id
        assert sig.args == [job_id, 42]
        with qtbot.waitSignal(jobs.failed, timeout=30000) as sig:
            bad_id = jobs.submit(lambda _control: 1 / 0).id
        assert sig.args[0] == bad_id and "division" in sig.args[1]
    finally:
        assert jobs.stop(2000)


def test_a_queued_job_can_be_cancelled_a_running_one_not(qtbot):
    jobs = JobRunner()
    gate = threading.Event()
    ran = []
    try:
        running = threading.Event()
        first = jobs.submit(lambda _control: (running.set(), gate.wait(30))[1]).id
        assert running.wait(30)
        second = jobs.submit(lambda _control: ran.append("second")).id
        assert not jobs.cancel(first)  # running: it goes on
        assert jobs.cancel(second) and not jobs.cancel(second)
        done = []
        jobs.finished.connect(lambda job_id, result: done.append((job_id, result)))
        third = jobs.submit(lambda _control: 3).id
        gate.set()
        qtbot.waitUntil(lambda: len(done) == 2, timeout=30000)
        assert done == [(first, True), (third, 3)] and ran == []
    finally:
        gate.set()
        assert jobs.stop(2000)


def test_a_result_that_ends_after_stop_is_disposed_not_delivered(qtbot):
    """An opened source that comes back after the window closed is handed to `dispose`."""
    disposed, delivered = [], []
    jobs = JobRunner("opener", dispose=disposed.append)
    jobs.finished.connect(lambda job_id, result: delivered.append(result))
    running, gate = threading.Event(), threading.Event()
    try:
        jobs.submit(lambda _control: (running.set(), gate.wait(30), "an opened source")[2])
        assert running.wait(30)
        assert not jobs.stop(1)  # the job is still running: left to end on its own
        gate.set()
        qtbot.waitUntil(lambda: disposed == ["an opened source"], timeout=30000)
    finally:
        gate.set()
        qtbot.waitUntil(lambda: not jobs.is_running(), timeout=30000)
    assert delivered == []


def test_a_long_job_reports_progress_and_stops_at_its_next_step_when_cancelled(qtbot):
    jobs = JobRunner()
    gate, steps, seen = threading.Event(), [], []
    jobs.progress.connect(lambda job_id, p: seen.append((job_id, p.done)))
    delivered = []
    jobs.finished.connect(lambda job_id, result: delivered.append(result))

    def long_job(control):
        for i in range(1000):
            steps.append(i)
            yield Progress(i, 1000)
            gate.wait(30)  # each step waits for the test
        return "all of it"

    try:
        ticket = jobs.submit(long_job)
        qtbot.waitUntil(lambda: seen == [(ticket.id, 0)], timeout=30000)
        assert ticket.state is JobState.RUNNING and jobs.is_busy()
        assert not jobs.cancel(ticket.id)  # running: asked to stop at its next step
        with qtbot.waitSignal(jobs.cancelled, timeout=30000) as sig:
            gate.set()
        assert sig.args == [ticket.id] and ticket.state is JobState.CANCELLED
        # the step under way when cancel came ends; no other begins
        assert steps == [0, 1] and delivered == [] and not jobs.is_busy()
    finally:
        gate.set()
        assert jobs.stop(2000)


def test_a_dropped_job_ends_cancelled_and_says_so_later(qtbot):
    jobs = JobRunner()
    gate, running = threading.Event(), threading.Event()
    try:
        busy = jobs.submit(lambda _control: (running.set(), gate.wait(30)))
        assert running.wait(30)
        queued = jobs.submit(lambda _control: "never")
        cancelled = []
        jobs.cancelled.connect(cancelled.append)
        assert queued.state is JobState.QUEUED
        assert jobs.cancel(queued.id) and queued.state is JobState.CANCELLED and queued.ended
        assert cancelled == []  # queued like every other signal, not from inside cancel()
        qtbot.waitUntil(lambda: cancelled == [queued.id], timeout=30000)
        gate.set()
        assert busy.wait(30) and busy.state is JobState.FINISHED
    finally:
        gate.set()
        assert jobs.stop(2000)
