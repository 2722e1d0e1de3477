"""Measurement logs as real Excel workbooks (openpyxl) and CSV files.

A workbook written here has three sheets:

- **Measurements**: one row per `MeasurementRecord`, units in the headers (see `COLUMNS`); the
  time is a real date-time cell (UTC), so Excel and LibreOffice sort, filter and format it.
- **Regression**: the (disparity, true distance) samples with each fitted model's prediction and
  residual, a table of the models (formula, R^2, coefficients), the fitted curves evaluated on a
  disparity grid (hidden columns) and a native Excel scatter chart of distance against disparity:
  samples as markers, each fit as a line, so no fit has to be made by hand in Excel.
- **Calibration**: the figures (RMS, baseline, board, date) and each camera's parameters, each
  with its 1-sigma uncertainty, the warnings, the pairs it was not made from, each pair's error,
  and the matrices M1 D1 M2 D2 R T P1 P2 Q as small tables.

Every sheet prints landscape, one page wide.

A new workbook is streamed with openpyxl's write-only mode (time linear in the rows: 20,000
readings take seconds); appending loads the workbook and adds rows below the last one.

Every write goes through a temporary file in the same folder and a rename, so a crash or a full
disk mid-write leaves the earlier file intact; a workbook is read back (its zip checked) before
it replaces the old one.

The parts live beside this module: the workbook itself (made, saved and checked, loaded,
appended to) in `workbook`, the columns and cell values in `sheet_columns`, each sheet in
`sheet_measurements`, `sheet_regression` and `sheet_calibration` (the last two drafted with
`sheet_draft`), and the same log as CSV in `measurement_csv`. The names callers use are
imported from here too.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from stereo_gui.core.jobs import Cancel, ProgressCallback
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.measurement_csv import (
    csv_decimals,
    pct_decimals,
    read_csv,
    records_to_csv,
    write_csv,
)

# the record type and its derived error are defined with the log; imported from here too
from stereo_gui.files.measurement_record import MeasurementRecord, record_error
from stereo_gui.files.sheet_columns import ERROR_HEADERS, FILE_HEADERS, HEADERS, XLSX_HEADERS

__all__ = [
    "ERROR_HEADERS", "FILE_HEADERS", "HEADERS", "MeasurementRecord", "XLSX_HEADERS",
    "append_measurements", "csv_decimals", "pct_decimals", "read_csv", "read_measurements",
    "record_error", "records_to_csv", "write_csv", "write_workbook",
]

# The workbook functions load files.workbook, and with it openpyxl, when first called: openpyxl
# adds about 230 ms to the window's start (measured with -X importtime, 1.7 s without it), and
# the window imports this module for MeasurementRecord and the exports.


def write_workbook(path: str | os.PathLike[str], records: Iterable[MeasurementRecord],
                   fits: Sequence[FitResult] = (), calibration: StereoCalibration | None = None,
                   calibration_file: str | os.PathLike[str] | None = None, cancel: Cancel = None,
                   progress: ProgressCallback | None = None) -> Path:
    """Write a new workbook (replacing `path` atomically) with the three sheets and the chart:
    `files.workbook.write_workbook`, which says what each argument does."""
    from stereo_gui.files import workbook  # openpyxl: loaded on first use (see above)

    return workbook.write_workbook(path, records, fits, calibration, calibration_file, cancel,
                                   progress)


def read_measurements(path: str | os.PathLike[str]) -> list[MeasurementRecord]:
    """The measurement log of a workbook written by `write_workbook` / `append_measurements`."""
    from stereo_gui.files import workbook  # openpyxl: loaded on first use (see above)

    return workbook.read_measurements(path)


def append_measurements(path: str | os.PathLike[str], records: Iterable[MeasurementRecord],
                        fits: Sequence[FitResult] | None = None,
                        calibration: StereoCalibration | None = None,
                        calibration_file: str | os.PathLike[str] | None = None) -> int:
    """Append `records` to the workbook at `path`, keeping every earlier row; return the count:
    `files.workbook.append_measurements`, which says what each argument does."""
    from stereo_gui.files import workbook  # openpyxl: loaded on first use (see above)

    return workbook.append_measurements(path, records, fits, calibration, calibration_file)
