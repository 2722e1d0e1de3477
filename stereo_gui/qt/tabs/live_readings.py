"""What the Live tab reads: the pointer's readout and double-click measurements (with the ruler).

- the pointer's readout is the same `measure_point` a double-click would run at that pixel of the
  frame shown (`stereo_gui.pipeline.readout.read_pointer`), on the job thread, coalesced: while one
  hover reading runs, only the newest pointer position waits (no queue);
- a double-click becomes a `measure_point` job on the job thread, run on the result that was on
  screen when the user clicked; its marker goes on every view in the left image's frame and its
  record into the measurement log (a ruler's A-B distance too).
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QLabel

from stereo_gui.core.measure import Measurement, Reason, measure_point
from stereo_gui.core.regression import FitResult
from stereo_gui.files.measurement_record import RULER_METHOD, MeasurementRecord
from stereo_gui.pipeline.live import LiveOutput
from stereo_gui.pipeline.readout import (
    MEASURABLE_VIEWS,
    PointerReading,
    format_distance,
    format_error,
    read_pointer,
    readout_line,
)
from stereo_gui.qt.widgets.image_view import marker_color

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext
    from stereo_gui.qt.widgets.image_view import ImagePanel
    from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

MEASURABLE = MEASURABLE_VIEWS  # views sharing the left image's pixel frame
# a hover reading asked for: (output, view key, x, y, fit, patch px, the frame's ground truth)
HoverRequest = tuple[LiveOutput, str, float, float, FitResult | None, int, object | None]
# the pixel a hover reading was last asked of: (output, view key, x, y, id of the fit)
HoverPixel = tuple[LiveOutput, str, int, int, int]
HOVER_REFRESH_S = 0.25  # a resting pointer's reading follows new frames at most this often
HOVER_HINT = "Point at a view to read the distance there; double-click to log it."
# marker labels stay short (the full reason is in the status bar and the log)
SHORT_REASONS: dict[Reason, str] = {
    Reason.NO_VALID_PIXELS: "no match", Reason.TOO_FEW: "too few pixels",
    Reason.NOT_SEEN: "not seen", Reason.NOT_SEARCHED: "not searched",
    Reason.NO_TEXTURE: "no texture", Reason.TOO_NEAR: "too near", Reason.TOO_FAR: "too far",
    Reason.OUTSIDE: "outside", Reason.OUT_OF_FIT_RANGE: "out of fit range",
    Reason.NO_METRIC_SCALE: "no scale", Reason.AMBIGUOUS: "ambiguous match",
    Reason.NEARER_EDGE: "beside an edge", Reason.NOT_CONFIRMED: "not confirmed",
    Reason.NEARER_HIDES: "nearer beside",
}


def short_reason(reason: Reason | str | None) -> str:
    """A marker's few words for why a point has no distance (a text of no Reason, as an older
    log may hold, shortened)."""
    known = Reason.of(reason)
    if known is not None:
        return SHORT_REASONS[known]
    if not reason:
        return "invalid"
    return reason if len(reason) <= 16 else reason[:15] + "…"


def status_text(m: Measurement) -> str:
    """The status bar's line for a logged reading: its ± right after Z, which it bounds (a
    1280 px wide window cuts the line's end off)."""
    if not m.valid:
        return f"({m.x:.0f}, {m.y:.0f}): no distance: {m.reason}"
    return (f"({m.x:.0f}, {m.y:.0f}): Z {format_distance(m.Z_mm)} "
            f"{format_error(m.expected_error_mm)}, range {format_distance(m.range_mm)}, "
            f"disparity {m.disparity_px:.2f} px, {m.valid_fraction:.0%} valid ({m.method})")


@dataclass(frozen=True)
class ReadingScreen:
    """What the readings read from and draw on, and nothing more of the tab that shows them."""

    output: Callable[[], LiveOutput | None]  # the processed frame shown (None: none yet)
    frame: Callable[[], StereoFrame | None]  # the raw frame of that output
    readout: QLabel  # the line under the views that says the pointer's reading
    markers: Mapping[str, ImagePanel]  # the views a measurement's marker goes on
    ruler_on: Callable[[], bool]  # a double-click is a ruler's point


