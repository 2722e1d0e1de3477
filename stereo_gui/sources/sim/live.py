"""The simulated rig as a live frame source: the board moving smoothly between poses, in front
of the demo scene or a plain background, paced like a camera."""

from __future__ import annotations

import time

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.sources.base import FramePacer, StereoFrame
from stereo_gui.sources.sim.rig import SimFrameTruth, SimRig
from stereo_gui.sources.sim.scene import BoardPose, Scene


def _interpolate_pose(p0: BoardPose, p1: BoardPose, f: float) -> BoardPose:
    """Pose a fraction f of the way from p0 to p1 (rotation along the shortest arc)."""
    dR = p1.R @ p0.R.T
    rvec = cv2.Rodrigues(dR)[0] * f
    R = cv2.Rodrigues(rvec)[0] @ p0.R
    return BoardPose(R, (1 - f) * p0.t + f * p1.t)


class SimSource:
    """The simulated rig as a live frame source.

    mode "board": a board moving smoothly between poses in front of a plain background;
    "scene": the demo scene alone; "mixed": the board moving in front of the demo scene. The
    poses visit the image corners, edges and centre in turn (SimRig.PLACES), as a technician
    following the coverage guidance does, and always in front of the scene's objects (random
    poses, some of them behind the nearest box, left corners of the images empty for 50 pairs
    and more, and the guidance never said ready).
    With paced=True frames arrive at `fps` like a camera; paced=False returns them at once.
    """

    MODES = ("mixed", "board", "scene")

    def __init__(self, rig: SimRig | None = None, mode: str = "mixed", fps: float = 30.0,
                 paced: bool = True, seed: int = 0, frames_per_move: int = 75):
        if mode not in self.MODES:
            raise InputError(f"simulated source mode must be one of {', '.join(self.MODES)}, not {mode!r}")
        if not fps > 0:
            raise InputError(f"frame rate must be positive, not {fps}")
        self.rig = rig or SimRig(seed=seed)
        self.mode = mode
        self.nominal_fps = float(fps)
        self.paced = bool(paced)
        self.name = "Simulated rig"
        self.scene = Scene.demo() if mode in ("mixed", "scene") else None
        self._rng = np.random.default_rng(seed + 1000003)
        self._pose_rng = np.random.default_rng(seed + 2000003)
        self._frames_per_move = max(2, int(frames_per_move))
        self._from: BoardPose | None = None
        self._to: BoardPose | None = None
        # the next pose goes to PLACES[_moves % len(PLACES)]; the first one to the centre, in
        # full view of both cameras (a far corner is a hard first sight of the board)
        self._moves = SimRig.PLACES.index((0.5, 0.5))
        self._index = 0
        self._pacer = FramePacer()
        self._closed = False
        if self.scene is not None:
            # the first render makes the scene's textures (most of a second); do it here, in
            # whatever thread opens the source, so that read() always takes frame time
            self.rig._render(None, self.scene, np.random.default_rng(0))

    def _pose(self, i: int) -> BoardPose:
        k = i % self._frames_per_move
        if self._to is None or k == 0:
            self._from = self._to or self._next_pose()
            self._to = self._next_pose()
        f = k / self._frames_per_move
        f = f * f * (3 - 2 * f)  # ease in and out: the board rests a moment at each pose
        return _interpolate_pose(self._from, self._to, f)

    def _next_pose(self) -> BoardPose:
        pose = self.rig.place_pose(self._pose_rng, self._moves, self.scene)
        self._moves += 1
        return pose

    def read(self) -> StereoFrame:
        from stereo_gui.core.errors import SourceError

        if self._closed:
            raise SourceError("the simulated rig was closed")
        if self.paced:
            self._pacer.wait(self.nominal_fps)
        pose = None if self.mode == "scene" else self._pose(self._index)
        t = time.monotonic()
        left, right = self.rig._render(pose, self.scene, self._rng)
        frame = StereoFrame(left, right, t, t, self._index,
                            SimFrameTruth(pose, self.scene, self.rig.truth))
        self._index += 1
        return frame

    def close(self) -> None:
        self._closed = True
