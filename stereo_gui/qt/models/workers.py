"""The worker registry: the long-lived workers, and every other one a tab starts, stopped
together when the application closes."""

from __future__ import annotations

import logging
import time
from typing import Protocol

from PySide6.QtCore import QObject

from stereo_gui.qt.workers.frame_worker import FrameWorker
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.recorder import Recorder

log = logging.getLogger(__name__)


class StoppableWorker(Protocol):
    """A worker the registry can stop: asked to end within `timeout_ms`, True when it did."""

    def stop(self, timeout_ms: int = ...) -> bool: ...


class WorkerRegistry(QObject):
    """The frame worker (`frames`), the job thread for occasional work (`jobs`), the recorder of
    raw frames (`recorder`), and the workers tabs register; `shutdown` stops them all."""

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.frames = FrameWorker(self)
        self.jobs = JobRunner("measure-jobs", self)
        self.recorder = Recorder(self.frames, self)
        self._extra: list[StoppableWorker] = []

    def register(self, worker: StoppableWorker) -> None:
        """Have `shutdown()` stop `worker` too."""
        if worker not in self._extra:
            self._extra.append(worker)

    def unregister(self, worker: StoppableWorker) -> None:
        if worker in self._extra:
            self._extra.remove(worker)

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Stop and join every worker within `timeout_ms` in total; True if all ended.

        Every worker is asked to stop, each waiting only for what is left of the time: a
        blocked one never makes closing take longer than `timeout_ms` (it is left to end on
        its own; see workers/threads.py).
        """
        ok = True
        deadline = time.monotonic() + timeout_ms / 1000.0
        workers: list[StoppableWorker] = [self.recorder, self.frames, self.jobs, *self._extra]
        for w in workers:
            left_ms = max(1, int((deadline - time.monotonic()) * 1000))
            try:
                ok = bool(w.stop(timeout_ms=left_ms)) and ok
            except Exception:  # one broken worker must not keep the others running
                log.warning("stopping %r failed", w, exc_info=True)
                ok = False
        return ok
