"""The Live tab's frame processor: the frame worker runs `LiveProcessor` on every frame.

It runs the pipeline (rectify, SGBM, closing, WLS, colour map) and converts each view into a
displayable uint8 image, so the UI thread only hands arrays to pyqtgraph. No Qt here.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.matching import (NO_MATCH_BGR, NOT_SEEN_BGR, MatcherParams, PipelineResult,
                                     StereoPipeline, paint)
from stereo_gui.core.health import CalibrationHealth
from stereo_gui.pipeline.health import HealthMonitor
from stereo_gui.pipeline.images import display_rgb
from stereo_gui.pipeline.region import Region, RegionStats, region_stats
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

# pixels without depth get colours of their own (black means "far" in OCEAN and the gray views),
# the same in every view and in `disparity -o`: no match, and not seen by the right camera
NO_MATCH_RGB = NO_MATCH_BGR[::-1]
NOT_SEEN_RGB = NOT_SEEN_BGR[::-1]


@dataclass(frozen=True, eq=False)
class LiveOutput:
    """What the processor hands to the UI: the pipeline result and each view as uint8 (RGB or
    gray), plus the disparity (px) mapped to colour levels 0 and 255 of the colour view."""

    result: PipelineResult
    images: dict[str, np.ndarray]
    scale_note: str = ""  # says so when the calibration was scaled to the source's frame size
    region: RegionStats | None = None  # the watched region of this frame (set_region)
    health: CalibrationHealth | None = None  # the newest calibration-health figure (pipeline.health)


VIEW_KEYS = ("left", "right", "raw", "closed", "wls")  # the images a LiveOutput can hold
DEFAULT_VIEWS = ("left", "raw", "closed", "wls")  # what the Live tab shows at first


def _gray_disparity(disp_px: np.ndarray, lo: float, hi: float,
                    not_seen: np.ndarray | None = None) -> np.ndarray:
    """Disparity (px, NaN invalid) as RGB uint8: gray, near bright; invalid NO_MATCH_RGB, the
    strip the right camera cannot see NOT_SEEN_RGB."""
    span = max(hi - lo, 1e-6)
    invalid = cv2.bitwise_not(cv2.compare(disp_px, disp_px, cv2.CMP_EQ))  # 255 where NaN
    gray = cv2.convertScaleAbs(disp_px, alpha=255.0 / span, beta=-lo * 255.0 / span)
    rgb = cv2.cvtColor(gray, cv2.COLOR_GRAY2RGB)
    paint(rgb, invalid, NO_MATCH_RGB)
    if not_seen is not None:
        paint(rgb, not_seen, NOT_SEEN_RGB)
    return rgb


class LiveProcessor:
    """The frame worker's processor for the Live tab (called in the worker thread only).

    The pipeline is built on the first frame, in the worker thread (building rectification maps
    takes a while); `set_params` may be called from any thread and applies to the next frame.
    Frames of another size than the calibration's use `StereoCalibration.scaled_to` (same aspect
    ratio: `LiveOutput.scale_note` says so); another aspect ratio raises CalibrationError with
    the reason, for every frame, so it is never silently wrong.
    """

    def __init__(self, calibration, params: MatcherParams) -> None:
        self.calibration = calibration
        self._lock = threading.Lock()
        self._params = params
        self._pipeline: StereoPipeline | None = None
        self._size: tuple[int, int] | None = None  # frame size the pipeline was built for
        self._note = ""
        self._region: tuple[Region, float | None, object] | None = None
        self._views: frozenset[str] = frozenset(VIEW_KEYS)
        self.health = HealthMonitor()  # about once a second, in a thread of its own

    def set_views(self, keys) -> None:
        """Make display images only of the views in `keys` (any thread; the next frame): the
        others cost time and nobody sees them. The right image is rectified in colour only
        when its view is shown (gray is all the matcher needs)."""
        keys = frozenset(keys) & frozenset(VIEW_KEYS)
        with self._lock:
            self._views = keys

    def set_params(self, params: MatcherParams) -> None:
        with self._lock:
            self._params = params
            if self._pipeline is not None:
                self._pipeline.set_params(params)

    def set_region(self, region: Region | None, alarm_mm: float | None = None,
                   fit=None) -> None:
        """Watch `region` (None: no region) from the next frame on: its distances through
        `fit` (a FitResult, None: triangulation) and an alarm below `alarm_mm` (any thread)."""
        with self._lock:
            self._region = None if region is None else (region, alarm_mm, fit)

    def __call__(self, frame: StereoFrame) -> LiveOutput:
        size = (int(frame.left.shape[1]), int(frame.left.shape[0]))
        with self._lock:
            if self._pipeline is None or self._size != size:
                if self._pipeline is not None:
                    self._pipeline.close()
                    self._pipeline = None
                calib = self.calibration.scaled_to(size)  # CalibrationError: another aspect
                self._pipeline = StereoPipeline(calib, self._params)
                self._size = size
                c = self.calibration
                self._note = ("" if calib is c else
                              f"Calibration made at {c.width}x{c.height} px, scaled to the "
                              f"source's {size[0]}x{size[1]} px (same aspect ratio)")
                if self._note:
                    log.info("%s", self._note)
            pipeline, note, watched = self._pipeline, self._note, self._region
            views = self._views
        r = pipeline.process(*self.calibration.ordered(frame.left, frame.right),
                             right_colour="right" in views)
        lo, hi = r.disparity_range_px
        make = {
            "left": lambda: display_rgb(r.rectified_left),
            "right": lambda: display_rgb(r.rectified_right),
            "raw": lambda: _gray_disparity(r.disparity_px, lo, hi, r.not_seen),
            "closed": lambda: _gray_disparity(r.closed_px, lo, hi, r.not_seen),
            "wls": lambda: cv2.cvtColor(r.color_bgr, cv2.COLOR_BGR2RGB),  # (painted by colorize)
        }
        images = {key: make[key]() for key in VIEW_KEYS if key in views}
        stats = None if watched is None else region_stats(r, *watched)
        if r.rectified_left is not None and r.rectified_right is not None:
            self.health.offer(r.rectified_left, r.rectified_right)
        return LiveOutput(r, images, note, stats, self.health.latest())

    def close(self) -> None:
        self.health.close()
        with self._lock:
            if self._pipeline is not None:
                self._pipeline.close()

