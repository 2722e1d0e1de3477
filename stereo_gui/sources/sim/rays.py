"""Ray maps (cached: they are the expensive, per-rig part): for every supersample of every
output pixel, the normalised undistorted ray (x, y, 1) obtained by inverting OpenCV's
distortion model of the camera's lens model (checked against its projection)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.lens import project_points, undistort_points
from stereo_gui.sources.sim.camera import CameraTruth


def _distort(x: np.ndarray, y: np.ndarray, D: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
def _ray_map_cached(M_bytes: bytes, D_bytes: bytes, model: str, w: int, h: int, s: int) -> RayMap:
    M = np.frombuffer(M_bytes, np.float64).reshape(3, 3)
    D = np.frombuffer(D_bytes, np.float64).reshape(1, -1)
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
    if model == "fisheye":
        grid = undistort_points(model, np.stack([gu, gv], -1).reshape(-1, 2), M, D)
    else:
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
    proj = project_points(model, pts, np.zeros(3), np.zeros(3), M, D)
    err = np.hypot(proj[:, 0] - uu.ravel(), proj[:, 1] - vv.ravel())
    max_err = float(err.max())
    if max_err > 1e-3:
        raise RuntimeError(f"distortion inversion failed: round trip error {max_err:.2e} px")
    return RayMap(np.ascontiguousarray(xy, dtype=np.float32), s, max_err)


def ray_map(cam: CameraTruth, image_size: tuple[int, int], supersample: int) -> RayMap:
    """The (cached) ray map of one camera."""
    return _ray_map_cached(np.ascontiguousarray(cam.M).tobytes(),
                           np.ascontiguousarray(cam.D.reshape(1, -1)).tobytes(), cam.model,
                           int(image_size[0]), int(image_size[1]), int(supersample))
