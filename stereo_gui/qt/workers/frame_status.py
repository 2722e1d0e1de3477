"""The frame worker's shared state, each piece with a lock of its own (`frame_worker`'s module
doc says who shares what): the stream's state machine (`StreamState`, its transitions in one
table), the status snapshot the UI reads (`WorkerStatus`), the rate meters and the watchdog's
read clock. No Qt here; used by `frame_worker` only, which re-exports the public names."""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from enum import StrEnum

from stereo_gui.core.states import Transitions
from stereo_gui.core.timing import SkewMeter, SkewStats
from stereo_gui.sources.base import FrameSource, StereoFrame

log = logging.getLogger(__name__)

_FPS_SMOOTHING = 0.1  # weight of the newest interval in the running frame-rate estimate
RATE_STALE_S = 2.0  # no event for this long (or 3 intervals, if longer): the rate is 0


class StreamState(StrEnum):
    """How the frames of the source in use come."""

    OK = "ok"  # frames arrive (again, after a problem)
    RECONNECTING = "reconnecting"  # the source opens a vanished camera again
    STALLED = "stalled"  # a read has not returned for frame_worker.READ_STALL_S
    FAILED = "failed"  # the source stopped and was dropped


# The stream's state machine, all of it: the states each state may move to while it is about the
# same source. A FAILED source was dropped and closed: nothing more is heard of it. The same
# state again about the same source is no news (not a move). A state about another source (the
# source was replaced, or the first news) may be any: it starts afresh.
STREAM_MOVES: Transitions[StreamState] = Transitions("stream", {
    StreamState.OK: {StreamState.RECONNECTING, StreamState.STALLED, StreamState.FAILED},
    StreamState.RECONNECTING: {StreamState.OK, StreamState.STALLED, StreamState.FAILED},
    StreamState.STALLED: {StreamState.OK, StreamState.RECONNECTING, StreamState.FAILED},
    StreamState.FAILED: set(),
})


@dataclass(frozen=True)
class StreamStatus:
    """A change of the stream's state: `message` is what the user was told ("" or "frames
    again" for OK), `source_name` the name of the source it is about."""

    state: StreamState
    message: str
    source_name: str


@dataclass(frozen=True)
class WorkerStatus:
    """What the worker is doing, read at one moment (`FrameWorker.status()`).

    Rates are frames per second (0 when idle); `pending_frames` is 0 or 1 (a slot, never a
    queue); `skipped_frames` counts the frames the source could not decode.
    """

    stream: StreamState
    source_name: str  # "" without a source
    paused: bool
    camera_fps: float
    processing_fps: float
    frames_read: int
    frames_processed: int
    pending_frames: int
    skipped_frames: int
    # CPU seconds the reader thread spent inside the source's reads (rendering the simulated
    # rig, decoding a recording's or a camera's images; a wait for the device is not CPU)
    source_cpu_s: float = 0.0


class RateMeter:
    """A smoothed events-per-second estimate from the intervals between events (not locked:
    `Meters` guards it)."""

    def __init__(self) -> None:
        self._last: float | None = None
        self._interval_s: float | None = None

    def tick(self, now: float) -> None:
        if self._last is not None:
            dt = max(now - self._last, 1e-6)
            self._interval_s = dt if self._interval_s is None else (
                (1 - _FPS_SMOOTHING) * self._interval_s + _FPS_SMOOTHING * dt)
        self._last = now

    def reset(self) -> None:
        self._last = None
        self._interval_s = None

    @property
    def fps(self) -> float:
        """The smoothed rate, never more than the time since the last event allows, and 0
        once nothing came for RATE_STALE_S (a stuck read must not keep showing 29.4 fps)."""
        if not self._interval_s or self._last is None:
            return 0.0
        waited = time.monotonic() - self._last
        if waited > max(RATE_STALE_S, 3.0 * self._interval_s):
            return 0.0
        return 1.0 / max(self._interval_s, waited)


