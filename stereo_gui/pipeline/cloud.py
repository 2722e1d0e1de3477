"""The point cloud of a frame for the 3D view, without Qt: every `step`-th pixel of the final
(confident) disparity reprojected through Q, coloured from the image or by distance (on the
frame's colour scale, as the depth view).

Display coordinates: metres, x = X (right), y = Z (ahead), z = -Y (up), so that the view's
"up" is the scene's up and the camera sits at the origin looking along +y.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.preset import COLORMAPS
from stereo_gui.core.stereo_calibration import StereoCalibration

COLOURINGS = ("image", "distance")
MAX_POINTS = 120_000  # what the view draws at interactive rates on a small machine
IMAGE_BACKGROUND_RGB = (32, 32, 32)  # behind points coloured from the image


def distance_background_rgb(colormap: str) -> tuple[int, int, int]:
    """The grey behind points coloured by distance with `colormap`: the one farthest from
    every colour of the map, so that no distance vanishes into it (OCEAN's far end is black:
    on the dark grey of the image colouring the farthest points could not be seen)."""
    cmap = COLORMAPS.get(colormap, cv2.COLORMAP_OCEAN)
    ramp = np.arange(256, dtype=np.uint8).reshape(256, 1)
    lut = cv2.applyColorMap(ramp, cmap).reshape(256, 3).astype(np.float64)
    greys = np.arange(0, 256, 2, dtype=np.float64)
    nearest = np.linalg.norm(lut[None, :, :] - greys[:, None, None], axis=2).min(axis=1)
    g = int(greys[int(np.argmax(nearest))])
    return (g, g, g)


@dataclass(frozen=True, eq=False)
class CloudPoints:
    """Points (N x 3 float32, m, display coordinates: see the module docstring) with colours
    (N x 4 float32 RGBA, 0..1), the depth range they span (m), and the background (RGB 0..255)
    every colour of theirs stands out from."""

    xyz_m: np.ndarray
    rgba: np.ndarray
    z_near_m: float
    z_far_m: float
    background_rgb: tuple[int, int, int] = IMAGE_BACKGROUND_RGB

    @property
    def count(self) -> int:
        return int(self.xyz_m.shape[0])


def reproject_every(disparity_px: np.ndarray, calibration: StereoCalibration, step: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every `step`-th pixel of a disparity map (px, NaN invalid) through Q: (its disparities
    (rows x cols float32), (N, 3) float64 X, Y, Z mm in the left rectified camera, N bools of
    the points in front of the camera). The 3D view and the depth stream's cloud share it."""
    h, w = disparity_px.shape[:2]
    d = np.ascontiguousarray(disparity_px[::step, ::step], np.float32)
    ys, xs = np.mgrid[0:h:step, 0:w:step]
    q = np.asarray(calibration.Q, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        hom = (q @ np.stack([xs.ravel(), ys.ravel(), d.ravel().astype(np.float64),
                             np.ones(d.size)]))
        xyz = (hom[:3] / hom[3]).T
    good = np.isfinite(d.ravel()) & np.all(np.isfinite(xyz), axis=1) & (xyz[:, 2] > 0)
    return d, xyz, good


def cloud_points(result: PipelineResult, colouring: str = "image", step: int = 2
                 ) -> CloudPoints:
    """The frame's point cloud (InputError for a calibration without metric scale)."""
    if colouring not in COLOURINGS:
        raise InputError(f"colouring must be one of {', '.join(COLOURINGS)}, not {colouring!r}")
    calib = result.calibration
    if calib is None or not calib.metric:
        raise InputError("a point cloud in metres needs a calibration with a metric scale")
    step = max(1, int(step))
    disp = result.final_px
    h, w = disp.shape[:2]
    while (h // step) * (w // step) > MAX_POINTS:
        step += 1
    d, xyz, good = reproject_every(disp, calib, step)
    xyz = xyz[good] / 1000.0
    pts = np.column_stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]]).astype(np.float32)
    z = xyz[:, 2]
    near, far = (float(np.percentile(z, 1)), float(np.percentile(z, 99))) if z.size else \
        (0.0, 0.0)
    if colouring == "image":
        img = result.rectified_left[::step, ::step]
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=2)
        rgb = img.reshape(-1, img.shape[2])[good][:, 2::-1]
    else:  # near bright, on the colours of the depth view (the scale its legend shows)
        if result.color_scale is not None:
            level = result.color_scale.level(d.ravel()[good])
        else:
            level = 255.0 * (far - z) / max(far - near, 1e-6)
        level = np.clip(np.rint(level), 0, 255).astype(np.uint8).reshape(-1, 1)
        cmap = COLORMAPS.get(result.preset.display.colormap, cv2.COLORMAP_OCEAN)
        rgb = cv2.applyColorMap(level, cmap).reshape(-1, 3)[:, ::-1]
    rgba = np.empty((pts.shape[0], 4), np.float32)
    rgba[:, :3] = rgb.astype(np.float32) / 255.0
    rgba[:, 3] = 1.0
    background = (IMAGE_BACKGROUND_RGB if colouring == "image" else
                  distance_background_rgb(result.preset.display.colormap))
    return CloudPoints(pts, rgba, near, far, background)
