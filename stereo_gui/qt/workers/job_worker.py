"""Slow jobs off the UI thread: a generator worker that reports progress and cancels cooperatively.

A job is a generator function `job(control) -> Generator[Progress, None, result]`. It yields
Progress between steps; the worker stops it at the next yield once cancel is asked for. The
`control` argument (a JobControl) is callable and answers "cancel asked?", so it can be handed
down to core functions that take `cancel=`; its `report` method fits their `progress=`
callbacks (done, total, text), so progress from inside a long core call reaches the UI too.
Whatever the generator returns is the result. Progress, JobControl and JobCancelled live in
`stereo_gui.pipeline.jobs` (no Qt), so jobs can be written and tested without Qt.

Signals reach the UI thread queued: progress(Progress), finished(result), failed(str) for an
exception (already phrased for a person), cancelled(). Exactly one of finished / failed /
cancelled is emitted per run, then done().
"""

from __future__ import annotations

import logging

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.pipeline.jobs import Job, JobCancelled, JobControl, Progress
from stereo_gui.qt.workers.threads import WorkerThread

__all__ = ["Job", "JobCancelled", "JobControl", "JobWorker", "Progress"]

log = logging.getLogger(__name__)


class JobWorker(QObject):
    """Runs one generator job in its own thread; see the module docstring for the signals.

    The thread is a `threads.WorkerThread` (a QThread): one OpenCV call of a job cannot be
    interrupted, so `stop()` waits at most its timeout and a job still running then is left to
    end on its own; it is never deleted while it runs.
    """

    progress = Signal(object)  # Progress
    finished_ok = Signal(object)  # the job's result
    failed = Signal(str)  # a message for a person
    cancelled = Signal()
    done = Signal()  # after any of the three above

    def __init__(self, job: Job, name: str = "job", parent=None) -> None:
        super().__init__(parent)
        self._job = job
        self._cancel = JobControl(self.progress.emit)
        self.job_name = name
        self.setObjectName(f"JobWorker-{name}")
        self._thread: WorkerThread | None = None
        # how the run ended, set before its signal is emitted (readable once the thread has
        # ended, without the queued signals): "", "finished", "failed" or "cancelled"
        self.outcome = ""

    def start(self) -> None:
        """Run the job in a new thread (once)."""
        if self._thread is not None:
            raise RuntimeError(f"{self.job_name} was already started")
        self._thread = WorkerThread(self.run, f"job-{self.job_name}", self.cancel,
                                    low_priority=False)
        self._thread.start()

    def worker_thread(self) -> WorkerThread | None:
        """The QThread the job runs in (None before `start`)."""
        return self._thread

    def isRunning(self) -> bool:  # noqa: N802 - the name QThread used, kept for callers
        return self._thread is not None and self._thread.isRunning()

    def wait(self, timeout_ms: int) -> bool:
        """Join the thread for at most `timeout_ms`; True if it has ended (or never started)."""
        return self._thread is None or self._thread.join(timeout_ms)

    def cancel(self) -> None:
        """Ask the job to stop at its next step (returns at once)."""
        self._cancel.set()

    @property
    def cancel_requested(self) -> bool:
        return self._cancel.is_set()

    def stop(self, timeout_ms: int = 2000) -> bool:
        """Cancel and wait for the thread to end; True if it ended within the timeout."""
        self.cancel()
        return self.wait(timeout_ms)

    def run(self) -> None:  # runs in the worker thread
        try:
            gen = self._job(self._cancel)
            result = None
            while True:
                if self._cancel.is_set():
                    gen.close()
                    raise JobCancelled()
                try:
                    step = next(gen)
                except StopIteration as stop:
                    result = stop.value
                    break
                if isinstance(step, Progress):
                    self.progress.emit(step)
            if self._cancel.is_set():
                raise JobCancelled()
        except JobCancelled:
            self.outcome = "cancelled"
            self.cancelled.emit()
        except StereoGuiError as exc:
            # the core's own Cancelled (raised by its cancel checks) is a StereoGuiError too
            if self._cancel.is_set():
                self.outcome = "cancelled"
                self.cancelled.emit()
            else:
                self.outcome = "failed"
                self.failed.emit(str(exc))
        except Exception as exc:  # a bug or an OpenCV error: the user still gets a message
            log.exception("%s failed", self.job_name)
            self.outcome = "failed"
            self.failed.emit(f"{self.job_name} failed: {type(exc).__name__}: {exc}")
        else:
            self.outcome = "finished"
            self.finished_ok.emit(result)
        finally:
            self.done.emit()
