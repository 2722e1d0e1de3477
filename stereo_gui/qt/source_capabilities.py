"""What some frame sources can do beyond `FrameSource` (read, close, name, nominal_fps), declared
as protocols so that the window and its widgets ask for a capability by type, not by probing
attribute names.

- `SimulatedRigSource`: renders the simulated rig (`rig`: its board, its cameras, its truth);
- `ControllableSource`: offers the two cameras' controls (`camera_controls()`);
- `PlaybackSource`: plays a recording, a folder of pairs or a video (pause, step, seek, loop).

A wrapper has a capability when its class declares it: from Python 3.12 on, isinstance against
these protocols looks attributes up statically, so one forwarded by `__getattr__` is not seen.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

from stereo_gui.sources.base import FrameSource

if TYPE_CHECKING:
    from stereo_gui.sources.camera_controls import PairControls
    from stereo_gui.sources.sim.rig import SimRig


@runtime_checkable
class SimulatedRigSource(Protocol):
    rig: SimRig


@runtime_checkable
class ControllableSource(Protocol):
    def camera_controls(self) -> PairControls | None: ...


@runtime_checkable
class PlaybackSource(Protocol):
    @property
    def frame_count(self) -> int: ...

    @property
    def position(self) -> int: ...

    @property
    def paused(self) -> bool: ...

    @property
    def finished(self) -> bool: ...

    @property
    def loop(self) -> bool: ...

    def time_s(self, i: int) -> float: ...

    def set_speed(self, speed: float) -> None: ...

    def set_loop(self, loop: bool) -> None: ...

    def pause(self) -> None: ...

    def resume(self) -> None: ...

    def step(self, n: int = 1) -> int: ...

    def seek(self, i: int) -> int: ...


def simulated_rig(source: FrameSource | None) -> SimRig | None:
    """The simulated rig `source` renders, or None for any other source."""
    return source.rig if isinstance(source, SimulatedRigSource) else None


def camera_controls_of(source: FrameSource | None) -> PairControls | None:
    """The two cameras' controls of `source`, or None when it has none (or not now)."""
    return source.camera_controls() if isinstance(source, ControllableSource) else None


def playback_of(source: FrameSource | None) -> PlaybackSource | None:
    """`source` when it plays something back, else None."""
    try:
        return source if isinstance(source, PlaybackSource) else None
    except Exception:  # noqa: BLE001 - a property of a closed source may raise when looked at
        return None
