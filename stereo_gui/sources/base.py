"""What every frame source yields, and the interface they share."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from stereo_gui.sources.camera_controls import PairControls
    from stereo_gui.sources.playback import PlaybackSource
    from stereo_gui.sources.sim.rig import SimRig


@dataclass(frozen=True, eq=False)
class StereoFrame:
    """One stereo frame: both raw images (BGR uint8, HxWx3) with capture times (seconds).

    `index` counts frames from the source's start; `truth` carries ground truth where the source
    knows it (the simulated rig), else None.
    """

    left: np.ndarray
    right: np.ndarray
    t_left: float
    t_right: float
    index: int
    truth: object | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the left image, px."""
        return (int(self.left.shape[1]), int(self.left.shape[0]))


@runtime_checkable
class FrameSource(Protocol):
    """What a source of stereo frames offers the frame worker and the window.

    Every source has a `name`, a `nominal_fps`, `read()` (blocks until the next frame; raises
    SourceError when it cannot give one, SourceUnavailable while a vanished device is looked for
    again) and `close()` (releases devices; may be called more than once). Sources are used from
    one worker thread at a time.

    The optional capabilities are members too, so that nobody has to probe for them: a source
    states them by deriving from FrameSource (which gives the "has none" answers below) and
    overriding what it has.
    """

    name: str  # what the status bar shows, e.g. "Simulated rig" or "Cameras 0, 1"
    nominal_fps: float  # the rate the source is meant to deliver, frames per second
    skipped_frames: int = 0  # frames it could not decode and left out (0: it does not count)

    def read(self) -> StereoFrame: ...

    def close(self) -> None: ...

    def camera_controls(self) -> PairControls | None:
        """The two cameras' controls (only the thread that reads frames may use them), or None
        for a source without any (or while a camera is missing)."""
        return None

    def playback(self) -> PlaybackSource | None:
        """The playback controls (pause, step, seek, loop) of a recording, or None."""
        return None

    def simulated_rig(self) -> SimRig | None:
        """The simulated rig the frames are rendered by (its true calibration, the board it
        shows, a camera turned on purpose), or None for frames of a real scene."""
        return None


class FramePacer:
    """Spaces reads 1/fps seconds apart like a camera's frame clock, for sources that could
    deliver faster (a file, the simulated rig). After a stall it catches up for at most half a
    second's worth of frames instead of bursting through the whole backlog."""

    MAX_LAG_S = 0.5

    def __init__(self) -> None:
        self._next_t: float | None = None  # when the next frame is due, time.monotonic() s

    def wait(self, fps: float) -> None:
        """Sleep until the next frame is due at `fps` frames per second."""
        now = time.monotonic()
        if self._next_t is None:
            self._next_t = now
        elif now < self._next_t:
            time.sleep(self._next_t - now)
        self._next_t = max(self._next_t + 1.0 / fps, time.monotonic() - self.MAX_LAG_S)
