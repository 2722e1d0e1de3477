"""How far apart in time the two cameras take their pictures (the skew of each stereo frame,
right time minus left time, and its statistics over the last second); how fast and how late
frames reach the screen (`ShownMeter`); and how much of the machine the process uses
(`CpuMeter`).

Two USB webcams are not synchronised: each exposes when its own clock says. While the scene
stands still that does not matter; when the board or the robot moves, the two images show
different moments and a match between them is wrong. A skew under a third of a frame interval
is what two free-running cameras read as one pair (grabbed together) can hold; more means the
frames are paired across frame boundaries.
"""

from __future__ import annotations

import math
import os
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

WINDOW_S = 1.0  # the statistics shown cover the frames of the last second
SKEW_LIMIT_OF_INTERVAL = 1.0 / 3.0  # a skew above this share of a frame interval is warned about


@dataclass(frozen=True)
class SkewStats:
    """The skew of the frames of the last second: `median_ms` (signed: positive when the right
    camera's picture is later), `worst_ms` (the largest in size, signed), `frames` counted,
    and `interval_ms` the median time between frames (None with fewer than two)."""

    median_ms: float
    worst_ms: float
    frames: int
    interval_ms: float | None

    @property
    def limit_ms(self) -> float | None:
        """The skew above which it is warned about: a third of a frame interval."""
        return None if self.interval_ms is None else self.interval_ms * SKEW_LIMIT_OF_INTERVAL

    @property
    def too_large(self) -> bool:
        """Whether the typical skew (the median's size) exceeds a third of a frame interval."""
        limit = self.limit_ms
        return limit is not None and abs(self.median_ms) > limit

    def text(self) -> str:
        """'Skew 20.0 ms median, 21.3 ms worst (right after left) over the last second
        (30 frames); a third of a frame is 11.1 ms'."""
        if self.frames == 0:
            return "Skew: no frames"
        order = ("right after left" if self.median_ms > 0 else "left after right"
                 if self.median_ms < 0 else "together")
        out = (f"Skew {abs(self.median_ms):.1f} ms median, {abs(self.worst_ms):.1f} ms worst "
               f"({order}) over the last second ({self.frames} frames)")
        if self.limit_ms is not None:
            out += f"; a third of a frame is {self.limit_ms:.1f} ms"
        return out


def skew_stats(t_left: ArrayLike, t_right: ArrayLike) -> SkewStats:
    """SkewStats of frames with capture times `t_left`, `t_right` (s, in order)."""
    tl = np.asarray(t_left, np.float64).reshape(-1)
    tr = np.asarray(t_right, np.float64).reshape(-1)
    ok = np.isfinite(tl) & np.isfinite(tr)
    tl, tr = tl[ok], tr[ok]
    if tl.size == 0:
        return SkewStats(0.0, 0.0, 0, None)
    skew = (tr - tl) * 1000.0
    worst = float(skew[np.argmax(np.abs(skew))])
    steps = np.diff(tl)
    steps = steps[steps > 0]
    interval = float(np.median(steps)) * 1000.0 if steps.size else None
    return SkewStats(float(np.median(skew)), worst, int(tl.size), interval)


class SkewMeter:
    """The skew of the frames of the last `window_s` seconds (by the left camera's clock), fed
    one frame at a time. Not thread-safe: its owner guards it."""

    def __init__(self, window_s: float = WINDOW_S) -> None:
        self.window_s = float(window_s)
        self._times: deque[tuple[float, float]] = deque()

    def add(self, t_left: float, t_right: float) -> None:
        t_left, t_right = float(t_left), float(t_right)
        if not (math.isfinite(t_left) and math.isfinite(t_right)):
            return
        if self._times and t_left < self._times[-1][0]:
            self._times.clear()  # a clock that went back: another source, a recording looped
        if self._times and (t_left, t_right) == self._times[-1]:
            return  # the same frame again (a paused playback shows its frame over and over)
        self._times.append((t_left, t_right))
        while self._times and self._times[0][0] < t_left - self.window_s:
            self._times.popleft()

    def reset(self) -> None:
        self._times.clear()

    def stats(self) -> SkewStats:
        if not self._times:
            return SkewStats(0.0, 0.0, 0, None)
        tl, tr = zip(*self._times, strict=True)
        return skew_stats(tl, tr)


# ---- frames shown and their latency ----------------------------------------------------------
SHOWN_WINDOW_S = 2.0  # the shown rate and the latency cover the frames drawn in this long
SHOWN_STALE_S = 1.0  # nothing drawn for this long (or 3 intervals, if longer): no rate


@dataclass(frozen=True)
class LatencyStats:
    """Latencies in milliseconds: their `median_ms`, 95th percentile `p95_ms` and how many
    (`count`); NaN medians when there are none."""

    median_ms: float
    p95_ms: float
    count: int


