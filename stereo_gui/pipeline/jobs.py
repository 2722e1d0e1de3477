"""What a slow job off the UI thread is made of, without Qt: its progress reports and the
cancel flag it checks.

A job is a generator function `job(control) -> Generator[Progress, None, result]`. It yields
Progress between steps; the worker running it (`stereo_gui.qt.workers.job_worker.JobWorker`)
stops it at the next yield once cancel is asked for. The `control` argument (a JobControl) is
callable and answers "cancel asked?", so it can be handed down to core functions that take
`cancel=`; its `report` method fits their `progress=` callbacks (done, total, text), so progress
from inside a long core call reaches the UI too. Whatever the generator returns is the result.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Generator
from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """How far a job is: `done` of `total` steps, and what it is doing now."""

    done: int
    total: int
    text: str = ""

    @property
    def percent(self) -> int:
        return int(round(100.0 * self.done / self.total)) if self.total > 0 else 0


class JobCancelled(Exception):
    """Raised inside a job (or by a core function's cancel check) to stop it early."""


class JobControl:
    """Thread-safe cancel flag and progress outlet handed to a job.

    Calling it answers whether cancel was asked (for core functions' `cancel=`); `report(done,
    total, text)` sends progress to the UI (for core functions' `progress=`).
    """

    def __init__(self, on_progress: Callable[[Progress], None] | None = None) -> None:
        self._event = threading.Event()
        self._on_progress = on_progress

    def report(self, done: int, total: int, text: str = "") -> None:
        if self._on_progress is not None:
            self._on_progress(Progress(int(done), int(total), str(text)))

    def set(self) -> None:
        self._event.set()

    def is_set(self) -> bool:
        return self._event.is_set()

    def __call__(self) -> bool:
        return self._event.is_set()

    def check(self) -> None:
        """Raise JobCancelled if cancel was asked."""
        if self._event.is_set():
            raise JobCancelled()


Job = Callable[[JobControl], Generator[Progress, None, object]]
