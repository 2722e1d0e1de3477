"""The optional abilities a frame source states (`sources.base.FrameSource`: the simulated rig it
renders, its cameras' controls, the playback of a recording), asked of whatever source the
frame worker has now, which may be none."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from stereo_gui.sources.base import FrameSource
    from stereo_gui.sources.camera_controls import PairControls
    from stereo_gui.sources.playback import PlaybackSource
    from stereo_gui.sources.sim.rig import SimRig


def simulated_rig(source: FrameSource | None) -> SimRig | None:
    """The simulated rig `source` renders, or None (another source, or none)."""
    return source.simulated_rig() if source is not None else None


def camera_controls_of(source: FrameSource | None) -> PairControls | None:
    """The two cameras' controls of `source`, or None when it has none (or not now)."""
    return source.camera_controls() if source is not None else None


def playback_of(source: FrameSource | None) -> PlaybackSource | None:
    """The playback controls (pause, step, seek, loop) of `source`, or None."""
    return source.playback() if source is not None else None