def latency_stats(latencies_ms: ArrayLike) -> LatencyStats:
    """LatencyStats of `latencies_ms` (the non-finite ones left out)."""
    v = np.asarray(latencies_ms, np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return LatencyStats(math.nan, math.nan, 0)
    return LatencyStats(float(np.median(v)), float(np.percentile(v, 95.0)), int(v.size))


@dataclass(frozen=True)
class ShownStats:
    """The frames drawn over the last `window_s` seconds: `fps` the rate they were drawn at (0
    when nothing was drawn for a while: then `frames` is 0 too), `frames` counted, and the
    latency from the source's delivery of each frame to its drawing (`latency`, ms)."""

    fps: float
    frames: int
    latency: LatencyStats
    window_s: float

    @property
    def showing(self) -> bool:
        """Whether frames are being drawn (a rate can be given)."""
        return self.frames > 0 and self.fps > 0

    def latency_intervals(self, camera_fps: float) -> float:
        """The median latency in frame intervals of a camera at `camera_fps` (NaN unknown)."""
        return intervals(self.latency.median_ms, camera_fps)


def intervals(ms: float, fps: float) -> float:
    """`ms` milliseconds in frame intervals at `fps` frames per second (NaN when unknown)."""
    if not (math.isfinite(ms) and math.isfinite(fps) and fps > 0):
        return math.nan
    return ms * fps / 1000.0


class ShownMeter:
    """Frames drawn (`add(shown_at, read_at)`, both seconds of one clock, `time.monotonic()`)
    and their statistics over the last `window_s` seconds (`stats(now)`). Times are passed in,
    so that the arithmetic is tested without a clock. Not thread-safe: its owner guards it."""

    def __init__(self, window_s: float = SHOWN_WINDOW_S, stale_s: float = SHOWN_STALE_S) -> None:
        self.window_s = float(window_s)
        self.stale_s = float(stale_s)
        self._shown: deque[tuple[float, float]] = deque()  # (shown_at, latency s or NaN)

    def add(self, shown_at: float, read_at: float | None = None) -> None:
        """A frame drawn at `shown_at`, read from its source at `read_at` (None: unknown)."""
        shown_at = float(shown_at)
        if not math.isfinite(shown_at):
            return
        if self._shown and shown_at < self._shown[-1][0]:
            self._shown.clear()  # a clock that went back: start again
        latency = math.nan
        if read_at is not None and math.isfinite(read_at) and read_at <= shown_at:
            latency = shown_at - float(read_at)
        self._shown.append((shown_at, latency))
        self._forget_before(shown_at - self.window_s)

    def reset(self) -> None:
        self._shown.clear()

    def _forget_before(self, t: float) -> None:
        while self._shown and self._shown[0][0] < t:
            self._shown.popleft()

    def stats(self, now: float | None = None) -> ShownStats:
        """The statistics at `now` (default `time.monotonic()`): the rate from the intervals
        between the frames of the window, never more than the time since the last frame allows
        (a view that stopped must not keep showing 30 fps), nothing once it stopped for
        `stale_s` or three intervals."""
        now = time.monotonic() if now is None else float(now)
        self._forget_before(now - self.window_s)
        empty = ShownStats(0.0, 0, LatencyStats(math.nan, math.nan, 0), self.window_s)
        if not self._shown:
            return empty
        first, last = self._shown[0][0], self._shown[-1][0]
        n = len(self._shown)
        interval = (last - first) / (n - 1) if n > 1 else math.inf
        waited = max(0.0, now - last)
        if waited > max(self.stale_s, 3.0 * interval if n > 1 else 0.0):
            return empty
        fps = 0.0 if n < 2 or interval <= 0 else 1.0 / max(interval, waited)
        latency = latency_stats([1000.0 * lat for _, lat in self._shown])
        return ShownStats(fps, n, latency, self.window_s)


# ---- the process's CPU -----------------------------------------------------------------------
CPU_WINDOW_S = 2.0  # the CPU share shown covers about this long


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the system tells it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # (no sched_getaffinity on macOS and Windows)
        return max(1, os.cpu_count() or 1)


def cpu_percent(cpu_s: float, wall_s: float, cores: int) -> float:
    """CPU time `cpu_s` used over `wall_s` of wall time as a percent of `cores` cores (100: all
    of them busy all the time); NaN without wall time."""
    if not (wall_s > 0 and cores > 0 and math.isfinite(cpu_s)):
        return math.nan
    return 100.0 * cpu_s / wall_s / cores


class CpuMeter:
    """The process's CPU time (`time.process_time()`: every thread) over wall time, as a percent
    of the cores it may use, over about the last `window_s` seconds. `sample(now, cpu)` takes
    the two clocks' readings (by default read here) and returns the share since the oldest
    sample kept. Not thread-safe: its owner guards it."""

    def __init__(self, cores: int | None = None, window_s: float = CPU_WINDOW_S) -> None:
        self.cores = usable_cores() if cores is None else max(1, int(cores))
        self.window_s = float(window_s)
        self._samples: deque[tuple[float, float]] = deque()  # (wall s, CPU s)

    def sample(self, now: float | None = None, cpu: float | None = None) -> float:
        """Add a reading (wall time `now`, process CPU time `cpu`, seconds); the CPU share since
        the oldest reading of the window, percent (NaN with no reading before this one)."""
        now = time.monotonic() if now is None else float(now)
        cpu = time.process_time() if cpu is None else float(cpu)
        if self._samples and (now < self._samples[-1][0] or cpu < self._samples[-1][1]):
            self._samples.clear()  # a clock that went back: start again
        self._samples.append((now, cpu))
        # keep one reading at least window_s old, so that the share covers the whole window
        while len(self._samples) > 2 and self._samples[1][0] <= now - self.window_s:
            self._samples.popleft()
        if len(self._samples) < 2:
            return math.nan
        t0, c0 = self._samples[0]
        return cpu_percent(cpu - c0, now - t0, self.cores)

    def reset(self) -> None:
        self._samples.clear()
