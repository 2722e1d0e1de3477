"""One entry of the measurement log, whatever keeps it: the log file (files.measurement_log), a
workbook or a CSV file (files.spreadsheet), the GUI's table.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from dataclasses import dataclass

from stereo_gui.core.measure import Measurement

__all__ = ["RULER_METHOD", "MeasurementRecord", "record_error"]


@dataclass(frozen=True)
class MeasurementRecord:
    """One entry of the measurement log (what a click in the GUI or `measure` produces).

    Pixel coordinates are of the rectified left image; X/Y/Z are in the left rectified camera
    frame, mm. Numbers that do not exist for an invalid reading are NaN.
    """

    time: str  # ISO 8601
    x_px: float
    y_px: float
    disparity_px: float
    X_mm: float
    Y_mm: float
    Z_mm: float
    range_mm: float
    valid: bool
    reason: str = ""  # why the reading is invalid, empty when valid
    valid_fraction: float = float("nan")  # share of valid pixels in the patch, 0..1
    expected_error_mm: float = float("nan")
    method: str = "triangulation"  # or the name of the fit used ("cubic", "inverse")
    true_mm: float | None = None  # true distance entered by the technician
    calibration_file: str = ""
    calibration_rms_px: float = float("nan")
    note: str = ""  # what was measured, in the technician's words

    @classmethod
    def from_measurement(cls, m: Measurement, *, time: str | None = None,
                         true_mm: float | None = None,
                         calibration_file: str | os.PathLike[str] = "",
                         calibration_rms_px: float = float("nan")) -> MeasurementRecord:
        """The log entry of a `stereo_gui.core.measure.Measurement` (time defaults to now)."""
        if time is None:
            time = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")
        return cls(time=time, x_px=float(m.x), y_px=float(m.y),
                   disparity_px=float(m.disparity_px), X_mm=float(m.X_mm), Y_mm=float(m.Y_mm),
                   Z_mm=float(m.Z_mm), range_mm=float(m.range_mm), valid=bool(m.valid),
                   reason=m.reason or "", valid_fraction=float(m.valid_fraction),
                   expected_error_mm=float(m.expected_error_mm), method=str(m.method),
                   true_mm=None if true_mm is None else float(true_mm),
                   calibration_file=str(calibration_file),
                   calibration_rms_px=float(calibration_rms_px))


# a ruler distance in the log: the method starts so; X/Y/Z are the components of B - A and
# Range its length
RULER_METHOD = "ruler A–B"


def record_error(rec: MeasurementRecord) -> tuple[float, float]:
    """(measured - true distance in mm, the same in % of the true distance); NaN without a true
    distance or a valid reading. Measured is Z, or the length for a ruler distance."""
    measured = rec.range_mm if rec.method.startswith(RULER_METHOD) else rec.Z_mm
    if rec.true_mm is None or not rec.valid or not math.isfinite(measured) or rec.true_mm <= 0:
        return float("nan"), float("nan")
    err = float(measured) - float(rec.true_mm)
    return err, 100.0 * err / float(rec.true_mm)
