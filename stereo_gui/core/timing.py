"""How far apart in time the two cameras take their pictures: the skew of each stereo frame
(right time minus left time) and its statistics over the last second.

Two USB webcams are not synchronised: each exposes when its own clock says. While the scene
stands still that does not matter; when the board or the robot moves, the two images show
different moments and a match between them is wrong. A skew under a third of a frame interval
is what two free-running cameras read as one pair (grabbed together) can hold; more means the
frames are paired across frame boundaries.
"""

from __future__ import annotations

import math
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
