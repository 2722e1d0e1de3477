"""The job system: every background action (a click's measurement, an export, a snapshot,
opening a source, a calibration) is a `stereo_gui.core.jobs` job run by a JobRunner, a QThread
that runs the jobs handed to it in order. Each job has a `JobTicket` (its id, its cancel flag,
where it stands); results come back by queued signal with the job's id, so a caller can drop a
stale answer.

A runner is long-lived (the context's runner for clicks and exports, the source opener) or
ends its thread once its queue is empty (`ends_when_idle`: a `job_worker.JobWorker`, one long
job with signals of its own).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from PySide6.QtCore import QObject, Qt, Signal, SignalInstance

from stereo_gui.core.jobs import Job, JobControl, JobEnd, JobState, JobTicket, Progress, run_job
from stereo_gui.qt.workers.threads import WorkerThread

log = logging.getLogger(__name__)

_JOIN_TIMEOUT_MS = 2000


def plain_message(exc: Exception) -> str:
    """A failed job's message: the error's own text (for a short job of a click or a menu)."""
    log.debug("a job failed", exc_info=exc)
    return str(exc) or type(exc).__name__


class JobRunner(QObject):
    """One background thread for jobs, run in order; see the module docstring.

    Signals (in the UI thread): `progress(id, Progress)`, then one of `finished(id, result)`,
    `failed(id, message)` (the message from `explain(error)`) or `cancelled(id)`. The thread is a
    `threads.WorkerThread`: a job that cannot be interrupted (opening a device) and outlives
    `stop()` is left to end on its own; it is never deleted while it runs. `dispose`, if
    given, is called in the job's thread with a result that ends after `stop()` and so is
    never delivered (an opened source to close).
    """

    progress = Signal(int, Progress)  # job id, its progress
    finished = Signal(int, object)  # job id, its result (object: whatever the job returns)
    failed = Signal(int, str)  # job id, a message for a person
    cancelled = Signal(int)  # job id
    _dropped = Signal(int)  # cancel() of a queued job -> cancelled, queued like the others

    def __init__(self, name: str = "jobs", parent: QObject | None = None,
                 dispose: Callable[[object], None] | None = None,
                 explain: Callable[[Exception], str] = plain_message,
                 ends_when_idle: bool = False) -> None:
        super().__init__(parent)
        self._dispose = dispose
        self._explain = explain
        self._ends_when_idle = ends_when_idle
        self._cond = threading.Condition()
        self._jobs: list[tuple[JobTicket, Job]] = []
        self._running: JobTicket | None = None
        self._next_id = 1
        self._stopping = False
        self._idle_end = False  # the thread saw its queue empty and is ending (ends_when_idle)
        self._name = name
        self._thread: WorkerThread | None = None
        self._dropped.connect(self.cancelled, Qt.ConnectionType.QueuedConnection)

    def submit(self, job: Job) -> JobTicket:
        """Queue `job` (see core.jobs: `job(control)`); its ticket, whose `id` the signals
        carry."""
        with self._cond:
            job_id = self._next_id
            self._next_id += 1

            def report(p: Progress, job_id: int = job_id) -> None:
                self.progress.emit(job_id, p)

            ticket = JobTicket(job_id, JobControl(report))
            self._jobs.append((ticket, job))
            self._cond.notify_all()
            new: WorkerThread | None = None
            if self._thread is None or not self._thread.isRunning() or self._idle_end:
                self._stopping = self._idle_end = False
                self._thread = new = WorkerThread(self._loop, self._name, self._request_stop,
                                                  low_priority=False)
        if new is not None:
            new.start()
        return ticket

    def _request_stop(self) -> None:
        """Drop the queued jobs, ask the running one to stop at its next step, end the thread;
        nothing is delivered from now on."""
        with self._cond:
            self._stopping = True
            for ticket, _job in self._jobs:
                ticket.move(JobState.CANCELLED)
            self._jobs.clear()
            if self._running is not None:
                self._running.control.set()
            self._cond.notify_all()

    def cancel(self, job_id: int) -> bool:
        """Cancel job `job_id`: one not started yet is dropped (True; it never runs, and only
        `cancelled` comes for it); a running one is asked to stop at its next step (False: a
        job of one step, or one that ignores it, runs to its end and is delivered)."""
        with self._cond:
            queued = next((t for t, _job in self._jobs if t.id == job_id), None)
            if queued is None:
                if self._running is not None and self._running.id == job_id:
                    self._running.control.set()
                return False
            self._jobs = [(t, j) for t, j in self._jobs if t is not queued]
            queued.move(JobState.CANCELLED)
        self._dropped.emit(job_id)
        return True

    def is_running(self) -> bool:
        return self._thread is not None and self._thread.isRunning()

    def worker_thread(self) -> WorkerThread | None:
        """The QThread the jobs run in (None before the first job)."""
        return self._thread

    def is_busy(self) -> bool:
        """True while a job is queued or running."""
        with self._cond:
            return self._running is not None or bool(self._jobs)

    def join(self, timeout_ms: int) -> bool:
        """Wait at most `timeout_ms` for the thread to end, without asking it to (for a runner
        that ends when idle); True if it has ended (or never started)."""
        with self._cond:
            thread = self._thread
        return thread is None or thread.join(timeout_ms)

    def stop(self, timeout_ms: int = _JOIN_TIMEOUT_MS) -> bool:
        """Drop queued jobs, ask the running one to stop (a job of one step finishes), join
        the thread; False if it did not end in time."""
        self._request_stop()
        with self._cond:
            thread = self._thread
        if thread is None:
            return True
        if not thread.join(timeout_ms):
            log.warning("%s: a job is still running; it is left to end on its own", self._name)
            return False
        with self._cond:
            if self._thread is thread:
                self._thread = None
        return True

    def _emit(self, signal: SignalInstance, *args: object) -> None:
        try:
            signal.emit(*args)
        except RuntimeError:  # the receiver side was deleted while the job ran (at exit)
            log.debug("%s: result dropped, object deleted", self._name)

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._stopping and not self._jobs and not self._ends_when_idle:
                    self._cond.wait()
                if self._stopping or not self._jobs:
                    self._idle_end = True
                    return
                ticket, job = self._jobs.pop(0)
                ticket.move(JobState.RUNNING)
                self._running = ticket
            end = run_job(job, ticket.control)
            with self._cond:
                ticket.move(end.state)
                self._running = None
                stopping = self._stopping
            if not stopping:
                self._deliver(ticket.id, end)
            elif end.state is JobState.FINISHED and self._dispose is not None:
                try:
                    self._dispose(end.result)
                except Exception:  # noqa: BLE001 - releasing must not end the thread unlogged
                    log.warning("%s: releasing an undelivered result failed", self._name,
                                exc_info=True)

    def _deliver(self, job_id: int, end: JobEnd) -> None:
        if end.state is JobState.FINISHED:
            self._emit(self.finished, job_id, end.result)
        elif end.state is JobState.FAILED:
            assert end.error is not None  # (run_job's FAILED end carries its error)
            self._emit(self.failed, job_id, self._explain(end.error))
        else:
            self._emit(self.cancelled, job_id)
