"""Exports of one frame's depth: disparity as 16-bit PNG (OpenCV's x16 fixed point) and float32
.npy, depth in millimetres as 16-bit PNG, and a coloured point cloud as binary PLY.

Input disparities are float32 px of the rectified left image with NaN where invalid (what
`PipelineResult.final_px` holds). Every write is atomic.
"""

from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.disparity import DISP_SCALE
from stereo_gui.core.errors import InputError
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.atomic import AtomicItem, StrPath, encode_image, write_bytes_atomic

UINT16_MAX = np.iinfo(np.uint16).max


def _check(disparity_px: np.ndarray) -> np.ndarray:
    d = np.asarray(disparity_px)
    if d.ndim != 2 or not np.issubdtype(d.dtype, np.floating):
        raise InputError("a disparity map must be a 2-D float array (px, NaN invalid)")
    return d.astype(np.float32, copy=False)


def disparity_to_png16(disparity_px: np.ndarray) -> np.ndarray:
    """uint16 disparity x16 (OpenCV's fixed point); 0 = invalid or not representable."""
    d = _check(disparity_px)
    fixed = np.rint(np.nan_to_num(d, nan=0.0) * DISP_SCALE)
    ok = np.isfinite(d) & (fixed > 0) & (fixed <= UINT16_MAX)
    return np.where(ok, fixed, 0).astype(np.uint16)


def _checked(disparity_px: np.ndarray, calibration: StereoCalibration) -> np.ndarray:
    d = _check(disparity_px)
    if not calibration.metric:
        raise InputError("this calibration has no metric scale (Hartley's method): depth and point "
                         "clouds in millimetres need a calibration made with a chessboard")
    if (d.shape[1], d.shape[0]) != tuple(calibration.image_size):
        raise InputError(f"the disparity map is {d.shape[1]}x{d.shape[0]} but the calibration is "
                         f"for {calibration.width}x{calibration.height}")
    return d


def points_mm(disparity_px: np.ndarray, calibration: StereoCalibration) -> np.ndarray:
    """(H, W, 3) float32 X, Y, Z in mm (left rectified frame) through Q; NaN where invalid."""
    d = _checked(disparity_px, calibration)
    xyz = cv2.reprojectImageTo3D(np.nan_to_num(d, nan=0.0), np.asarray(calibration.Q, np.float64))
    bad = ~np.isfinite(d) | ~np.all(np.isfinite(xyz), axis=2) | (xyz[..., 2] <= 0)
    xyz[bad] = np.nan
    return xyz


def depth_mm(disparity_px: np.ndarray, calibration: StereoCalibration) -> np.ndarray:
    """(H, W) float32 depth Z in mm; NaN where invalid. Z depends on the disparity alone (Q's
    last two rows): computed from it directly, a tenth of a full reprojection's time (the depth
    stream makes it at every frame)."""
    d = _checked(disparity_px, calibration)
    q = np.asarray(calibration.Q, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.float32(q[2, 3]) / (d * np.float32(q[3, 2]) + np.float32(q[3, 3]))
    z[~(z > 0) | ~np.isfinite(z)] = np.nan
    return z


def depth_to_png16(depth: np.ndarray) -> np.ndarray:
    """uint16 depth in whole mm; 0 = invalid or beyond 65.535 m."""
    mm = np.rint(np.nan_to_num(depth, nan=0.0))
    ok = np.isfinite(depth) & (mm > 0) & (mm <= UINT16_MAX)
    return np.where(ok, mm, 0).astype(np.uint16)


# Each export is made as an item (path, bytes, verify or None) that files.atomic writes: alone
# (the write_* functions) or with others as one set (write_many_atomic), all or none.
def _png16_item(path: StrPath, image: np.ndarray) -> AtomicItem:
    if Path(path).suffix.lower() != ".png":
        raise InputError(f"{path}: a 16-bit image must be written as .png")
    return (path, encode_image(path, image), None)


def disparity_png16_item(path: StrPath, disparity_px: np.ndarray) -> AtomicItem:
    return _png16_item(path, disparity_to_png16(disparity_px))


def write_disparity_png16(path: StrPath, disparity_px: np.ndarray) -> Path:
    return write_bytes_atomic(*disparity_png16_item(path, disparity_px))


def disparity_npy_item(path: StrPath, disparity_px: np.ndarray) -> AtomicItem:
    d = _check(disparity_px)
    buf = io.BytesIO()
    np.save(buf, d.astype(np.float32))
    expected = d.shape

    def verify(tmp: Path) -> None:
        back = np.load(tmp, allow_pickle=False)
        if back.shape != expected or back.dtype != np.float32:
            raise ValueError(f"it holds {back.dtype} {back.shape}, not float32 {expected}")

    return (path, buf.getvalue(), verify)


def write_disparity_npy(path: StrPath, disparity_px: np.ndarray) -> Path:
    return write_bytes_atomic(*disparity_npy_item(path, disparity_px))


def depth_png16_item(path: StrPath, disparity_px: np.ndarray,
                     calibration: StereoCalibration) -> AtomicItem:
    return _png16_item(path, depth_to_png16(depth_mm(disparity_px, calibration)))


def write_depth_png16(path: StrPath, disparity_px: np.ndarray,
                      calibration: StereoCalibration) -> Path:
    return write_bytes_atomic(*depth_png16_item(path, disparity_px, calibration))


def write_ply(path: StrPath, disparity_px: np.ndarray, color_bgr: np.ndarray,
              calibration: StereoCalibration) -> int:
    """Binary little-endian PLY of the valid points: x y z (float32 mm), red green blue (uchar).

    `color_bgr` is an image of the same size (e.g. the rectified left image). Returns the number
    of points written.
    """
    item, n = ply_item(path, disparity_px, color_bgr, calibration)
    write_bytes_atomic(*item)  # size and bytes checked there
    return n


def ply_item(path: StrPath, disparity_px: np.ndarray, color_bgr: np.ndarray,
             calibration: StereoCalibration) -> tuple[AtomicItem, int]:
    """(the PLY's item, the number of points in it); see write_ply."""
    xyz = points_mm(disparity_px, calibration)
    color = np.asarray(color_bgr)
    if color.shape[:2] != xyz.shape[:2]:
        raise InputError("the colour image and the disparity map differ in size")
    if color.ndim == 2:
        color = np.repeat(color[..., None], 3, axis=2)
    valid = np.all(np.isfinite(xyz), axis=2)
    n = int(valid.sum())
    vertex = np.empty(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    pts = xyz[valid]
    bgr = color[valid][:, :3].astype(np.uint8)
    vertex["x"], vertex["y"], vertex["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    vertex["red"], vertex["green"], vertex["blue"] = bgr[:, 2], bgr[:, 1], bgr[:, 0]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment stereo-gui point cloud, millimetres, left rectified camera frame\n"
        f"element vertex {n}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        "end_header\n"
    ).encode("ascii")
    return (path, header + vertex.tobytes(), None), n


__all__ = [
    "disparity_to_png16", "points_mm", "depth_mm", "depth_to_png16", "write_disparity_png16",
    "write_disparity_npy", "write_depth_png16", "write_ply", "disparity_png16_item",
    "disparity_npy_item", "depth_png16_item", "ply_item",
]
