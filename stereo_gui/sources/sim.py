"""The simulated stereo rig: two distorted pinhole cameras with known truth, rendering a chessboard
and textured planar objects. It is a frame source, the demo, and the ground truth of the tests.

Rendering goes through OpenCV's distortion model exactly: for each camera a ray map holds, for
every supersample of every output pixel, the normalised undistorted ray (x, y, 1) obtained by
inverting the distortion model (Newton iteration, checked against cv2.projectPoints). Each frame
intersects those rays with the planes of the board and scene, looks up the texture, and averages
the supersamples (anti-aliasing). Frames: the left camera frame is the world frame; a point X_left
maps to the right camera as X_right = R @ X_left + T (R_right_left, T_right_left, mm), the same
convention as cv2.stereoCalibrate.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.atomic import write_image_atomic, write_json_atomic
from stereo_gui.sources.base import FramePacer, StereoFrame

log = logging.getLogger(__name__)

TRUTH_FORMAT_VERSION = 1

# grey levels of the printed board (not 0/255, so that noise does not clip)
_BLACK = 28.0
_WHITE = 225.0
_BOARD_BACKGROUND = 118.0  # plain grey behind the board when no scene is shown
_TEXELS_PER_SQUARE = 96
# multi-scale noise octaves of object textures: (size in texels, amplitude)
_TEXTURE_MAX_PX = 1536.0  # longest side of an object texture, texels
OCTAVES = ((1, 0.55), (2, 0.8), (4, 1.0), (8, 0.9), (16, 0.8), (48, 0.9), (160, 0.7))
_NOISE_PAD = 64  # the noise bank is this much larger than an image (random crops)  # board texture resolution: 0.26 mm texels for 25 mm squares


# ---------------------------------------------------------------------------------------------
# rig description
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CameraTruth:
    """One camera's true intrinsics: M (3x3 float64, px) and D (1x5 float64: k1 k2 p1 p2 k3)."""

    M: np.ndarray
    D: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "M", np.asarray(self.M, np.float64).reshape(3, 3))
        object.__setattr__(self, "D", np.asarray(self.D, np.float64).reshape(1, 5))

    @staticmethod
    def make(fx: float, fy: float, cx: float, cy: float,
             k1: float = 0.0, k2: float = 0.0, p1: float = 0.0, p2: float = 0.0,
             k3: float = 0.0) -> CameraTruth:
        M = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return CameraTruth(M, np.array([[k1, k2, p1, p2, k3]]))


def _default_left() -> CameraTruth:
    return CameraTruth.make(752.0, 748.5, 323.6, 237.2, k1=-0.182, k2=0.061, p1=1.1e-3,
                            p2=-6.0e-4, k3=-0.012)


def _default_right() -> CameraTruth:
    return CameraTruth.make(745.3, 742.8, 316.1, 243.4, k1=-0.214, k2=0.083, p1=-7.5e-4,
                            p2=1.25e-3, k3=-0.021)


@dataclass(frozen=True)
class RigConfig:
    """How to build a simulated rig. Angles in radians, lengths in mm, noise in grey levels."""

    image_size: tuple[int, int] = (640, 480)  # (width, height), px
    left: CameraTruth = field(default_factory=_default_left)
    right: CameraTruth = field(default_factory=_default_right)
    # R_right_left as a Rodrigues vector: about 0.8 degrees in total
    rvec_right_left: tuple[float, float, float] = (0.0061, -0.0118, 0.0042)
    baseline_mm: float = 110.0
    # direction of T_right_left; scaled so that |T| = baseline_mm
    t_direction: tuple[float, float, float] = (-1.0, 0.0065, -0.0085)
    noise_sigma: float = 2.0  # sensor noise, grey levels (standard deviation)
    gain_right: float = 0.93  # the right camera is a little darker
    board: BoardSpec = field(default_factory=BoardSpec)
    supersample: int = 3  # samples per pixel along each axis (anti-aliasing)

    @staticmethod
    def for_size(size: tuple[int, int]) -> RigConfig:
        """The default rig at another resolution: the same horizontal field of view (camera
        matrices scaled by width/640, principal points kept at the same place relative to the
        centre); fewer supersamples above 640x480 to keep rendering fast."""
        w, h = int(size[0]), int(size[1])
        base = RigConfig()
        if (w, h) == base.image_size:
            return base
        if w < 64 or h < 48:
            raise InputError(f"the simulated rig needs at least 64x48 pixels, not {w}x{h}")
        k = w / base.image_size[0]

        def scaled(cam: CameraTruth) -> CameraTruth:
            M = cam.M.copy()
            M[:2, :2] *= k
            M[0, 2] = (M[0, 2] - (base.image_size[0] - 1) / 2) * k + (w - 1) / 2
            M[1, 2] = (M[1, 2] - (base.image_size[1] - 1) / 2) * k + (h - 1) / 2
            return CameraTruth(M, cam.D.copy())

        return RigConfig(image_size=(w, h), left=scaled(base.left), right=scaled(base.right),
                         supersample=3 if w * h <= 640 * 480 else 2)


