"""The job runner: one background QThread for occasional requests (a click's measurement, an
export, a snapshot, opening a source), results delivered by queued signal with the request's
id."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from PySide6.QtCore import QObject, Signal

from stereo_gui.qt.workers.threads import WorkerThread

log = logging.getLogger(__name__)

_JOIN_TIMEOUT_MS = 2000


class JobRunner(QObject):
    """One background thread for occasional jobs; `finished(id, result)` / `failed(id, message)`.

    Jobs run in order; `submit` returns the job's id so a caller can drop a stale answer. The
    thread is a `threads.WorkerThread`: a job that cannot be interrupted (opening a device) and
    outlives `stop()` is left to end on its own; it is never deleted while it runs. `dispose`,
    if given, is called in the job's thread with a result that ends after `stop()` and so is
    never delivered (an opened source to close).
    """

    finished = Signal(int, object)
    failed = Signal(int, str)

    def __init__(self, name: str = "jobs", parent: QObject | None = None,
                 dispose: Callable[[object], None] | None = None) -> None:
        super().__init__(parent)
        self._dispose = dispose
        self._cond = threading.Condition()
        self._jobs: list[tuple[int, Callable[[], object]]] = []
        self._next_id = 1
        self._stopping = False
        self._busy = False
        self._name = name
        self._thread: WorkerThread | None = None

    def submit(self, fn: Callable[[], object]) -> int:
        with self._cond:
            job_id = self._next_id
            self._next_id += 1
            self._jobs.append((job_id, fn))
            self._cond.notify_all()
            start = self._thread is None or not self._thread.isRunning()
            if start:
                self._stopping = False
                self._thread = WorkerThread(self._loop, self._name, self._request_stop,
                                            low_priority=False)
            thread = self._thread
        if start:
            thread.start()
        return job_id

    def _request_stop(self) -> None:
        with self._cond:
            self._stopping = True
            self._jobs.clear()
            self._cond.notify_all()

    def cancel(self, job_id: int) -> bool:
        """Drop job `job_id` if it has not started yet; True if it was dropped (it then never
        runs and neither signal comes for it)."""
        with self._cond:
            kept = [j for j in self._jobs if j[0] != job_id]
            dropped = len(kept) != len(self._jobs)
            self._jobs = kept
            return dropped

    def is_running(self) -> bool:
        return self._thread is not None and self._thread.isRunning()

    def worker_thread(self) -> WorkerThread | None:
        """The QThread the jobs run in (None before the first job)."""
        return self._thread

    def is_busy(self) -> bool:
        """True while a job is queued or running."""
        with self._cond:
            return self._busy or bool(self._jobs)

    def stop(self, timeout_ms: int = _JOIN_TIMEOUT_MS) -> bool:
        """Drop queued jobs, let the running one finish, join the thread; False if it did not."""
        with self._cond:
            self._stopping = True
            self._jobs.clear()
            self._cond.notify_all()
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

    def _emit(self, signal, *args) -> None:
        try:
            signal.emit(*args)
        except RuntimeError:  # the receiver side was deleted while the job ran (at exit)
            log.debug("%s: result dropped, object deleted", self._name)

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._stopping and not self._jobs:
                    self._cond.wait()
                if self._stopping:
                    return
                job_id, fn = self._jobs.pop(0)
                self._busy = True
            try:
                result = fn()
            except Exception as exc:  # noqa: BLE001 - reported to the caller by signal
                log.debug("job %d failed", job_id, exc_info=True)
                with self._cond:
                    self._busy = False
                    stopping = self._stopping
                if not stopping:
                    self._emit(self.failed, job_id, str(exc) or type(exc).__name__)
                continue
            with self._cond:
                self._busy = False
                stopping = self._stopping
            if not stopping:
                self._emit(self.finished, job_id, result)
            elif self._dispose is not None:
                try:
                    self._dispose(result)
                except Exception:  # noqa: BLE001 - releasing must not end the thread unlogged
                    log.warning("%s: releasing an undelivered result failed", self._name,
                                exc_info=True)
