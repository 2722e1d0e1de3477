"""Long work that reports progress and can be cancelled, without Qt: the one `Progress` type,
the one cancel exception (`Cancelled`) and the flag a job checks.

Core functions that take long (detection of many pairs, calibration, a workbook export) take
`progress=` (a `ProgressCallback`, called as `progress(done, total, text)`) and `cancel=` (a
`Cancel`: a threading.Event, or a callable answering "stop?"); they raise `Cancelled` when asked
to stop.

A job run off the UI thread is a generator function `job(control) -> Generator[Progress, None,
result]`. It yields Progress between steps; the worker running it
(`stereo_gui.qt.workers.job_worker.JobWorker`) stops it at the next yield once cancel is asked
for. The `control` argument (a JobControl) is callable and answers "cancel asked?", so it can be
handed down to core functions as their `cancel=`; its `report` method fits their `progress=`, so
progress from inside a long core call reaches the UI too. Whatever the generator returns is the
result.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Generator
from dataclasses import dataclass

from stereo_gui.core.errors import StereoGuiError

__all__ = ["Cancel", "Cancelled", "Job", "JobControl", "Progress", "ProgressCallback",
           "check_cancel", "is_cancelled"]


@dataclass(frozen=True)
class Progress:
    """How far a job is: `done` of `total` steps, and what it is doing now."""

    done: int
    total: int
    text: str = ""

    @property
    def percent(self) -> int:
        return int(round(100.0 * self.done / self.total)) if self.total > 0 else 0


# progress(done, total, text): what a long core function calls after each step, from the
# calling thread (never from a pool thread)
ProgressCallback = Callable[[int, int, str], None]
# a threading.Event (set = cancel) or a callable returning True to cancel
Cancel = threading.Event | Callable[[], bool] | None


class Cancelled(StereoGuiError):
    """The user cancelled a long job (detection, calibration, an export) before it ended."""

    def __init__(self, message: str = "cancelled") -> None:
        super().__init__(message)


def is_cancelled(cancel: Cancel) -> bool:
    """True when `cancel` (an Event or a callable) asks to stop."""
    if cancel is None:
        return False
    if isinstance(cancel, threading.Event):
        return cancel.is_set()
    return bool(cancel())


def check_cancel(cancel: Cancel) -> None:
    """Raise Cancelled when `cancel` asks to stop."""
    if is_cancelled(cancel):
        raise Cancelled()


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
        """Raise Cancelled if cancel was asked."""
        if self._event.is_set():
            raise Cancelled()


Job = Callable[[JobControl], Generator[Progress, None, object]]