@dataclass(frozen=True, eq=False)
class RigTruth:
    """The rig's true parameters, named as cv2.stereoCalibrate returns them (T in mm)."""

    image_size: tuple[int, int]
    M1: np.ndarray
    D1: np.ndarray
    M2: np.ndarray
    D2: np.ndarray
    R: np.ndarray  # R_right_left
    T: np.ndarray  # T_right_left, 3x1, mm
    board: BoardSpec

    @property
    def baseline_mm(self) -> float:
        return float(np.linalg.norm(self.T))

    @property
    def relative_rotation_deg(self) -> float:
        rvec, _ = cv2.Rodrigues(self.R)
        return float(np.degrees(np.linalg.norm(rvec)))

    def to_json(self) -> dict:
        return {
            "format_version": TRUTH_FORMAT_VERSION,
            "image_size": [int(self.image_size[0]), int(self.image_size[1])],
            "M1": self.M1.tolist(), "D1": self.D1.reshape(-1).tolist(),
            "M2": self.M2.tolist(), "D2": self.D2.reshape(-1).tolist(),
            "R": self.R.tolist(), "T": self.T.reshape(-1).tolist(),
            "baseline_mm": self.baseline_mm,
            "relative_rotation_deg": self.relative_rotation_deg,
            "board": {"cols": self.board.cols, "rows": self.board.rows,
                      "square_mm": self.board.square_mm},
        }

    @staticmethod
    def from_json(data: dict, where: str = "rig truth") -> RigTruth:
        """The truth `to_json` wrote; InputError naming `where` and the field when a value is
        missing, of the wrong type, not finite or not what a camera can have."""
        def bad(text: str) -> InputError:
            return InputError(f"{where}: {text}")

        def matrix(key: str, shape: tuple[int, ...]) -> np.ndarray:
            raw = data.get(key)
            try:
                m = np.array(raw, np.float64)
            except (TypeError, ValueError, OverflowError):
                raise bad(f"{key} should be a list of numbers") from None
            if m.size != int(np.prod(shape)) or (m.ndim != len(shape) and m.ndim != 1):
                raise bad(f"{key} should be {'x'.join(map(str, shape))} numbers")
            m = m.reshape(shape)
            if not np.all(np.isfinite(m)) or np.max(np.abs(m)) > 1e7:
                raise bad(f"{key} holds values that are not finite or absurd")
            return m

        if not isinstance(data, dict):
            raise bad("should be a JSON object")
        size = data.get("image_size")
        if not (isinstance(size, list) and len(size) == 2 and all(
                isinstance(v, int) and not isinstance(v, bool) and 0 < v <= 100_000
                for v in size)):
            raise bad(f"image_size should be [width, height] in px, not {size!r:.60}")
        M1, M2 = matrix("M1", (3, 3)), matrix("M2", (3, 3))
        for key, M in (("M1", M1), ("M2", M2)):
            if not (M[0, 0] > 0 and M[1, 1] > 0 and np.allclose(M[2], (0, 0, 1))):
                raise bad(f"{key} is not a camera matrix (positive focal lengths, last row 0 0 1)")
        D = {}
        for key in ("D1", "D2"):
            raw = data.get(key)
            n = len(raw) if isinstance(raw, list) else -1
            if n not in (4, 5, 8, 12, 14):
                raise bad(f"{key} should have 4, 5, 8, 12 or 14 coefficients")
            D[key] = matrix(key, (n,)).reshape(1, -1)
        R = matrix("R", (3, 3))
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
            raise bad("R is not a rotation")
        T = matrix("T", (3,)).reshape(3, 1)
        if not np.linalg.norm(T) > 0:
            raise bad("T is zero: the cameras would be at the same place")
        b = data.get("board")
        if not isinstance(b, dict):
            raise bad("board should be an object with cols, rows, square_mm")
        cols, rows, sq = b.get("cols"), b.get("rows"), b.get("square_mm")
        if not (isinstance(cols, int) and isinstance(rows, int) and not isinstance(cols, bool)
                and not isinstance(rows, bool) and isinstance(sq, int | float)
                and not isinstance(sq, bool)):
            raise bad("board cols and rows should be whole numbers and square_mm a number")
        try:
            board = BoardSpec(cols, rows, float(sq))
        except InputError as exc:
            raise bad(f"board: {exc}") from None
        return RigTruth(image_size=(size[0], size[1]), M1=M1, D1=D["D1"], M2=M2, D2=D["D2"],
                        R=R, T=T, board=board)


def load_truth(path: str | Path) -> RigTruth:
    """The rig truth of a `truth.json` written by `write_calibration_set` (or its folder)."""
    from stereo_gui.files.readers import read_json_object

    path = Path(path)
    if path.is_dir():
        path = path / "truth.json"
    return RigTruth.from_json(read_json_object(path, "rig truth"), where=str(path))


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
        return obj @ self.R.T + self.t

    def to_json(self) -> dict:
        return {"R_left_board": self.R.tolist(), "t_left_board_mm": self.t.tolist()}


# ---------------------------------------------------------------------------------------------
# scene
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SceneObject:
    """A textured rectangle: centre (3,) mm in the left camera frame, in-plane unit axes u, v.

    The rectangle spans centre +- u*width/2 +- v*height/2; `seed` picks its texture.
    """

    name: str
    center: np.ndarray
    u: np.ndarray
    v: np.ndarray
    width_mm: float
    height_mm: float
    seed: int = 0

    def __post_init__(self) -> None:
        for k in ("center", "u", "v"):
            object.__setattr__(self, k, np.asarray(getattr(self, k), np.float64).reshape(3))

    @property
    def normal(self) -> np.ndarray:
        n = np.cross(self.u, self.v)
        return n / np.linalg.norm(n)

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

    def to_json(self) -> dict:
        return {"name": self.name, "center_mm": self.center.tolist(), "u": self.u.tolist(),
                "v": self.v.tolist(), "width_mm": self.width_mm, "height_mm": self.height_mm,
                "normal": self.normal.tolist(),
                "distance_mm": float(self.center[2]) if abs(self.normal[2]) > 0.999 else None}


def _fronto(name: str, cx: float, cy: float, z: float, w: float, h: float, seed: int,
            yaw_deg: float = 0.0) -> SceneObject:
    a = math.radians(yaw_deg)
    u = np.array([math.cos(a), 0.0, math.sin(a)])
    return SceneObject(name, np.array([cx, cy, z]), u, np.array([0.0, 1.0, 0.0]), w, h, seed)