class Meters:
    """Frame rates, counts and the cameras' skew; its lock is a leaf (taken inside others)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._camera = RateMeter()
        self._processing = RateMeter()
        self._skew = SkewMeter()
        self.frames_read = 0
        self.frames_processed = 0
        self.source_cpu_s = 0.0

    def reset(self, skew: bool = True) -> None:
        with self._lock:
            self._camera.reset()
            self._processing.reset()
            if skew:
                self._skew.reset()

    def read(self, frame: StereoFrame) -> None:
        with self._lock:
            self.frames_read += 1
            self._camera.tick(time.monotonic())
            self._skew.add(frame.t_left, frame.t_right)

    def read_cpu(self, seconds: float) -> None:
        """Count the reader thread's CPU time of one read."""
        with self._lock:
            self.source_cpu_s += max(0.0, seconds)

    def processed(self) -> tuple[float, float]:
        """Count a result kept; (camera, processing) frames per second now."""
        with self._lock:
            self.frames_processed += 1
            self._processing.tick(time.monotonic())
            return self._camera.fps, self._processing.fps

    def rates(self) -> tuple[float, float, int, int]:
        """(camera fps, processing fps, frames read, frames processed)."""
        with self._lock:
            return (self._camera.fps, self._processing.fps, self.frames_read,
                    self.frames_processed)

    def source_cpu(self) -> float:
        """The reader thread's CPU seconds inside the source's reads, all told."""
        with self._lock:
            return self.source_cpu_s

    def skew(self) -> SkewStats:
        with self._lock:
            return self._skew.stats()


class ReadClock:
    """When the reader's read under way began (one per reader: a reader left behind keeps its
    own, so it can never reset the new reader's)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._started: float | None = None

    def start(self) -> None:
        with self._lock:
            self._started = time.monotonic()

    def stop(self) -> None:
        with self._lock:
            self._started = None

    def blocked_for(self) -> float:
        """Seconds the read under way has taken so far (0 when none is)."""
        with self._lock:
            t0 = self._started
        return 0.0 if t0 is None else time.monotonic() - t0


class StreamMachine:
    """The stream's state machine (see STREAM_MOVES), and the error said last (an error is said
    once, not once a frame).

    News comes from two threads (the reader, and the watchdog in the UI thread): news the table
    refuses is stale (the watchdog saw a read of a source blocked that has failed since) and
    is dropped, never announced."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._state = StreamState.OK
        self._about: FrameSource | None = None  # the source the state is about
        self._said = ""

    @property
    def state(self) -> StreamState:
        with self._lock:
            return self._state

    def _move(self, state: StreamState, source: FrameSource | None) -> bool:
        """(With the lock held) take the move to `state` about `source`; False if it is no news
        or refused."""
        if source is not self._about:  # about another source: any state may follow
            self._state, self._about = state, source
            return True
        if state is self._state:
            return False
        if not STREAM_MOVES.allows(self._state, state):
            log.debug("stream: %s of %s dropped (it is %s)", state.name,
                      source.name if source is not None else "no source", self._state.name)
            return False
        self._state = state
        return True

    def enter(self, state: StreamState, message: str, source: FrameSource | None
              ) -> StreamStatus | None:
        """Move to a problem `state` about `source`: the status to announce, None if no news."""
        with self._lock:
            if not self._move(state, source):
                return None
        return StreamStatus(state, message, source.name if source is not None else "")

    def frames_again(self, source: FrameSource) -> StreamStatus | None:
        """A frame of `source` arrived: the status to announce if a problem is over."""
        with self._lock:
            if self._state is StreamState.OK:
                self._about = source
                return None
            same = source is self._about
            if not self._move(StreamState.OK, source):
                return None
            self._said = ""  # the same problem again is said again
        return StreamStatus(StreamState.OK, f"{source.name}: frames again" if same else "",
                            source.name)

    def say(self, text: str) -> bool:
        """True if `text` is news (not the error said last)."""
        with self._lock:
            if text == self._said:
                return False
            self._said = text
            return True

    def forget_said(self) -> None:
        with self._lock:
            self._said = ""
