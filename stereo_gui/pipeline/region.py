"""A region of the live view watched frame by frame, without Qt: the nearest and the median
distance in it, how much of it has depth, and an alarm when anything in it is nearer than a set
distance (the robot's own question: is anything too close?).

The distances come from the frame's final disparity (the confident WLS output the colour view
shows) through the calibration's Q matrix, or through the active fit. "Nearest" is the 1st
percentile of the region's distances, so that a single stray pixel neither raises nor hides an
alarm; with fewer than MIN_PIXELS pixels of depth nothing is said.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.regression import FitResult

NEAREST_PERCENTILE = 1.0
MIN_PIXELS = 20


@dataclass(frozen=True)
class Region:
    """A box of the rectified left image: columns x0 .. x1-1, rows y0 .. y1-1 (px)."""

    x0: int
    y0: int
    x1: int
    y1: int

    def clipped(self, width: int, height: int) -> Region | None:
        """The part inside a width x height image, None when nothing is."""
        x0, x1 = max(0, min(self.x0, self.x1)), min(width, max(self.x0, self.x1))
        y0, y1 = max(0, min(self.y0, self.y1)), min(height, max(self.y0, self.y1))
        return Region(x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


@dataclass(frozen=True)
class RegionStats:
    """What the region shows in one frame. Distances (Z) in mm; NaN when `note` says why not.

    `alarm` is True when `nearest_mm` is below `alarm_mm` (None: no alarm set)."""

    region: Region
    nearest_mm: float = math.nan
    median_mm: float = math.nan
    valid_fraction: float = 0.0
    pixels: int = 0
    alarm_mm: float | None = None
    alarm: bool = False
    note: str = ""


def region_stats(result: PipelineResult, region: Region, alarm_mm: float | None = None,
                 fit: FitResult | None = None) -> RegionStats:
    """The distances in `region` of `result`'s final disparity (see the module docstring)."""
    disp = result.final_px
    h, w = disp.shape[:2]
    box = region.clipped(w, h)
    if box is None:
        return RegionStats(region, alarm_mm=alarm_mm, note="outside the image")
    d = disp[box.y0:box.y1, box.x0:box.x1].astype(np.float64)
    total = d.size
    with np.errstate(invalid="ignore", divide="ignore"):
        if fit is not None:
            lo, hi = fit.disparity_span
            z = np.where((d >= lo) & (d <= hi), np.asarray(fit.predict(d), np.float64), np.nan)
        else:
            calib = result.calibration
            if calib is None or not calib.metric:
                return RegionStats(box, alarm_mm=alarm_mm,
                                   note="no metric scale: fit a regression first")
            q = np.asarray(calib.Q, np.float64)
            z = q[2, 3] / (q[3, 2] * d + q[3, 3])
    good = np.isfinite(z) & (z > 0)
    n = int(good.sum())
    if n < MIN_PIXELS:
        return RegionStats(box, valid_fraction=n / total, pixels=n, alarm_mm=alarm_mm,
                           note="too little depth in the region")
    zs = z[good]
    nearest = float(np.percentile(zs, NEAREST_PERCENTILE))
    alarm = alarm_mm is not None and alarm_mm > 0 and nearest < alarm_mm
    return RegionStats(box, nearest, float(np.median(zs)), n / total, n, alarm_mm, bool(alarm))
