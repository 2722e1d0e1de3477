"""Measurement logs as CSV files: a header with units, one row per record, numbers rounded to
what they mean: 0.1 mm and 0.001 px, an error in % to its 0.1 mm (`csv_decimals`,
`pct_decimals`). Written atomically (files.atomic)."""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable
from pathlib import Path

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import write_text_atomic
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.readers import read_csv_rows
from stereo_gui.files.sheet_columns import (
    COLUMNS,
    ERROR_FIELDS,
    ERROR_HEADERS,
    FILE_HEADERS,
    HEADERS,
    cell_value,
    file_values,
    record_from_row,
)


def csv_decimals(field: str) -> int | None:
    """Decimals a CSV number of record field `field` keeps, from the unit in its name: 0.1 mm,
    0.001 px (a fraction to 0.001, 0.1 %); None for a number without a unit (6 digits). An error
    in % keeps as many as its true distance asks (`pct_decimals`)."""
    if field.endswith("_mm"):
        return 1
    if field.endswith("_px") or field.endswith("fraction"):
        return 3
    return None


def pct_decimals(true_mm: float | None) -> int:
    """Decimals of an error in % of `true_mm` that keep the error's own 0.1 mm: 3 at 2 m (a
    step of 0.005 %), 2 at 0.5 m; rounded to 0.1 % an error of -0.6 mm at 2 m was written 0.0."""
    if true_mm is None or not math.isfinite(true_mm) or true_mm <= 0:
        return 1
    step_pct = 100.0 * 0.1 / float(true_mm)
    return int(min(6, max(1, math.ceil(-math.log10(step_pct)))))


def _csv_number(value: float, decimals: int | None) -> str:
    text = f"{value:.{decimals}f}" if decimals is not None else f"{value:.6g}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text  # no "-0.0"


def records_to_csv(records: Iterable[MeasurementRecord]) -> str:
    """The log as CSV text: a header with units, one row per record; empty where no number;
    numbers rounded to what they mean (`csv_decimals`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(FILE_HEADERS)
    decimals = ([csv_decimals(name) for name, _, _, _ in COLUMNS]
                + [csv_decimals(name) for name in ERROR_FIELDS] + [None])
    pct = len(COLUMNS) + ERROR_FIELDS.index("error_pct")
    for rec in records:
        row: list[object] = []
        decimals[pct] = pct_decimals(rec.true_mm)
        for value, dec in zip(file_values(rec), decimals, strict=True):
            v = cell_value(value)
            if v is None:
                row.append("")
            elif isinstance(v, float):
                row.append(_csv_number(v, dec))
            else:
                row.append(v)
        w.writerow(row)
    return buf.getvalue()


def write_csv(path: str | os.PathLike[str], records: Iterable[MeasurementRecord]) -> Path:
    """Write the log as a UTF-8 CSV file (atomically)."""
    return write_text_atomic(path, records_to_csv(records))


def read_csv(path: str | os.PathLike[str]) -> list[MeasurementRecord]:
    """Read a CSV file written by `write_csv` (with the error and note columns or, older,
    without them)."""
    what = "a measurement CSV of stereo-gui"
    try:
        rows = read_csv_rows(path, FILE_HEADERS, what)
    except InputError:
        try:
            rows = read_csv_rows(path, HEADERS + ERROR_HEADERS, what)
        except InputError:
            rows = read_csv_rows(path, HEADERS, what)
    return [record_from_row(r, f"{path}, line {i}") for i, r in enumerate(rows, start=2) if r]