class LiveReadings(QObject):
    """The readings of one Live tab, read from and drawn on its `screen`; `ctx` is the
    AppContext, whose job thread runs every reading."""

    measured = Signal(Measurement)  # after its marker was drawn
    logged = Signal(MeasurementRecord)  # each reading put into the log (and a ruler's)
    hoverRead = Signal(PointerReading)  # after the readout line shows it

    def __init__(self, ctx: AppContext, screen: ReadingScreen,
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._screen = screen
        self._hover: tuple[str, float, float] | None = None
        self._hover_job: int | None = None  # id of the hover reading running on the job thread
        self._hover_next: HoverRequest | None = None  # the newest request waiting for it
        self._hover_last: HoverPixel | None = None  # the pixel last asked for
        self.hover_jobs_submitted = 0
        self._hover_t = 0.0  # when the last hover reading was asked for, time.monotonic() s
        self.last_reading: PointerReading | None = None
        self._pending: dict[int, tuple[str, bool]] = {}  # job id -> (view key, ruler click)
        self._ruler_a: Measurement | None = None  # first point of a ruler pair
        self.last_ruler_mm: float | None = None
        ctx.jobs.finished.connect(self._job_finished)
        ctx.jobs.failed.connect(self._job_failed)

    def frame_shown(self) -> None:
        """A new frame is on screen: a resting pointer reads it too (at most every
        HOVER_REFRESH_S)."""
        if self._hover is not None and time.monotonic() - self._hover_t >= HOVER_REFRESH_S:
            self._request_reading(*self._hover)

    def forget_ruler_point(self) -> None:
        self._ruler_a = None

    def hovered(self, key: str, x: float, y: float) -> None:
        self._hover = None if math.isnan(x) else (key, x, y)
        if self._hover is None:
            self._hover_next = None
            self._hover_last = None  # back on the same pixel later: read it again
            self._screen.readout.setText(HOVER_HINT)
        else:
            self._request_reading(key, x, y)

    def _request_reading(self, key: str, x: float, y: float) -> None:
        """Ask for the reading under the pointer on the frame shown: at once when no hover
        reading runs, else as the one waiting (replacing an older wish: newest wins)."""
        out = self._screen.output()
        if out is None:
            self._screen.readout.setText(f"x {round(x):4d}  y {round(y):4d}   no frame yet")
            return
        fit = self.ctx.active_fit
        ask: HoverPixel = (out, key if key not in MEASURABLE else "left", round(x), round(y),
                           id(fit))
        if ask == self._hover_last:
            if self._hover_job is not None:
                self._hover_next = None  # the reading running is of this very pixel
            return  # the same pixel of the same frame: the line says (or will say) it
        frame = self._screen.frame()
        request: HoverRequest = (out, key, x, y, fit, int(self.ctx.settings.patch_size),
                                 frame.truth if frame is not None else None)
        if self._hover_job is not None:
            self._hover_next = request
            return
        self._submit_reading(request)
        self._hover_last = ask

    def _submit_reading(self, request: HoverRequest) -> None:
        out, key, x, y, fit, patch, truth = request
        self._hover_t = time.monotonic()
        result = out.result
        self._hover_job = self.ctx.jobs.submit(
            lambda _control: read_pointer(result, key, x, y, patch, fit, truth)).id
        self.hover_jobs_submitted += 1

    def _hover_finished(self, reading: PointerReading) -> None:
        self._hover_job = None
        if self._hover is not None:
            self.last_reading = reading
            self._screen.readout.setText(readout_line(reading))
            self.hoverRead.emit(reading)
        request, self._hover_next = self._hover_next, None
        if request is not None and self._hover is not None:
            out, key, x, y, fit, _patch, _truth = request
            self._hover_last = (out, key if key not in MEASURABLE else "left", round(x),
                                round(y), id(fit))
            self._submit_reading(request)

    # ---- measuring ---------------------------------------------------------------------------
    def double_clicked(self, key: str, x: float, y: float) -> None:
        if key not in MEASURABLE:
            self.ctx.show_status("Measure on the left image or a disparity view: the right "
                                 "image has other pixel coordinates.")
            return
        self.measure_at(x, y, key)

    def measure_at(self, x: float, y: float, key: str = "depth") -> int | None:
        """Measure at rectified-left pixel (x, y) on the frame now shown; returns the job id."""
        out = self._screen.output()
        if out is None:
            self.ctx.report_error("No frame to measure on yet.")
            return None
        patch = int(self.ctx.settings.patch_size)
        fit = self.ctx.active_fit
        result = out.result
        job = self.ctx.jobs.submit(
            lambda _control: measure_point(result, x, y, patch=patch, fit=fit)).id
        self._pending[job] = (key, self._screen.ruler_on())
        return job

    def _job_finished(self, job_id: int, m: Measurement | PointerReading) -> None:
        if job_id == self._hover_job and isinstance(m, PointerReading):
            self._hover_finished(m)
            return
        if job_id not in self._pending or not isinstance(m, Measurement):
            return  # another tab's job
        _key, ruler = self._pending.pop(job_id)
        color = marker_color(m.valid)
        label = format_distance(m.Z_mm) if m.valid else f"✕ {short_reason(m.reason)}"
        line_to, line_text, ruler_record, status = None, "", None, status_text(m)
        if ruler:
            a = self._ruler_a
            if a is None:
                if m.valid:
                    self._ruler_a = m
                    label = "A: " + label
                    status = f"Ruler: A at {status}; double-click the second point (B)."
                else:
                    label = "A? " + label
                    status = (f"Ruler: the first point has no distance ({m.reason}); "
                              f"double-click another first point (A).")
            elif not m.valid:
                label = "B? " + label  # A stays: only B is asked for again
                status = (f"Ruler: the second point has no distance ({m.reason}); double-click "
                          f"another second point (B).")
            else:
                self._ruler_a = None
                dist = math.dist((a.X_mm, a.Y_mm, a.Z_mm), (m.X_mm, m.Y_mm, m.Z_mm))
                bound = math.hypot(a.expected_error_mm, m.expected_error_mm)
                label = f"B: {label}"
                line_text = f"A–B {format_distance(dist)}"
                line_to = (a.x, a.y)
                color = "#40c4ff"
                self.last_ruler_mm = dist
                ruler_record = self._ruler_record(a, m, dist, bound)
                status = (f"Ruler: A–B {format_distance(dist)} {format_error(bound)} "
                          f"(logged)")
        for panel in self._screen.markers.values():
            panel.add_marker(m.x, m.y, label, color, line_to, line_text)
        for record in (self._record(m), ruler_record):
            if record is not None:
                self.ctx.add_measurement(record)
                self.logged.emit(record)
        self.ctx.show_status(status)
        self.measured.emit(m)

    def _job_failed(self, job_id: int, message: str) -> None:
        if job_id == self._hover_job:
            log.warning("hover reading failed: %s", message)
            key, x, y = self._hover or ("", 0.0, 0.0)
            self._hover_finished(PointerReading(key, x, y, note=f"reading failed: {message}"))
            return
        if self._pending.pop(job_id, None) is not None:
            self.ctx.report_error(f"Measurement failed: {message}")

    def _record(self, m: Measurement) -> MeasurementRecord:
        calib = self.ctx.calibration
        path = self.ctx.calibration_path
        return MeasurementRecord(
            time=_dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            x_px=float(m.x), y_px=float(m.y), disparity_px=float(m.disparity_px),
            X_mm=float(m.X_mm), Y_mm=float(m.Y_mm), Z_mm=float(m.Z_mm),
            range_mm=float(m.range_mm), valid=bool(m.valid), reason=str(m.reason or ""),
            valid_fraction=float(m.valid_fraction), expected_error_mm=float(m.expected_error_mm),
            method=m.method,
            calibration_file=str(path) if path else self.ctx.calibration_note,
            calibration_rms_px=float(calib.rms_stereo) if calib is not None else float("nan"),
        )

    def _ruler_record(self, a: Measurement, b: Measurement, dist_mm: float, bound_mm: float
                      ) -> MeasurementRecord:
        """The log entry of a ruler distance: at B's pixel, X/Y/Z the components of B - A
        (mm), Range the length |B - A|, ± the two points' bounds added in quadrature."""
        rec = self._record(b)
        return MeasurementRecord(**{
            **rec.__dict__, "disparity_px": float("nan"), "X_mm": b.X_mm - a.X_mm,
            "Y_mm": b.Y_mm - a.Y_mm, "Z_mm": b.Z_mm - a.Z_mm, "range_mm": float(dist_mm),
            "valid_fraction": min(a.valid_fraction, b.valid_fraction),
            "expected_error_mm": float(bound_mm),
            "method": f"{RULER_METHOD} from ({a.x:.0f}, {a.y:.0f})"})

    def ruler_toggled(self, on: bool) -> None:
        self._ruler_a = None
        if on:
            self.ctx.show_status("Ruler: double-click the first point, then the second.")