@dataclass(frozen=True, eq=False)
class Scene:
    """Textured planar objects in the left camera frame (mm)."""

    objects: tuple[SceneObject, ...]
    name: str = "scene"

    @staticmethod
    def wall(distance_mm: float, seed: int = 1) -> Scene:
        """A fronto-parallel textured wall at Z = distance_mm filling both cameras' views."""
        z = float(distance_mm)
        if not z > 0:
            raise InputError(f"wall distance must be positive, not {distance_mm}")
        # wide enough for both cameras' (distorted, so wider) fields of view and the baseline
        w = 2.0 * (0.75 * z + 250.0)
        h = 2.0 * (0.6 * z + 200.0)
        return Scene((_fronto("wall", 0.0, 0.0, z, w, h, seed),), name=f"wall-{z:g}mm")

    @staticmethod
    def demo() -> Scene:
        """A background wall at 3 m with three objects in front: 0.8 m, 1.3 m, 2 m."""
        return Scene((
            _fronto("wall", 0.0, 0.0, 3000.0, 2.0 * (0.75 * 3000 + 250), 2.0 * (0.6 * 3000 + 200), 11),
            _fronto("box-0.8m", -260.0, 60.0, 800.0, 260.0, 300.0, 12),
            _fronto("panel-1.3m", 240.0, -120.0, 1300.0, 420.0, 360.0, 13, yaw_deg=20.0),
            _fronto("poster-2m", 30.0, 250.0, 2000.0, 600.0, 380.0, 14),
        ), name="demo")

    def depth_along_ray(self, origin, direction) -> float | None:
        """Distance (mm, along the normalised direction) from origin to the first hit, or None."""
        o = np.asarray(origin, np.float64).reshape(3)
        d = np.asarray(direction, np.float64).reshape(3)
        d = d / np.linalg.norm(d)
        hits = [t for t in (obj.hit(o, d) for obj in self.objects) if t is not None]
        return min(hits) if hits else None

    def to_json(self) -> dict:
        return {"name": self.name, "objects": [o.to_json() for o in self.objects]}


# ---------------------------------------------------------------------------------------------
# ray maps and textures (cached: they are the expensive, per-rig parts)
# ---------------------------------------------------------------------------------------------
def _distort(x: np.ndarray, y: np.ndarray, D: np.ndarray):
    """OpenCV's distortion (k1 k2 p1 p2 k3) of normalised coordinates, with its Jacobian."""
    k1, k2, p1, p2, k3 = (float(v) for v in D.reshape(-1)[:5])
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    jxx = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
    jxy = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    jyx = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    jyy = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
    return xd, yd, jxx, jxy, jyx, jyy


