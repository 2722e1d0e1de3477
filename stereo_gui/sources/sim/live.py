"""The simulated rig as a live frame source: the board moving smoothly between poses, in front
of the demo scene or a plain background, paced like a camera."""

from __future__ import annotations

import time

import cv2
import numpy as np

from stereo_gui.core.errors import InputError, SourceError
from stereo_gui.sources.base import FramePacer, FrameSource, StereoFrame
from stereo_gui.sources.camera_controls import PairControls
from stereo_gui.sources.sim.conditions import condition_named
from stereo_gui.sources.sim.controls import SimCameraDevice, sim_controls
from stereo_gui.sources.sim.rig import SimFrameTruth, SimRig
from stereo_gui.sources.sim.scene import BoardPose, Scene


def _interpolate_pose(p0: BoardPose, p1: BoardPose, f: float) -> BoardPose:
    """Pose a fraction f of the way from p0 to p1 (rotation along the shortest arc)."""
    dR = p1.R @ p0.R.T
    rvec = cv2.Rodrigues(dR)[0] * f
    R = cv2.Rodrigues(rvec)[0] @ p0.R
    return BoardPose(R, (1 - f) * p0.t + f * p1.t)


class SimSource(FrameSource):
    """The simulated rig as a live frame source.

    mode "board": a board moving smoothly between poses in front of a plain background;
    "scene": the demo scene alone; "mixed": the board moving in front of the demo scene; "wall": a
    painted wall `wall_mm` away rendered under `condition` (sim/conditions.py: its texture's
    contrast, and the webcam effects applied to the rig's cameras). The
    poses visit the image corners, edges and centre in turn (SimRig.PLACES), as a technician
    following the coverage guidance does, and always in front of the scene's objects (random
    poses, some of them behind the nearest box, left corners of the images empty for 50 pairs
    and more, and the guidance never said ready).
    With paced=True frames arrive at `fps` like a camera; paced=False returns them at once.

    Each camera has controls (`camera_controls()`, sim/controls.py) that act on its images.
    The right camera takes its picture the rig's `time_offset_s` after the left: its frame
    time is that much later and it sees the board where it has moved by then.
    """

    MODES = ("mixed", "board", "scene", "wall")
    WALL_MM = (400.0, 8000.0)  # the distances a wall may be put at

    def __init__(self, rig: SimRig | None = None, mode: str = "mixed", fps: float = 30.0,
                 paced: bool = True, seed: int = 0, frames_per_move: int = 75,
                 condition: str = "rig", wall_mm: float = 1000.0):
        if mode not in self.MODES:
            raise InputError(f"simulated source mode must be one of {', '.join(self.MODES)}, not {mode!r}")
        if not fps > 0:
            raise InputError(f"frame rate must be positive, not {fps}")
        self.rig = rig or SimRig(seed=seed)
        self.mode = mode
        self.nominal_fps = float(fps)
        self.paced = bool(paced)
        self.name = "Simulated rig"
        self.condition = None
        self.scene: Scene | None  # what the rig shows besides the board (None: the board alone)
        if mode == "wall":
            lo, hi = self.WALL_MM
            if not lo <= wall_mm <= hi:
                raise InputError(f"the simulated wall must be from {lo / 1000:g} to {hi / 1000:g} m "
                                 f"away, not {wall_mm / 1000:g} m")
            self.condition = condition_named(condition)
            self.rig.set_sensor(self.condition)
            self.name = f"Simulated rig: a wall at {wall_mm / 1000:g} m, {self.condition.description}"
            self.scene = Scene.wall(wall_mm, seed=seed + int(wall_mm),
                                    contrast=self.condition.contrast)
        else:
            self.scene = Scene.demo() if mode in ("mixed", "scene") else None
        self._rng = np.random.default_rng(seed + 1000003)
        self._pose_rng = np.random.default_rng(seed + 2000003)
        self._frames_per_move = max(2, int(frames_per_move))
        self._waypoints: dict[int, BoardPose] = {}  # the poses the board moves between, in turn
        self._next_waypoint = 0
        # the m-th pose goes to PLACES[(_first_place + m) % len(PLACES)]: the first one to the
        # centre, in full view of both cameras (a far corner is a hard first sight of the board)
        self._first_place = SimRig.PLACES.index((0.5, 0.5))
        self._index = 0
        auto = bool(self.rig.config.auto_modes)
        self.devices = (SimCameraDevice(0, auto), SimCameraDevice(1, auto))
        self._controls = (sim_controls(self.devices[0], "left"),
                          sim_controls(self.devices[1], "right"))
        self._pacer = FramePacer()
        self._closed = False
        if self.scene is not None:
            # the first render makes the scene's textures (most of a second); do it here, in
            # whatever thread opens the source, so that read() always takes frame time
            self.rig._render(None, self.scene, np.random.default_rng(0))

    def _waypoint(self, m: int) -> BoardPose:
        """The board's m-th resting pose (drawn in order, so the sequence is the seed's)."""
        while self._next_waypoint <= m:
            self._waypoints[self._next_waypoint] = self.rig.place_pose(
                self._pose_rng, self._first_place + self._next_waypoint, self.scene)
            self._next_waypoint += 1
        for old in [k for k in self._waypoints if k < m - 1]:
            del self._waypoints[old]
        return self._waypoints[m]

    def _pose(self, x: float) -> BoardPose:
        """The board's pose at frame position `x` (a fraction between frames: a camera that
        takes its picture later sees it further on)."""
        x = max(0.0, float(x))
        m = int(x // self._frames_per_move)
        f = (x - m * self._frames_per_move) / self._frames_per_move
        f = f * f * (3 - 2 * f)  # ease in and out: the board rests a moment at each pose
        return _interpolate_pose(self._waypoint(m), self._waypoint(m + 1), f)

    def camera_controls(self) -> PairControls:
        """The simulated cameras' controls (they answer as V4L2 webcams do)."""
        return PairControls(*self._controls)

    def simulated_rig(self) -> SimRig:
        return self.rig

    def read(self) -> StereoFrame:
        if self._closed:
            raise SourceError("the simulated rig was closed")
        if self.paced:
            self._pacer.wait(self.nominal_fps)
        offset = float(self.rig.config.time_offset_s)
        pose = pose_r = None
        if self.mode in ("mixed", "board"):
            pose = self._pose(self._index)
            pose_r = pose if offset == 0 else self._pose(self._index + offset * self.nominal_fps)
        t = time.monotonic()
        looks = [d.look() for d in self.devices]
        left = self.rig._render_camera(0, pose, self.scene, self._rng, looks[0])
        right = self.rig._render_camera(1, pose_r, self.scene, self._rng, looks[1])
        for dev, img, p in zip(self.devices, (left, right), (pose, pose_r), strict=True):
            dev.follow(float(np.mean(cv2.mean(img)[:3])),
                       None if p is None else float(np.linalg.norm(p.t)))
        truth = SimFrameTruth(pose, self.scene, self.rig.truth, pose_r,
                              (looks[0].focal_scale, looks[1].focal_scale))
        frame = StereoFrame(left, right, t, t + offset, self._index, truth)
        self._index += 1
        return frame

    def close(self) -> None:
        self._closed = True
