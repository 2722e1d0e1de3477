"""The Live tab's frame processor: the frame worker runs `LiveProcessor` on every frame.

It runs the pipeline (rectify, SGBM, closing, WLS, colour map) and converts each view into a
displayable uint8 image, so the UI thread only hands arrays to pyqtgraph. No Qt here.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from stereo_gui.core.colouring import NO_MATCH_BGR, NOT_SEEN_BGR, ColorScale, colorize, paint
from stereo_gui.core.health import CalibrationHealth
from stereo_gui.core.matching import PipelineResult, StereoPipeline
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.concurrency import lanes_for, use_preset_threads
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


VIEW_KEYS = ("left", "right", "raw", "closed", "depth", "wls")  # the images a LiveOutput can hold
DEFAULT_VIEWS = ("left", "raw", "depth", "wls")  # what the Live tab shows at first


def _gray_disparity(disp_px: np.ndarray, lo: float, hi: float,
                    not_seen: np.ndarray | None = None, not_seen_cols: int | None = None
                    ) -> np.ndarray:
    """Disparity (px, NaN invalid) as RGB uint8: gray, near bright; invalid NO_MATCH_RGB, the
    strip the right camera cannot see NOT_SEEN_RGB (`not_seen`, set only in the leftmost
    `not_seen_cols` columns if given)."""
    span = max(hi - lo, 1e-6)
    invalid = cv2.bitwise_not(cv2.compare(disp_px, disp_px, cv2.CMP_EQ))  # 255 where NaN
    gray = cv2.convertScaleAbs(disp_px, alpha=255.0 / span, beta=-lo * 255.0 / span)
    rgb = cv2.cvtColor(gray, cv2.COLOR_GRAY2RGB)
    paint(rgb, invalid, NO_MATCH_RGB)
    if not_seen is not None:
        paint(rgb, not_seen, NOT_SEEN_RGB, not_seen_cols)
    return rgb


def _wls_picture(r: PipelineResult) -> np.ndarray:
    """The WLS view as RGB uint8: the filter's output on the depth view's colour scale (the
    depth view itself when the filter's output is the final map or there is none)."""
    if r.wls_px is None or r.wls_px is r.final_px or r.color_scale is None:
        return cv2.cvtColor(r.color_bgr, cv2.COLOR_BGR2RGB)
    bgr = colorize(r.wls_px, r.color_scale, r.preset.display.colormap, r.not_seen,
                   r.not_seen_cols)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def frame_lanes(params: Preset | MatcherParams, cpus: int | None = None) -> int:
    """How many frames the Live tab processes at once for `params` (pipeline.concurrency)."""
    return lanes_for(Preset.of(params).threads.parallel, cpus)


class FramePublisher(Protocol):
    """What a processed frame is published on (pipeline.stream.DepthStream)."""

    def publish(self, result: PipelineResult, t_capture_s: float,
                region: RegionStats | None = None,
                health: CalibrationHealth | None = None) -> None: ...


# the watched region: (region, alarm below mm or None, the fit its distances go through or None)
Watched = tuple[Region, float | None, FitResult | None]


def _publish(stream: FramePublisher, out: LiveOutput, frame: StereoFrame, said: set[str]
             ) -> None:
    """Publish a processed frame; a failure is logged (each reason once, not at 30 frames a
    second), never the frame's: the view goes on."""
    try:
        stream.publish(out.result, frame.t_left, region=out.region, health=out.health)
    except Exception as exc:  # noqa: BLE001 - the stream's trouble must not stop the view
        if str(exc) not in said:
            said.add(str(exc))
            log.warning("the depth stream could not publish frame %d: %s", frame.index, exc)


class LiveProcessor:
    """The frame worker's processor for the Live tab (called in the worker's threads only).

    `lanes` frames may be processed at once, each by a thread of its own (`frame_lanes`): every
    call takes a pipeline of its own from a small pool, made on the call that first needs it, in
    the worker thread (building rectification maps takes a while). The pipelines themselves run
    one frame's stages one after the other (a `parallel` preset's parallelism is the lanes).
    `set_params` may be called from any thread and applies to the next frame. Frames of another
    size than the calibration's use `StereoCalibration.scaled_to` (same aspect ratio:
    `LiveOutput.scale_note` says so); another aspect ratio raises CalibrationError with the
    reason, for every frame, so it is never silently wrong.
    """

    def __init__(self, calibration: StereoCalibration, params: Preset | MatcherParams) -> None:
        params = Preset.of(params)
        self.calibration = calibration
        self._lock = threading.Lock()
        self._lane_params = params  # what each lane's pipeline runs
        self._lanes = frame_lanes(params)
        # the parameters whose OpenCV thread count was set (on the first frame they run)
        self._threads_of: Preset | None = None
        self._idle: list[StereoPipeline] = []  # pipelines for frames of self._size, not in use
        self._busy: set[StereoPipeline] = set()
        self._size: tuple[int, int] | None = None  # frame size the pipelines are built for
        self._scaled = calibration  # the calibration scaled to that size
        self._note = ""
        self._closed = False
        self._region: Watched | None = None
        self._views: frozenset[str] = frozenset(VIEW_KEYS)
        self._stream: FramePublisher | None = None  # every frame is published on it
        self._stream_said: set[str] = set()  # why publishing failed, said once each
        # the colour scale of the newest frame processed: a "view" colour range follows the
        # scene from it (core.colouring.color_scale), so its colours do not flicker
        self._color_scale: ColorScale | None = None
        self.health = HealthMonitor()  # every two seconds, in a thread of its own

    @property
    def lanes(self) -> int:
        """How many calls may run at once (the Live tab gives it to the frame worker with the
        processor)."""
        with self._lock:
            return self._lanes

    def set_views(self, keys: Iterable[str]) -> None:
        """Make display images only of the views in `keys` (any thread; the next frame): the
        others cost time and nobody sees them. The right image is rectified in colour only
        when its view is shown (gray is all the matcher needs)."""
        shown = frozenset(keys) & frozenset(VIEW_KEYS)
        with self._lock:
            self._views = shown

    def set_params(self, params: Preset | MatcherParams) -> None:
        params = Preset.of(params)
        with self._lock:
            self._lane_params = lane = params
            self._lanes = frame_lanes(params)
            for pipeline in (*self._idle, *self._busy):
                pipeline.set_params(lane)

    def set_stream(self, stream: FramePublisher | None) -> None:
        """Publish every frame from the next on with `stream` (a pipeline.stream.DepthStream;
        None: stop), in the lane that processed it (any thread)."""
        with self._lock:
            self._stream = stream

    def set_region(self, region: Region | None, alarm_mm: float | None = None,
                   fit: FitResult | None = None) -> None:
        """Watch `region` (None: no region) from the next frame on: its distances through
        `fit` (a FitResult, None: triangulation) and an alarm below `alarm_mm` (any thread)."""
        with self._lock:
            self._region = None if region is None else (region, alarm_mm, fit)

    def _take_pipeline(self, size: tuple[int, int]) -> StereoPipeline:
        """A pipeline for frames of `size`, not in use by another call (made if none is idle)."""
        with self._lock:
            if self._closed:
                raise RuntimeError("the live processor is closed")
            if self._size != size:
                stale, self._idle = self._idle, []
                calib = self.calibration.scaled_to(size)  # CalibrationError: another aspect
                self._size, self._scaled = size, calib
                c = self.calibration
                self._note = ("" if calib is c else
                              f"Calibration made at {c.width}x{c.height} px, scaled to the "
                              f"source's {size[0]}x{size[1]} px (same aspect ratio)")
                if self._note:
                    log.info("%s", self._note)
                for old in stale:
                    old.close()
            if self._idle:
                pipeline = self._idle.pop()
            else:
                pipeline = None
                calib, params = self._scaled, self._lane_params
        if pipeline is None:  # built outside the lock: the other lane goes on meanwhile
            pipeline = StereoPipeline(calib, params)
        with self._lock:
            lane = self._lane_params
            if self._threads_of is not lane:
                self._threads_of = lane
                use_preset_threads(lane)
            # (the same object on every frame but the first after a change: no field-by-field
            # comparison, and no new parameters validated, per frame)
            if pipeline.params is not lane and pipeline.params != lane:
                pipeline.set_params(lane)  # changed while it was built
            self._busy.add(pipeline)
        return pipeline

    def _give_back(self, pipeline: StereoPipeline, size: tuple[int, int]) -> None:
        with self._lock:
            self._busy.discard(pipeline)
            keep = not self._closed and size == self._size
            if keep:
                self._idle.append(pipeline)
        if not keep:
            pipeline.close()

    def __call__(self, frame: StereoFrame) -> LiveOutput:
        size = (int(frame.left.shape[1]), int(frame.left.shape[0]))
        pipeline = self._take_pipeline(size)
        try:
            with self._lock:
                note, watched, views = self._note, self._region, self._views
                previous, stream = self._color_scale, self._stream
            out = self._process(pipeline, frame, note, watched, views, previous)
            with self._lock:
                self._color_scale = out.result.color_scale
            if stream is not None:
                _publish(stream, out, frame, self._stream_said)
            return out
        finally:
            self._give_back(pipeline, size)

    def _process(self, pipeline: StereoPipeline, frame: StereoFrame, note: str,
                 watched: Watched | None, views: frozenset[str], previous: ColorScale | None
                 ) -> LiveOutput:
        r = pipeline.process(*self.calibration.ordered(frame.left, frame.right),
                             right_colour="right" in views, wls="wls" in views,
                             previous_scale=previous)
        lo, hi = r.disparity_range_px
        make: dict[str, Callable[[], np.ndarray]] = {
            "left": lambda: display_rgb(r.rectified_left),
            "right": lambda: display_rgb(r.rectified_right),
            "raw": lambda: _gray_disparity(r.disparity_px, lo, hi, r.not_seen, r.not_seen_cols),
            "closed": lambda: _gray_disparity(r.closed_px, lo, hi, r.not_seen, r.not_seen_cols),
            "depth": lambda: cv2.cvtColor(r.color_bgr, cv2.COLOR_BGR2RGB),  # (painted by colorize)
            "wls": lambda: _wls_picture(r),
        }
        images = {key: make[key]() for key in VIEW_KEYS if key in views}
        stats = None if watched is None else region_stats(r, *watched)
        if r.rectified_left is not None and r.rectified_right is not None:
            self.health.offer(r.rectified_left, r.rectified_right)
        return LiveOutput(r, images, note, stats, self.health.latest())

    def close(self, wait: bool = True) -> None:
        """Close the idle pipelines and the health check (a call still running closes its own
        pipeline when it ends; `wait` for a running health check, see HealthMonitor.close)."""
        self.health.close(wait)
        with self._lock:
            self._closed = True
            idle, self._idle = self._idle, []
        for pipeline in idle:
            pipeline.close()
