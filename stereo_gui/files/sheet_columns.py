"""The columns of a measurement log, as a workbook and a CSV file hold them, and the cell values
a record becomes and is read back from.

`COLUMNS` lists (record field, header with unit, Excel number format, column width) in file
order; the derived error columns (`ERROR_COLUMNS`) and the technician's note (`NOTE_COLUMN`)
follow them. In a workbook the time is a date-time cell in UTC; a CSV keeps ISO 8601 text.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Sequence
from dataclasses import astuple, fields
from typing import Any

import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.files.measurement_record import MeasurementRecord, record_error

# (record field, header with unit, Excel number format, column width)
COLUMNS: tuple[tuple[str, str, str, int], ...] = (
    ("time", "Time (ISO 8601)", "@", 27),
    ("x_px", "x (px)", "0.0", 8),
    ("y_px", "y (px)", "0.0", 8),
    ("disparity_px", "Disparity (px)", "0.000", 13),
    ("X_mm", "X (mm)", "0.0", 10),
    ("Y_mm", "Y (mm)", "0.0", 10),
    ("Z_mm", "Z (mm)", "0.0", 10),
    ("range_mm", "Range (mm)", "0.0", 11),
    ("valid", "Valid", "General", 7),
    ("reason", "Reason", "@", 18),
    ("valid_fraction", "Valid fraction", "0.0%", 11),  # 0..1; Excel shows it as a percentage
    ("expected_error_mm", "Expected error (mm)", "0.0", 11),
    ("method", "Method", "@", 14),
    ("true_mm", "True distance (mm)", "0.0", 13),
    ("calibration_file", "Calibration file", "@", 30),
    ("calibration_rms_px", "Calibration RMS (px)", "0.000", 12),
)
# the technician's note, the last column of a file: files written before it had none, and are
# read as they are (their columns are the first ones of today's)
NOTE_COLUMN = ("note", "Note", "@", 40)
HEADERS = tuple(c[1] for c in COLUMNS)
# derived from each record and written after its columns (readers ignore them): how far Z is
# from the true distance once one was entered
ERROR_COLUMNS: tuple[tuple[str, str, int], ...] = (
    ("Error Z - true (mm)", "0.0", 12), ("Error (%)", "0.00", 10))
ERROR_HEADERS = tuple(c[0] for c in ERROR_COLUMNS)
ERROR_FIELDS = ("error_mm", "error_pct")  # their names, for their units (csv_decimals)
_FIELD_NAMES = tuple(f.name for f in fields(MeasurementRecord))
# the layout covers every field, in order
assert tuple(c[0] for c in COLUMNS) + (NOTE_COLUMN[0],) == _FIELD_NAMES
FILE_HEADERS = HEADERS + ERROR_HEADERS + (NOTE_COLUMN[1],)  # a CSV's first row, in order

# In a workbook the time is a date-time cell in UTC (Excel has no time zones); CSV keeps ISO text.
XLSX_TIME_HEADER = "Time (UTC)"
XLSX_TIME_FORMAT = "yyyy-mm-dd hh:mm:ss.000"
XLSX_HEADERS = tuple(XLSX_TIME_HEADER if name == "time" else header
                     for name, header, _, _ in COLUMNS) + ERROR_HEADERS + (NOTE_COLUMN[1],)


# ---- cell values ----------------------------------------------------------------------------
def cell_value(value: object) -> object:
    """A value Excel can hold: NaN, inf and None become empty cells, numpy scalars plain numbers."""
    if value is None:
        return None
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        v = float(value)
        return v if math.isfinite(v) else None
    return value


def _time_cell(text: str) -> _dt.datetime | str | None:
    """An ISO 8601 time as a naive UTC datetime for a date-time cell (text that is not a time
    stays text)."""
    try:
        t = _dt.datetime.fromisoformat(str(text))
    except ValueError:
        return text or None
    if t.tzinfo is not None:
        t = t.astimezone(_dt.timezone.utc).replace(tzinfo=None)
    return t


def _time_text(value: _dt.datetime) -> str:
    """A date-time cell (UTC) back as ISO 8601 text, milliseconds only when it has them."""
    t = value.replace(tzinfo=_dt.timezone.utc)
    return t.isoformat(timespec="milliseconds" if t.microsecond else "seconds")


def record_from_row(values: Sequence[Any], where: str) -> MeasurementRecord:
    """The record of a row read back (a workbook's cells or a CSV's texts); `where` names the
    row in an error."""
    kw: dict[str, Any] = {}
    note_at = len(COLUMNS) + len(ERROR_COLUMNS)
    if len(values) > note_at and values[note_at] not in (None, ""):
        kw["note"] = str(values[note_at])
    for (name, header, _, _), v in zip(COLUMNS, values, strict=False):
        if name == "time" and isinstance(v, _dt.datetime):
            kw[name] = _time_text(v)
        elif name in ("time", "reason", "method", "calibration_file"):
            kw[name] = "" if v is None else str(v)
        elif name == "valid":
            text = str(v).strip().lower()
            kw[name] = bool(v) if not isinstance(v, str) else text in ("true", "1", "yes")
        else:
            try:
                number = None if v in (None, "") else float(v)
            except (TypeError, ValueError) as exc:
                raise InputError(f"{where}: column {header!r} holds {v!r}, not a number") from exc
            # an empty cell is "not entered" for the true distance, NaN for measured numbers
            kw[name] = number if name == "true_mm" or number is not None else float("nan")
    return MeasurementRecord(**kw)


# ---- a record's cells ----------------------------------------------------------------------
def file_values(rec: MeasurementRecord) -> tuple[object, ...]:
    """A record's values in the order of a file's columns: the measured fields, the derived
    errors, the note."""
    values = astuple(rec)
    return values[:len(COLUMNS)] + record_error(rec) + (rec.note,)


def row_values(rec: MeasurementRecord) -> list[object]:
    """A record's cells in a workbook's row: its time a date-time, no NaN."""
    values = [cell_value(v) for v in file_values(rec)]
    values[0] = _time_cell(rec.time)
    return values


def number_formats() -> list[str]:
    """The Excel number format of each column of the Measurements sheet, in file order."""
    return ([XLSX_TIME_FORMAT if name == "time" else fmt for name, _, fmt, _ in COLUMNS]
            + [c[1] for c in ERROR_COLUMNS] + [NOTE_COLUMN[2]])
