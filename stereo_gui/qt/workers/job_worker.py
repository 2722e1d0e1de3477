"""One long job (a calibration, a workbook export, reading a session) in a thread of its own,
with signals of its own: a `job_runner.JobRunner` that ends its thread once the job is over.

A job is a `stereo_gui.core.jobs` job, usually a generator function that yields Progress between
steps (see there); the worker stops it at the next yield once cancel is asked for.

Signals reach the UI thread queued: progress(Progress), finished_ok(result), failed(str) for an
exception (already phrased for a person), cancelled(). Exactly one of finished_ok / failed /
cancelled is emitted per run, then done().
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.jobs import Job, JobState, JobTicket, Progress
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.threads import WorkerThread

__all__ = ["JobWorker"]

log = logging.getLogger(__name__)


def named_message(name: str) -> Callable[[Exception], str]:
    """A long job's failure for a person: our own errors say what went wrong; anything else
    (a bug, an OpenCV error) is logged with its traceback and named."""

    def explain(exc: Exception) -> str:
        if isinstance(exc, StereoGuiError):
            return str(exc)
        log.error("%s failed", name, exc_info=exc)
        return f"{name} failed: {type(exc).__name__}: {exc}"

    return explain


class JobWorker(QObject):
    """Runs one job in its own thread; see the module docstring for the signals.

    One OpenCV call of a job cannot be interrupted, so `stop()` waits at most its timeout and a
    job still running then is left to end on its own; its thread is never deleted while it runs.
    """

    progress = Signal(Progress)
    finished_ok = Signal(object)  # the job's result (object: whatever the job returns)
    failed = Signal(str)  # a message for a person
    cancelled = Signal()
    done = Signal()  # after any of the three above

    def __init__(self, job: Job, name: str = "job", parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._job = job
        self.job_name = name
        self.setObjectName(f"JobWorker-{name}")
        self._runner = JobRunner(f"job-{name}", self, explain=named_message(name),
                                 ends_when_idle=True)
        self._runner.progress.connect(self._progressed)
        self._runner.finished.connect(self._finished)
        self._runner.failed.connect(self._failed)
        self._runner.cancelled.connect(self._cancelled)
        self._ticket: JobTicket | None = None

    def start(self) -> None:
        """Run the job in a new thread (once)."""
        if self._ticket is not None:
            raise RuntimeError(f"{self.job_name} was already started")
        self._ticket = self._runner.submit(self._job)

    @property
    def outcome(self) -> JobState | None:
        """How the run ended (FINISHED, FAILED or CANCELLED), readable as soon as it has, before
        the queued signals; None before."""
        ticket = self._ticket
        return ticket.state if ticket is not None and ticket.ended else None

    def worker_thread(self) -> WorkerThread | None:
        """The QThread the job runs in (None before `start`)."""
        return self._runner.worker_thread()

    def isRunning(self) -> bool:  # noqa: N802 - the name QThread used, kept for callers
        return self._runner.is_running()

    def wait(self, timeout_ms: int) -> bool:
        """Join the thread for at most `timeout_ms`; True if it has ended (or never started)."""
        return self._runner.join(timeout_ms)

    def cancel(self) -> None:
        """Ask the job to stop at its next step (returns at once)."""
        if self._ticket is not None:
            self._runner.cancel(self._ticket.id)

    def stop(self, timeout_ms: int = 2000) -> bool:
        """Cancel and wait for the thread to end; True if it ended within the timeout."""
        self.cancel()
        return self.wait(timeout_ms)

    def _progressed(self, _job_id: int, p: Progress) -> None:
        self.progress.emit(p)

    def _finished(self, _job_id: int, result: object) -> None:
        self.finished_ok.emit(result)
        self.done.emit()

    def _failed(self, _job_id: int, message: str) -> None:
        self.failed.emit(message)
        self.done.emit()

    def _cancelled(self, _job_id: int) -> None:
        self.cancelled.emit()
        self.done.emit()
