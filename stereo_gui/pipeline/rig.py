"""The Python API for a robot's own programs: the window's live pipeline (`LiveProcessor`, the
same preset, calibration and double-click) over any source, frame by frame, without Qt.

    import stereo_gui
    with stereo_gui.open_rig(source="sim", calibration="calib.yaml", preset="live") as rig:
        for frame in rig.frames():           # the newest frame each time; nothing queues up
            frame.depth_mm                   # uint16 millimetres of Z, 0 = no value
            r = frame.measure(320, 240)      # Reading: z_mm, pm_mm (95 %), valid, reason
            frame.nearest(region=(x, y, w, h))

A thread of the rig's own reads the source and keeps only its newest frame; each step of
`frames()` processes the newest one there is, so a program slower than the cameras skips frames
instead of falling behind. Errors are the command line's: InputError, CalibrationFileError,
SourceError (all StereoGuiError), with the message a person reads.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property
from typing import Self

import numpy as np

from stereo_gui.core.errors import InputError, SourceError, StereoGuiError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.measure import PATCH_PX, Measurement, measure_point
from stereo_gui.core.preset import Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.presets import load_preset
from stereo_gui.pipeline.live import LiveOutput, LiveProcessor
from stereo_gui.pipeline.region import Region, RegionStats, region_stats
from stereo_gui.pipeline.stream import depth_image_mm
from stereo_gui.sources.base import FrameSource, StereoFrame
from stereo_gui.sources.open import open_source

log = logging.getLogger(__name__)

READ_TIMEOUT_S = 10.0  # no frame from the source for this long: SourceError


@dataclass(frozen=True)
class Reading:
    """One distance reading at rectified pixel (x, y): Z and the range in mm, its 95 % bound
    `pm_mm`; `valid` False with the `reason` when there is no reading there."""

    x: float
    y: float
    valid: bool
    z_mm: float = math.nan
    range_mm: float = math.nan
    pm_mm: float = math.nan
    reason: str | None = None

    @classmethod
    def of(cls, m: Measurement) -> Reading:
        return cls(m.x, m.y, bool(m.valid), m.Z_mm, m.range_mm, m.expected_error_mm,
                   None if m.reason is None else str(m.reason))

    def __str__(self) -> str:
        if not self.valid:
            return f"({self.x:g}, {self.y:g}): no reading ({self.reason})"
        return f"({self.x:g}, {self.y:g}): {self.z_mm / 1000:.3f} m +- {self.pm_mm:.0f} mm"


@dataclass(frozen=True)
class RegionReading:
    """A box's distances: the nearest (1st percentile) and the median Z in mm, the share of
    its pixels with depth, and whether anything is nearer than the alarm distance. NaN
    distances with a `note` when the box holds too little depth."""

    nearest_mm: float
    median_mm: float
    valid_share: float
    alarm: bool
    note: str = ""

    @classmethod
    def of(cls, s: RegionStats) -> RegionReading:
        return cls(s.nearest_mm, s.median_mm, s.valid_fraction, s.alarm, s.note)


class Frame:
    """One processed frame: the capture time (`t_capture`, seconds of the source's clock), the
    pipeline's result, and readings of it. Arrays are made on first use."""

    def __init__(self, source_frame: StereoFrame, output: LiveOutput) -> None:
        self.index = source_frame.index
        self.t_capture = source_frame.t_left
        self.output = output
        self.result: PipelineResult = output.result

    @property
    def calibration(self) -> StereoCalibration:
        calib = self.result.calibration
        if calib is None:  # (the live processor always rectifies with one)
            raise InputError("this frame has no calibration")
        return calib

    @cached_property
    def depth_mm(self) -> np.ndarray:
        """(H, W) uint16 Z in mm of the rectified left image, 0 where there is no value (the map
        the double-click reads)."""
        return depth_image_mm(self.result)

    @property
    def left(self) -> np.ndarray:
        """The rectified left picture (BGR uint8)."""
        return self.result.rectified_left

    @property
    def disparity_px(self) -> np.ndarray:
        """The final disparity map (float32 px, NaN where invalid)."""
        return self.result.final_px

    def measure(self, x: float, y: float, patch: int = PATCH_PX) -> Reading:
        """The distance at rectified pixel (x, y), read as the window reads a double-click."""
        return Reading.of(measure_point(self.result, x, y, patch=patch))

    def nearest(self, region: tuple[int, int, int, int] | None = None,
                alarm_mm: float | None = None) -> RegionReading:
        """The nearest and median distance in the box `region` = (x, y, width, height) of the
        rectified left image (None: the whole frame), with an alarm below `alarm_mm`."""
        w, h = self.result.size
        if region is None:
            box = Region(0, 0, w, h)
        else:
            x, y, bw, bh = (int(v) for v in region)
            if bw <= 0 or bh <= 0:
                raise InputError(f"a region needs a positive width and height, not {bw}x{bh}")
            box = Region(x, y, x + bw, y + bh)
        return RegionReading.of(region_stats(self.result, box, alarm_mm))


class _Newest:
    """A thread that reads the source and keeps only its newest frame."""

    def __init__(self, source: FrameSource) -> None:
        self._source = source
        self._cond = threading.Condition()
        self._frame: StereoFrame | None = None
        self._error: BaseException | None = None
        self._stop = False
        self.dropped = 0
        self._thread = threading.Thread(target=self._run, name="rig-source", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            with self._cond:
                if self._stop:
                    return
            try:
                frame = self._source.read()
            except Exception as exc:  # noqa: BLE001 - handed to the reader, who raises it
                with self._cond:
                    self._error = exc
                    self._cond.notify_all()
                return
            with self._cond:
                if self._frame is not None:
                    self.dropped += 1
                self._frame = frame
                self._cond.notify_all()

    def take(self, timeout: float = READ_TIMEOUT_S) -> StereoFrame | None:
        """The newest frame not taken yet (waits for one); None once stopped or the source
        ended."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._frame is None and self._error is None and not self._stop:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise SourceError(f"no frame from the source for {timeout:g} s")
                self._cond.wait(left)
            frame, self._frame = self._frame, None
            if frame is None and self._error is not None:
                err = self._error
                if isinstance(err, StopIteration):
                    return None
                if isinstance(err, StereoGuiError):
                    raise err
                raise SourceError(f"the source failed: {err}") from err
            return frame

    def stop(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join(timeout=5.0)


class Rig:
    """An opened source with its calibration and preset (a Preset, or a name `load_preset`
    knows; see `open_rig`). The rig owns the source: closing it closes the source."""

    def __init__(self, source: FrameSource, calibration: StereoCalibration, preset: Preset | str,
                 description: str = "") -> None:
        if isinstance(preset, str):
            preset = load_preset(preset)
        self.source = source
        self.calibration = calibration
        self.description = description
        self._processor = LiveProcessor(calibration, preset)
        self._processor.set_views(())  # no display pictures: the programs read arrays
        self._newest: _Newest | None = None
        self._closed = False

    @property
    def dropped_frames(self) -> int:
        """Frames the source gave that were skipped because a newer one came first."""
        return self._newest.dropped if self._newest is not None else 0

    def watch(self, region: tuple[int, int, int, int] | None, alarm_mm: float | None = None
              ) -> None:
        """Watch the box (x, y, width, height) in every frame from the next on
        (`Frame.output.region`), with an alarm below `alarm_mm`; None stops."""
        if region is None:
            self._processor.set_region(None)
            return
        x, y, w, h = (int(v) for v in region)
        if w <= 0 or h <= 0:
            raise InputError(f"a region needs a positive width and height, not {w}x{h}")
        self._processor.set_region(Region(x, y, x + w, y + h), alarm_mm)

    def frames(self, limit: int | None = None, every: bool = False) -> Iterator[Frame]:
        """Processed frames until `limit` frames (None: until the source ends or the rig is
        closed): the newest each time, or with `every` each frame of the source in turn, none
        skipped (a recording converted at the pipeline's pace, played once, not looped)."""
        if self._closed:
            raise InputError("the rig is closed")
        read = self._every_frame() if every else self._newest_frame
        done = 0
        while limit is None or done < limit:
            raw = read()
            if raw is None:
                return
            yield Frame(raw, self._processor(raw))
            done += 1

    def _newest_frame(self) -> StereoFrame | None:
        if self._newest is None:
            self._newest = _Newest(self.source)
        return self._newest.take()

    def _every_frame(self) -> Callable[[], StereoFrame | None]:
        playback = self.source.playback()
        if playback is not None:
            playback.set_loop(False)
            playback.paced = False  # as fast as the pipeline takes them

        def read() -> StereoFrame | None:
            if self._closed or (playback is not None and playback.finished):
                return None
            try:
                return self.source.read()
            except StopIteration:
                return None

        return read

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._newest is not None:
            self._newest.stop()
        self._processor.close()
        self.source.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_rig(source: str | None = "sim", calibration: str | StereoCalibration | None = None,
             preset: str = "live", size: tuple[int, int] = (640, 480)) -> Rig:
    """Open a source (a spec as `--source` takes: sim, cams:L,R, sbs:N, a folder or video of
    recorded pairs, auto) with a calibration (a file as `--calib` takes, or a
    StereoCalibration; on the simulated rig None means the rig's true calibration) and a
    matcher preset (live, quality, seed, a user preset or a .json file)."""
    params = load_preset(preset)  # before a camera is opened: a wrong name costs nothing
    opened = open_source(source, size=size)
    src = opened.source
    try:
        if calibration is None:
            rig = src.simulated_rig()
            if rig is None:
                raise InputError("a calibration is needed for this source (a file of ours, "
                                 "OpenCV's, ROS's or Middlebury's)")
            calib = rig.true_calibration()
            what = "the simulated rig's true calibration"
        elif isinstance(calibration, StereoCalibration):
            calib, what = calibration, "the calibration given"
        else:
            calib = load_any_calibration(str(calibration), size).calibration
            what = str(calibration)
        if not calib.metric:
            raise InputError("this calibration has no metric scale (Hartley's method): depth in "
                             "millimetres needs a calibration made with a chessboard")
    except BaseException:
        src.close()
        raise
    return Rig(src, calib, params, f"{opened.message or src.name}; {what}")