def undistort_normalized(u: np.ndarray, v: np.ndarray, M: np.ndarray, D: np.ndarray,
                         iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Invert the distortion model: pixel (u, v) -> normalised undistorted (x, y), float64.

    Newton iteration on OpenCV's forward model; converges to machine precision for webcam-like
    distortion (checked against cv2.projectPoints in the tests).
    """
    fx, fy, cx, cy = M[0, 0], M[1, 1], M[0, 2], M[1, 2]
    xd = (np.asarray(u, np.float64) - cx) / fx
    yd = (np.asarray(v, np.float64) - cy) / fy
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        fx_, fy_, a, b, c, d = _distort(x, y, D)
        ex, ey = fx_ - xd, fy_ - yd
        det = a * d - b * c
        x -= (d * ex - b * ey) / det
        y -= (a * ey - c * ex) / det
    return x, y


@dataclass(frozen=True, eq=False)
class RayMap:
    """Normalised rays (x, y, 1) of every supersample of a camera: xy float32 (H*s, W*s, 2)."""

    xy: np.ndarray
    supersample: int
    max_error_px: float  # round-trip error of the inversion, checked with cv2.projectPoints


def _interp_cubic(a: np.ndarray, pos: np.ndarray, axis: int) -> np.ndarray:
    """Sample `a` along `axis` at fractional indices `pos` (1-D) by 4-point Lagrange
    interpolation; the caller keeps pos within [1, n - 3)."""
    base = np.floor(pos).astype(np.intp)
    t = (pos - base).astype(a.dtype)
    weights = (-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2,
               -(t + 1) * t * (t - 2) / 2, (t + 1) * t * (t - 1) / 6)
    src = np.moveaxis(a, axis, 0)
    shape = (-1,) + (1,) * (src.ndim - 1)
    out = weights[0].reshape(shape) * src[base - 1]
    for j in (1, 2, 3):
        out += weights[j].reshape(shape) * src[base + j - 1]
    return np.moveaxis(out, 0, axis)


# ray maps: the exact inverse is computed on a grid this many pixels apart, then interpolated
_RAY_GRID_PX = 4


@functools.lru_cache(maxsize=8)
def _ray_map_cached(M_bytes: bytes, D_bytes: bytes, w: int, h: int, s: int) -> RayMap:
    M = np.frombuffer(M_bytes, np.float64).reshape(3, 3)
    D = np.frombuffer(D_bytes, np.float64).reshape(1, 5)
    # Exact inversion (OpenCV's iterative undistortion, tight criteria) on a grid every
    # _RAY_GRID_PX pixels with a margin, then cubic Lagrange interpolation to the supersample
    # positions: the inverse is so smooth at that spacing that interpolation adds < 1e-4 px
    # (the round trip is checked below with cv2.projectPoints), and it is much faster than
    # inverting every supersample.
    g = _RAY_GRID_PX
    margin = 2 * g
    gx = np.arange(-margin, w + margin + 1, g, dtype=np.float64)
    gy = np.arange(-margin, h + margin + 1, g, dtype=np.float64)
    gu, gv = np.meshgrid(gx, gy)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-14)
    grid = cv2.undistortPoints(np.stack([gu, gv], -1).reshape(-1, 1, 2), M, D, criteria=crit)
    grid = grid.reshape(len(gy), len(gx), 2)
    offs = (np.arange(s) + 0.5) / s - 0.5  # sample positions inside a pixel (centre = integer)
    us = (np.arange(w)[:, None] + offs[None, :]).reshape(-1)
    vs = (np.arange(h)[:, None] + offs[None, :]).reshape(-1)
    rows = _interp_cubic(grid, (us + margin) / g, axis=1)  # float64: (len(gy), W*s, 2)
    xy = _interp_cubic(rows.astype(np.float32), (vs + margin) / g, axis=0)
    sel = (slice(None, None, max(1, h * s // 37)), slice(None, None, max(1, w * s // 53)))
    uu, vv = np.meshgrid(us[sel[1]], vs[sel[0]])
    sub = xy[sel].reshape(-1, 2).astype(np.float64)
    pts = np.concatenate([sub, np.ones((len(sub), 1))], 1)
    proj, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), M, D)
    err = np.hypot(proj[:, 0, 0] - uu.ravel(), proj[:, 0, 1] - vv.ravel())
    max_err = float(err.max())
    if max_err > 1e-3:
        raise RuntimeError(f"distortion inversion failed: round trip error {max_err:.2e} px")
    return RayMap(np.ascontiguousarray(xy, dtype=np.float32), s, max_err)


def ray_map(cam: CameraTruth, image_size: tuple[int, int], supersample: int) -> RayMap:
    """The (cached) ray map of one camera."""
    return _ray_map_cached(np.ascontiguousarray(cam.M).tobytes(),
                           np.ascontiguousarray(cam.D.reshape(1, 5)).tobytes(),
                           int(image_size[0]), int(image_size[1]), int(supersample))


@functools.lru_cache(maxsize=16)
def _texture(seed: int, width_mm: float, height_mm: float) -> tuple[np.ndarray, float]:
    """A rich colour texture (uint8 HxWx3) for an object, and its texel size in mm.

    Multi-scale noise (octaves of smoothly upsampled random images) so that there is detail for
    the matcher at every distance: the texel follows the object's size, walls grow with distance.
    """
    texel = max(max(width_mm, height_mm) / _TEXTURE_MAX_PX, 0.35)
    tw = max(8, int(math.ceil(width_mm / texel)) + 2)
    th = max(8, int(math.ceil(height_mm / texel)) + 2)
    rng = np.random.default_rng(seed)
    acc = np.zeros((th, tw, 3), np.float32)
    total = 0.0
    for k, amp in OCTAVES:
        sw, sh = max(2, tw // k), max(2, th // k)
        small = rng.standard_normal((sh, sw, 3), dtype=np.float32)
        small[..., 1:] = 0.6 * small[..., :1] + 0.4 * small[..., 1:]  # partly grey, partly colour
        layer = small if k == 1 else cv2.resize(small, (tw, th), interpolation=cv2.INTER_CUBIC)
        acc += amp * layer[:th, :tw]
        total += amp * amp
    acc *= 46.0 / math.sqrt(total)
    acc += 125.0 + rng.uniform(-30.0, 30.0, 3).astype(np.float32)  # a tint per object
    tex = np.empty((th, tw, 4), np.uint8)
    tex[..., :3] = np.clip(acc, 10, 245)
    tex[..., 3] = 255  # alpha: outside the texture remap gives 0, which masks the object
    return tex, texel


@functools.lru_cache(maxsize=8)
def _board_texture(cols: int, rows: int, square_mm: float) -> tuple[np.ndarray, float]:
    """The printed board (BGRA uint8) over its outline, and its texel size in mm.

    Squares are exact in texels (TEXELS_PER_SQUARE each), the black corner square at (-1, -1)
    as OpenCV expects, a white border of one square around them.
    """
    n = _TEXELS_PER_SQUARE
    qa = (np.arange((cols + 3) * n) + 0.5) / n - 2.0  # texel centres in squares from corner 0
    qb = (np.arange((rows + 3) * n) + 0.5) / n - 2.0
    ia, ib = np.floor(qa).astype(int), np.floor(qb).astype(int)
    in_a = (ia >= -1) & (ia < cols)
    in_b = (ib >= -1) & (ib < rows)
    black = in_b[:, None] & in_a[None, :] & (((ib[:, None] + ia[None, :]) & 1) == 0)
    tex = np.empty((len(qb), len(qa), 4), np.uint8)
    tex[..., :3] = np.where(black, np.uint8(_BLACK), np.uint8(_WHITE))[..., None]
    tex[..., 3] = 255
    return tex, square_mm / n


# ---------------------------------------------------------------------------------------------
# the rig
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimFrameTruth:
    """Ground truth attached to a simulated frame (StereoFrame.truth)."""

    pose: BoardPose | None
    scene: Scene | None
    truth: RigTruth


@dataclass(frozen=True, eq=False)
class _Plane:
    """A rectangle in one camera's frame, ready for rendering: origin + a*u + b*v, a in
    [0, width], b in [0, height] (mm)."""

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    width: float
    height: float


class SimRig:
    """A simulated stereo rig with known truth that renders board and scene pairs."""

    def __init__(self, config: RigConfig | None = None, seed: int = 0):
        self.config = config or RigConfig()
        self.seed = int(seed)
        c = self.config
        R, _ = cv2.Rodrigues(np.asarray(c.rvec_right_left, np.float64).reshape(3, 1))
        tdir = np.asarray(c.t_direction, np.float64).reshape(3)
        T = (tdir / np.linalg.norm(tdir) * c.baseline_mm).reshape(3, 1)
        self.truth = RigTruth(tuple(c.image_size), c.left.M.copy(), c.left.D.copy(),
                              c.right.M.copy(), c.right.D.copy(), R, T, c.board)
        self._rays = (ray_map(c.left, c.image_size, c.supersample),
                      ray_map(c.right, c.image_size, c.supersample))
        self._scene_cache: dict[tuple, tuple] = {}
        self._noise: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()

    # ---- geometry -------------------------------------------------------------------------
    def _to_camera(self, cam: int, p: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the left frame -> camera `cam` (0 left, 1 right) frame."""
        if cam == 0:
            return p
        return p @ self.truth.R.T + self.truth.T.reshape(3)

    def _dir_to_camera(self, cam: int, d: np.ndarray) -> np.ndarray:
        return d if cam == 0 else d @ self.truth.R.T

    def project(self, points_left_mm: np.ndarray, cam: int) -> np.ndarray:
        """Project (N, 3) left-frame points (mm) into camera `cam`'s image, (N, 2) px."""
        M, D = (self.truth.M1, self.truth.D1) if cam == 0 else (self.truth.M2, self.truth.D2)
        rvec = np.zeros(3) if cam == 0 else cv2.Rodrigues(self.truth.R)[0]
        tvec = np.zeros(3) if cam == 0 else self.truth.T.reshape(3)
        pts, _ = cv2.projectPoints(np.asarray(points_left_mm, np.float64).reshape(-1, 1, 3),
                                   rvec, tvec, M, D)
        return pts.reshape(-1, 2)

    def board_outline_mm(self) -> tuple[float, float, float, float]:
        """The printed board (squares plus white border) on its plane: (a0, b0, a1, b1) mm."""
        b = self.config.board
        s = b.square_mm
        return (-2.0 * s, -2.0 * s, (b.cols + 1) * s, (b.rows + 1) * s)

    def _board_visible(self, pose: BoardPose, margin_px: float = 8.0) -> bool:
        a0, b0, a1, b1 = self.board_outline_mm()
        # densely sample the outline: the distorted image of a straight edge is curved
        k = np.linspace(0.0, 1.0, 17)
        edge = np.concatenate([
            np.stack([a0 + (a1 - a0) * k, np.full_like(k, b0)], 1),
            np.stack([a0 + (a1 - a0) * k, np.full_like(k, b1)], 1),
            np.stack([np.full_like(k, a0), b0 + (b1 - b0) * k], 1),
            np.stack([np.full_like(k, a1), b0 + (b1 - b0) * k], 1)])
        pts = np.concatenate([edge, np.zeros((len(edge), 1))], 1) @ pose.R.T + pose.t
        w, h = self.config.image_size
        for cam in (0, 1):
            pc = self._to_camera(cam, pts)
            if np.any(pc[:, 2] < 100.0):
                return False
            # beyond about 50 degrees off-axis the distortion polynomial is not meaningful
            if np.any(np.hypot(pc[:, 0], pc[:, 1]) / pc[:, 2] > 0.9):
                return False
            uv = self.project(pts, cam)
            if (uv[:, 0].min() < margin_px or uv[:, 1].min() < margin_px
                    or uv[:, 0].max() > w - 1 - margin_px or uv[:, 1].max() > h - 1 - margin_px):
                return False
        return True

    def random_board_pose(self, rng: np.random.Generator, max_tries: int = 2000) -> BoardPose:
        """One random board pose fully visible in both images (0.4-1.2 m, tilts up to 40 deg).

        Depth and tilt are drawn first; the position is then drawn uniformly over the room the
        board leaves in both images, so that poses reach the image edges (needed to see the
        distortion) as often as the centre.
        """
        b = self.config.board
        w, h = self.config.image_size
        margin = 10.0
        centre_board = np.array([(b.cols - 1) * b.square_mm / 2, (b.rows - 1) * b.square_mm / 2, 0])
        a0, b0, a1, b1 = self.board_outline_mm()
        outline = np.array([[a0, b0, 0], [a1, b0, 0], [a1, b1, 0], [a0, b1, 0]], np.float64)
        f = float(self.truth.M1[0, 0])
        for _ in range(max_tries):
            z = rng.uniform(400.0, 1200.0)
            tilt_x = math.radians(rng.uniform(-40, 40))
            tilt_y = math.radians(rng.uniform(-40, 40))
            if math.hypot(tilt_x, tilt_y) > math.radians(45):
                continue
            spin = math.radians(rng.uniform(-20, 20))
            R = (cv2.Rodrigues(np.array([0.0, tilt_y, 0.0]))[0]
                 @ cv2.Rodrigues(np.array([tilt_x, 0.0, 0.0]))[0]
                 @ cv2.Rodrigues(np.array([0.0, 0.0, spin]))[0])
            t0 = np.array([0.0, 0.0, z]) - R @ centre_board
            pts = outline @ R.T + t0
            if np.any(pts[:, 2] < 150.0):
                continue
            lo, hi = np.array([-np.inf, -np.inf]), np.array([np.inf, np.inf])
            for cam in (0, 1):
                uv = self.project(pts, cam)
                lo = np.maximum(lo, [margin - uv[:, 0].min(), margin - uv[:, 1].min()])
                hi = np.minimum(hi, [w - 1 - margin - uv[:, 0].max(), h - 1 - margin - uv[:, 1].max()])
            if np.any(hi <= lo):
                continue
            shift_px = rng.uniform(lo, hi)
            pose = BoardPose(R, t0 + np.array([shift_px[0] * z / f, shift_px[1] * z / f, 0.0]))
            if self._board_visible(pose, margin_px=margin - 2.0):
                return pose
        raise RuntimeError("could not find a board pose visible in both cameras")

    def board_poses(self, n: int, seed: int | None = None) -> list[BoardPose]:
        """`n` varied board poses (0.4-1.2 m, tilts up to 40 deg, positions covering the image),
        each with the whole board visible in both images with a margin."""
        rng = np.random.default_rng(self.seed * 7919 + 17 if seed is None else seed)
        return [self.random_board_pose(rng) for _ in range(int(n))]

    # ---- rendering ------------------------------------------------------------------------
    def _plane_in_camera(self, cam: int, origin, u, v, width: float, height: float) -> _Plane:
        return _Plane(self._to_camera(cam, np.asarray(origin, np.float64)),
                      self._dir_to_camera(cam, np.asarray(u, np.float64)),
                      self._dir_to_camera(cam, np.asarray(v, np.float64)), width, height)

    def _bbox(self, cam: int, plane_left: _Plane) -> tuple[int, int, int, int] | None:
        """Supersample-grid box (x0, y0, x1, y1) that contains the plane's image, or None."""
        s = self.config.supersample
        w, h = self.config.image_size
        k = np.linspace(0.0, 1.0, 33)
        ab = np.concatenate([
            np.stack([k * plane_left.width, np.zeros_like(k)], 1),
            np.stack([k * plane_left.width, np.full_like(k, plane_left.height)], 1),
            np.stack([np.zeros_like(k), k * plane_left.height], 1),
            np.stack([np.full_like(k, plane_left.width), k * plane_left.height], 1)])
        pts = plane_left.origin + ab[:, :1] * plane_left.u + ab[:, 1:] * plane_left.v
        pc = self._to_camera(cam, pts)
        if np.all(pc[:, 2] <= 0):
            return None
        rad = np.hypot(pc[:, 0], pc[:, 1]) / np.maximum(pc[:, 2], 1e-9)
        if np.any(pc[:, 2] <= 1.0) or np.any(rad > 0.9):
            return (0, 0, w * s, h * s)  # partly behind or far off-axis: test every ray
        uv = self.project(pts, cam)
        x0 = int(math.floor((uv[:, 0].min() - 3) * s))
        y0 = int(math.floor((uv[:, 1].min() - 3) * s))
        x1 = int(math.ceil((uv[:, 0].max() + 4) * s))
        y1 = int(math.ceil((uv[:, 1].max() + 4) * s))
        x0, y0 = max(0, x0), max(0, y0)
        x1, y1 = min(w * s, x1), min(h * s, y1)
        if x1 <= x0 or y1 <= y0:
            return None
        return (x0, y0, x1, y1)

    def _draw_plane(self, cam: int, plane_left: _Plane, tex: np.ndarray, texel: float,
                    img: np.ndarray, zbuf: np.ndarray | None, box0: tuple[int, int] = (0, 0)
                    ) -> None:
        """Draw a textured rectangle into the supersampled `img` (which starts at supersample
        (x, y) = box0 of the full grid), with a depth test against `zbuf` when given.

        The texture spans the rectangle (texel centres at (i + 0.5) * texel mm); it must have an
        alpha channel (remap's zero border marks rays that miss the rectangle).
        """
        box = self._bbox(cam, plane_left)
        if box is None:
            return
        ox, oy = box0
        hh, ww = img.shape[:2]
        x0, y0 = max(box[0], ox), max(box[1], oy)
        x1, y1 = min(box[2], ox + ww), min(box[3], oy + hh)
        if x1 <= x0 or y1 <= y0:
            return
        pl = self._plane_in_camera(cam, plane_left.origin, plane_left.u, plane_left.v,
                                   plane_left.width, plane_left.height)
        n = np.cross(pl.u, pl.v)
        npo = float(n @ pl.origin)
        if abs(npo) < 1e-9:
            return  # the plane passes through the camera centre: seen edge-on
        # a ray t*(x, y, 1) meets the plane at depth t = n.o / n.r, where (a, b) =
        # (u.(t r - o), v.(t r - o)): a homography of (x, y, 1); fold in mm -> texel centres
        Ha = npo * pl.u - float(pl.u @ pl.origin) * n
        Hb = npo * pl.v - float(pl.v @ pl.origin) * n
        H = np.stack([Ha / texel - 0.5 * n, Hb / texel - 0.5 * n, n])
        xy = np.ascontiguousarray(self._rays[cam].xy[y0:y1, x0:x1])
        tmap = cv2.perspectiveTransform(xy, H)
        sampled = cv2.remap(tex, tmap, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                            borderValue=(0, 0, 0, 0))
        mask = cv2.compare(sampled[..., 3], 127, cv2.CMP_GT)
        Hz = np.array([[0.0, 0.0, npo], [0.0, 0.0, 0.0], n])  # (x, y, 1) -> (depth, 0)
        z = cv2.perspectiveTransform(xy, Hz)[..., 0]
        cv2.bitwise_and(mask, cv2.compare(z, 0.0, cv2.CMP_GT), dst=mask)
        if zbuf is not None:
            zb = zbuf[y0 - oy:y1 - oy, x0 - ox:x1 - ox]
            cv2.bitwise_and(mask, cv2.compare(z, zb, cv2.CMP_LT), dst=mask)
            cv2.copyTo(z, mask, zb)
        cv2.copyTo(np.ascontiguousarray(sampled[..., :3]), mask, img[y0 - oy:y1 - oy, x0 - ox:x1 - ox])

    def _object_plane(self, obj: SceneObject) -> _Plane:
        return _Plane(obj.corner_origin, obj.u, obj.v, obj.width_mm, obj.height_mm)

    def _board_plane(self, pose: BoardPose) -> _Plane:
        a0, b0, a1, b1 = self.board_outline_mm()
        origin = pose.t + pose.R @ np.array([a0, b0, 0.0])
        return _Plane(origin, pose.R[:, 0], pose.R[:, 1], a1 - a0, b1 - b0)

    def _background(self, cam: int, scene: Scene | None):
        """Supersampled image (uint8 BGR), depth buffer and averaged image of the static scene
        for one camera (cached: the scene does not move)."""
        key = (cam, id(scene))
        with self._lock:
            hit = self._scene_cache.get(key)
            if hit is not None and hit[0] is scene:
                return hit[1:]
        s = self.config.supersample
        w, h = self.config.image_size
        img = np.full((h * s, w * s, 3), _BOARD_BACKGROUND, np.uint8)
        zbuf = np.full((h * s, w * s), np.inf, np.float32)
        if scene is not None:
            for obj in scene.objects:
                tex, texel = _texture(int(obj.seed), float(obj.width_mm), float(obj.height_mm))
                self._draw_plane(cam, self._object_plane(obj), tex, texel, img, zbuf)
        small = img if s == 1 else cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
        with self._lock:
            if len(self._scene_cache) > 8:
                self._scene_cache.clear()
            self._scene_cache[key] = (scene, img, zbuf, small)
        return img, zbuf, small

    def _noise_bank(self, cam: int) -> np.ndarray:
        """Gaussian sensor noise around 128 (uint8), larger than an image; frames use random
        crops of it, which is much cheaper than drawing fresh noise for every pixel."""
        bank = self._noise.get(cam)
        if bank is None:
            w, h = self.config.image_size
            rng = np.random.default_rng(self.seed * 31 + cam + 99)
            noise = rng.standard_normal((h + _NOISE_PAD, w + _NOISE_PAD, 3)) * self.config.noise_sigma
            bank = np.clip(np.rint(noise + 128.0), 0, 255).astype(np.uint8)
            self._noise[cam] = bank
        return bank

    def _render_camera(self, cam: int, pose: BoardPose | None, scene: Scene | None,
                       rng: np.random.Generator) -> np.ndarray:
        s = self.config.supersample
        w, h = self.config.image_size
        bg, zb, small = self._background(cam, scene)
        out = small.copy()
        if pose is not None:
            plane = self._board_plane(pose)
            box = self._bbox(cam, plane)
            if box is not None:
                # work only on the board's box, aligned to whole pixels
                x0, y0 = box[0] // s * s, box[1] // s * s
                x1, y1 = min(w * s, -(-box[2] // s) * s), min(h * s, -(-box[3] // s) * s)
                crop = bg[y0:y1, x0:x1].copy()
                zcrop = zb[y0:y1, x0:x1].copy() if scene is not None else None
                tex, texel = _board_texture(*self.config.board.pattern_size,
                                            float(self.config.board.square_mm))
                self._draw_plane(cam, plane, tex, texel, crop, zcrop, box0=(x0, y0))
                part = crop if s == 1 else cv2.resize(crop, ((x1 - x0) // s, (y1 - y0) // s),
                                                      interpolation=cv2.INTER_AREA)
                out[y0 // s:y1 // s, x0 // s:x1 // s] = part
        gain = 1.0 if cam == 0 else float(self.config.gain_right)
        if self.config.noise_sigma > 0:
            dx, dy = (int(v) for v in rng.integers(0, _NOISE_PAD + 1, 2))
            noise = self._noise_bank(cam)[dy:dy + h, dx:dx + w]
            return cv2.addWeighted(out, gain, noise, 1.0, -128.0, dtype=cv2.CV_8U)
        return cv2.convertScaleAbs(out, alpha=gain)

    def _render(self, pose: BoardPose | None, scene: Scene | None, rng) -> tuple[np.ndarray, np.ndarray]:
        rng = rng if rng is not None else np.random.default_rng()
        return self._render_camera(0, pose, scene, rng), self._render_camera(1, pose, scene, rng)

    def render_board_pair(self, pose: BoardPose, rng=None, scene: Scene | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
        """Left and right BGR uint8 (h, w, 3) images of the board at `pose` (optionally in front
        of a scene)."""
        return self._render(pose, scene, rng)

    def calibration_set(self, n_pairs: int, seed: int | None = None
                        ) -> list[tuple[np.ndarray, np.ndarray]]:
        """`n_pairs` rendered board pairs at varied poses (deterministic for the rig's seed)."""
        rng = np.random.default_rng(self.seed * 104729 + 5 if seed is None else seed)
        return [self.render_board_pair(p, rng) for p in self.board_poses(n_pairs, seed)]

    def render_scene(self, scene: Scene, rng=None) -> tuple[np.ndarray, np.ndarray]:
        """Left and right BGR uint8 images of a scene."""
        return self._render(None, scene, rng)

    # ---- ground truth for the pipeline --------------------------------------------------
    def true_calibration(self, alpha: float = 0.0) -> StereoCalibration:
        """The calibration a perfect calibration would find (Bouguet rectification)."""
        t = self.truth
        size = tuple(int(v) for v in t.image_size)
        R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(t.M1, t.D1, t.M2, t.D2, size, t.R, t.T,
                                                    flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
        tx = t.T.reshape(3)
        Tx = np.array([[0, -tx[2], tx[1]], [tx[2], 0, -tx[0]], [-tx[1], tx[0], 0]], np.float64)
        E = Tx @ t.R
        F = np.linalg.inv(t.M2).T @ E @ np.linalg.inv(t.M1)
        F = F / F[2, 2]
        return StereoCalibration(size, t.M1.copy(), t.D1.copy(), t.M2.copy(), t.D2.copy(),
                                 t.R.copy(), t.T.copy(), E, F, R1, R2, P1, P2, Q, board=t.board,
                                 rms_left=0.0, rms_right=0.0, rms_stereo=0.0,
                                 epipolar_error_px=0.0, method="bouguet", alpha=float(alpha))

    def true_point_rectified(self, calib: StereoCalibration, scene: Scene, x: float, y: float
                             ) -> np.ndarray | None:
        """True (X, Y, Z) mm in the left rectified frame of `calib` seen at rectified pixel
        (x, y), or None if the ray hits nothing."""
        ray_rect = np.linalg.inv(np.asarray(calib.P1, np.float64)[:, :3]) @ np.array([x, y, 1.0])
        R1 = np.asarray(calib.R1, np.float64)
        ray_left = R1.T @ ray_rect
        ray_left /= np.linalg.norm(ray_left)
        t = scene.depth_along_ray(np.zeros(3), ray_left)
        if t is None:
            return None
        return R1 @ (t * ray_left)


# ---------------------------------------------------------------------------------------------
# calibration sets on disk
# ---------------------------------------------------------------------------------------------
SCENE_WALL_DISTANCES_MM = (500.0, 1000.0, 1500.0, 2000.0, 3000.0)
# scene pairs go into a subfolder so that calibrating OUT_DIR does not take them for board pairs
SCENE_FOLDER = "scenes"


def calibration_set_names(n_pairs: int, scene: bool) -> list[str]:
    """The file names write_calibration_set writes for these arguments."""
    names = [f"chessboard-{side}{n}.png" for n in range(1, n_pairs + 1) for side in "LR"]
    if scene:
        names += [f"{SCENE_FOLDER}/scene-{side}{k}.png"
                  for k in range(1, len(SCENE_WALL_DISTANCES_MM) + 2) for side in "LR"]
    return names + ["truth.json"]


def write_calibration_set(out_dir, n_pairs: int = 20, seed: int = 0, scene: bool = False,
                          config: RigConfig | None = None, progress=None) -> Path:
    """Write a calibration set in the report's naming plus truth.json; return the folder.

    chessboard-L{n}.png / chessboard-R{n}.png for n = 1..n_pairs; with `scene`, also
    scenes/scene-L{k}.png / scenes/scene-R{k}.png for walls at SCENE_WALL_DISTANCES_MM and the
    demo scene, with their true distances in truth.json (paths relative to the folder).
    `progress(done, total)` is called after each pair. Every file is written atomically.
    """
    out = Path(out_dir)
    if n_pairs < 0:
        raise InputError(f"number of pairs must not be negative, not {n_pairs}")
    rig = SimRig(config, seed=seed)
    poses = rig.board_poses(n_pairs)
    rng = np.random.default_rng(seed * 104729 + 5)
    scenes = ([Scene.wall(d) for d in SCENE_WALL_DISTANCES_MM] + [Scene.demo()]) if scene else []
    total = len(poses) + len(scenes)
    pairs = []
    for n, pose in enumerate(poses, start=1):
        left, right = rig.render_board_pair(pose, rng)
        lname, rname = f"chessboard-L{n}.png", f"chessboard-R{n}.png"
        write_image_atomic(out / lname, left)
        write_image_atomic(out / rname, right)
        pairs.append({"n": n, "left": lname, "right": rname, **pose.to_json()})
        if progress:
            progress(n, total)
    scene_entries = []
    for k, sc in enumerate(scenes, start=1):
        left, right = rig.render_scene(sc, rng)
        lname, rname = f"{SCENE_FOLDER}/scene-L{k}.png", f"{SCENE_FOLDER}/scene-R{k}.png"
        (out / SCENE_FOLDER).mkdir(exist_ok=True)
        write_image_atomic(out / lname, left)
        write_image_atomic(out / rname, right)
        entry = {"name": sc.name, "left": lname, "right": rname}
        if len(sc.objects) == 1:
            entry["distance_mm"] = float(sc.objects[0].center[2])
        else:
            entry["objects"] = [o.to_json() for o in sc.objects]
        scene_entries.append(entry)
        if progress:
            progress(len(poses) + k, total)
    data = rig.truth.to_json()
    data.update({"seed": int(seed), "generator": "stereo_gui.sources.sim",
                 "noise_sigma": rig.config.noise_sigma, "gain_right": rig.config.gain_right,
                 "pairs": pairs})
    if scene:
        data["scenes"] = scene_entries
    write_json_atomic(out / "truth.json", data)
    return out


# ---------------------------------------------------------------------------------------------
# the live source
# ---------------------------------------------------------------------------------------------
def _interpolate_pose(p0: BoardPose, p1: BoardPose, f: float) -> BoardPose:
    """Pose a fraction f of the way from p0 to p1 (rotation along the shortest arc)."""
    dR = p1.R @ p0.R.T
    rvec = cv2.Rodrigues(dR)[0] * f
    R = cv2.Rodrigues(rvec)[0] @ p0.R
    return BoardPose(R, (1 - f) * p0.t + f * p1.t)


class SimSource:
    """The simulated rig as a live frame source.

    mode "board": a board moving smoothly between poses in front of a plain background;
    "scene": the demo scene alone; "mixed": the board moving in front of the demo scene.
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
            self._from = self._to or self.rig.random_board_pose(self._pose_rng)
            self._to = self.rig.random_board_pose(self._pose_rng)
        f = k / self._frames_per_move
        f = f * f * (3 - 2 * f)  # ease in and out: the board rests a moment at each pose
        return _interpolate_pose(self._from, self._to, f)

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
