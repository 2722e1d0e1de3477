"""What the simulated cameras look at: the board's pose and textured planar objects, in the
left camera frame (mm)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError


@dataclass(frozen=True, eq=False)
class BoardPose:
    """Where the board is: X_left = R @ X_board + t (board corner 0 at the origin, Z=0 plane).

    R is 3x3 (R_left_board), t is (3,) in mm in the left camera frame.
    """

    R: np.ndarray
    t: np.ndarray

    @property
    def rvec(self) -> np.ndarray:
        return cv2.Rodrigues(np.asarray(self.R, np.float64))[0].reshape(3)

    def corners_left_mm(self, board: BoardSpec) -> np.ndarray:
        """Inner corners in the left camera frame, (N, 3) float64 mm, OpenCV order."""
        obj = board.object_points_mm().astype(np.float64)
        corners: np.ndarray = obj @ self.R.T + self.t
        return corners

    def to_json(self) -> dict[str, Any]:
        return {"R_left_board": self.R.tolist(), "t_left_board_mm": self.t.tolist()}

    def moved(self, velocity_mm_s: np.ndarray, spin_rad_s: np.ndarray, seconds: float
              ) -> BoardPose:
        """The pose `seconds` later for a board moving at `velocity_mm_s` (3,) and turning at
        `spin_rad_s` (3,, an axis times an angular speed, left camera frame) about its first
        corner."""
        turn = cv2.Rodrigues(np.asarray(spin_rad_s, np.float64).reshape(3, 1) * seconds)[0]
        return BoardPose(turn @ self.R, self.t + np.asarray(velocity_mm_s, np.float64) * seconds)


@dataclass(frozen=True, eq=False)
class SceneObject:
    """A textured rectangle: centre (3,) mm in the left camera frame, in-plane unit axes u, v.

    The rectangle spans centre +- u*width/2 +- v*height/2; `seed` picks its texture and
    `contrast` scales it (1: the rig's usual rich texture; 0.1: a smooth painted wall).
    """

    name: str
    center: np.ndarray
    u: np.ndarray
    v: np.ndarray
    width_mm: float
    height_mm: float
    seed: int = 0
    contrast: float = 1.0

    def __post_init__(self) -> None:
        for k in ("center", "u", "v"):
            object.__setattr__(self, k, np.asarray(getattr(self, k), np.float64).reshape(3))
        if not (math.isfinite(self.contrast) and 0.0 <= self.contrast <= 4.0):
            raise InputError(f"texture contrast must be from 0 to 4, not {self.contrast}")

    @property
    def normal(self) -> np.ndarray:
        n = np.cross(self.u, self.v)
        unit: np.ndarray = n / np.linalg.norm(n)
        return unit

    @property
    def corner_origin(self) -> np.ndarray:
        """The rectangle's (a=0, b=0) corner, mm."""
        return self.center - self.u * self.width_mm / 2 - self.v * self.height_mm / 2

    def hit(self, origin: np.ndarray, direction: np.ndarray) -> float | None:
        """Ray parameter t of the intersection with origin + t*direction, or None."""
        n = self.normal
        denom = float(n @ direction)
        if abs(denom) < 1e-12:
            return None
        t = float(n @ (self.center - origin)) / denom
        if t <= 0:
            return None
        p = origin + t * direction - self.center
        if abs(p @ self.u) <= self.width_mm / 2 and abs(p @ self.v) <= self.height_mm / 2:
            return t
        return None

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "center_mm": self.center.tolist(), "u": self.u.tolist(),
                "contrast": self.contrast,
                "v": self.v.tolist(), "width_mm": self.width_mm, "height_mm": self.height_mm,
                "normal": self.normal.tolist(),
                "distance_mm": float(self.center[2]) if abs(self.normal[2]) > 0.999 else None}


def _fronto(name: str, cx: float, cy: float, z: float, w: float, h: float, seed: int,
            yaw_deg: float = 0.0, contrast: float = 1.0) -> SceneObject:
    a = math.radians(yaw_deg)
    u = np.array([math.cos(a), 0.0, math.sin(a)])
    return SceneObject(name, np.array([cx, cy, z]), u, np.array([0.0, 1.0, 0.0]), w, h, seed,
                       contrast)


@dataclass(frozen=True, eq=False)
class Scene:
    """Textured planar objects in the left camera frame (mm)."""

    objects: tuple[SceneObject, ...]
    name: str = "scene"

    @staticmethod
    def wall(distance_mm: float, seed: int = 1, contrast: float = 1.0) -> Scene:
        """A fronto-parallel textured wall at Z = distance_mm filling both cameras' views, its
        texture's contrast scaled by `contrast` (see SceneObject)."""
        z = float(distance_mm)
        if not z > 0:
            raise InputError(f"wall distance must be positive, not {distance_mm}")
        # wide enough for both cameras' (distorted, so wider) fields of view and the baseline
        w = 2.0 * (0.75 * z + 250.0)
        h = 2.0 * (0.6 * z + 200.0)
        return Scene((_fronto("wall", 0.0, 0.0, z, w, h, seed, contrast=contrast),),
                     name=f"wall-{z:g}mm" + ("" if contrast == 1.0 else f"-contrast{contrast:g}"))

    @staticmethod
    def demo() -> Scene:
        """A background wall at 3 m with three objects in front: 0.8 m, 1.3 m, 2 m."""
        return Scene((
            _fronto("wall", 0.0, 0.0, 3000.0, 2.0 * (0.75 * 3000 + 250), 2.0 * (0.6 * 3000 + 200), 11),
            _fronto("box-0.8m", -260.0, 60.0, 800.0, 260.0, 300.0, 12),
            _fronto("panel-1.3m", 240.0, -120.0, 1300.0, 420.0, 360.0, 13, yaw_deg=20.0),
            _fronto("poster-2m", 30.0, 250.0, 2000.0, 600.0, 380.0, 14),
        ), name="demo")

    def depth_along_ray(self, origin: ArrayLike, direction: ArrayLike) -> float | None:
        """Distance (mm, along the normalised direction) from origin to the first hit, or None."""
        o = np.asarray(origin, np.float64).reshape(3)
        d = np.asarray(direction, np.float64).reshape(3)
        d = d / np.linalg.norm(d)
        hits = [t for t in (obj.hit(o, d) for obj in self.objects) if t is not None]
        return min(hits) if hits else None

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "objects": [o.to_json() for o in self.objects]}
