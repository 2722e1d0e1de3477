"""Long work that reports progress and can be cancelled, without Qt: the one `Progress` type,
the one cancel exception (`Cancelled`), the flag a job checks, and how a job is run and where it
stands (`run_job`, `JobTicket`).

Core functions that take long (detection of many pairs, calibration, a workbook export) take
`progress=` (a `ProgressCallback`, called as `progress(done, total, text)`) and `cancel=` (a
`Cancel`: a threading.Event, or a callable answering "stop?"); they raise `Cancelled` when asked
to stop.

Every background action is a job, run off the UI thread by the one job system
(`stereo_gui.qt.workers.job_runner.JobRunner`): a function `job(control)`. A long one is a
generator function (`job(control) -> Generator[Progress, None, result]`): it yields Progress
between steps and is stopped at the next yield once cancel is asked for; whatever it returns is
the result. A short one (a click's measurement, a frame's export) returns its result at once and
cannot be stopped once it runs. The `control` argument (a JobControl) is callable and answers
"cancel asked?", so it can be handed down to core functions as their `cancel=`; its `report`
method fits their `progress=`, so progress from inside a long core call reaches the UI too.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Generator
from dataclasses import dataclass
from enum import StrEnum

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.states import Transitions

__all__ = ["JOB_MOVES", "Cancel", "Cancelled", "Job", "JobControl", "JobEnd", "JobState",
           "JobTicket", "Progress", "ProgressCallback", "check_cancel", "is_cancelled",
           "report_progress", "run_job"]


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


def report_progress(progress: ProgressCallback | None, done: int, total: int, text: str) -> None:
    """`progress(done, total, text)`, when there is a `progress`."""
    if progress:
        progress(done, total, text)


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
        self.publish(Progress(int(done), int(total), str(text)))

    def publish(self, progress: Progress) -> None:
        """Send `progress` on (a generator job's yielded steps come this way)."""
        if self._on_progress is not None:
            self._on_progress(progress)

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


# a generator function yielding Progress and returning the result, or a function returning it
Job = Callable[[JobControl], Generator[Progress, None, object] | object]


class JobState(StrEnum):
    """Where a job stands."""

    QUEUED = "queued"  # waiting for its thread
    RUNNING = "running"
    FINISHED = "finished"  # it returned its result
    FAILED = "failed"  # it raised
    CANCELLED = "cancelled"  # stopped at a step, or dropped before it ran


JOB_MOVES: Transitions[JobState] = Transitions("job", {
    JobState.QUEUED: {JobState.RUNNING, JobState.CANCELLED},
    JobState.RUNNING: {JobState.FINISHED, JobState.FAILED, JobState.CANCELLED},
    JobState.FINISHED: set(),
    JobState.FAILED: set(),
    JobState.CANCELLED: set(),
})


class JobTicket:
    """One job handed to the job system: its `id`, its `control` and its state, which any
    thread may read or wait for (closing asks whether an export is written without waiting
    for the queued signals)."""

    def __init__(self, job_id: int, control: JobControl) -> None:
        self.id = job_id
        self.control = control
        self._lock = threading.Lock()
        self._state = JobState.QUEUED
        self._ended = threading.Event()

    @property
    def state(self) -> JobState:
        with self._lock:
            return self._state

    @property
    def ended(self) -> bool:
        """True once FINISHED, FAILED or CANCELLED."""
        return self._ended.is_set()

    def move(self, to: JobState) -> None:
        """Go to state `to` (JOB_MOVES refuses an impossible move: TransitionError)."""
        with self._lock:
            self._state = JOB_MOVES.check(self._state, to)
        if not JOB_MOVES.targets(to):
            self._ended.set()

    def wait(self, timeout_s: float) -> bool:
        """Wait at most `timeout_s` for the job to end; True if it has."""
        return self._ended.wait(max(0.0, timeout_s))


@dataclass(frozen=True)
class JobEnd:
    """How a run ended: FINISHED with `result`, FAILED with `error`, or CANCELLED."""

    state: JobState
    result: object = None
    error: Exception | None = None


def run_job(job: Job, control: JobControl) -> JobEnd:
    """Run `job` in the calling thread to its end: a generator job is stopped at its next step
    once `control` asks (and ends CANCELLED if it was asked during its last one); the core's
    own Cancelled, or an error of ours raised once cancel was asked, is a cancel too. Never
    raises: an error becomes a FAILED end."""
    if control.is_set():
        return JobEnd(JobState.CANCELLED)
    try:
        out = job(control)
        if isinstance(out, Generator):
            out = _drive(out, control)
    except Cancelled:
        return JobEnd(JobState.CANCELLED)
    except Exception as exc:  # noqa: BLE001 - the job system tells the user, it goes on
        if control.is_set() and isinstance(exc, StereoGuiError):
            return JobEnd(JobState.CANCELLED)
        return JobEnd(JobState.FAILED, error=exc)
    return JobEnd(JobState.FINISHED, result=out)


def _drive(gen: Generator[Progress, None, object], control: JobControl) -> object:
    """Run a generator job's steps, its Progress to `control`; its result, or Cancelled."""
    while True:
        if control.is_set():
            gen.close()
            raise Cancelled()
        try:
            step = next(gen)
        except StopIteration as stop:
            result = stop.value
            break
        if isinstance(step, Progress):
            control.publish(step)
    if control.is_set():
        raise Cancelled()
    return result
