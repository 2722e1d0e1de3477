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
CSV numbers are rounded to what they mean: 0.1 mm and 0.001 px, an error in % to its 0.1 mm
(`csv_decimals`, `pct_decimals`).

Every write goes through a temporary file in the same folder and a rename, so a crash or a full
disk mid-write leaves the earlier file intact.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
import logging
import math
import os
import zipfile
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import astuple, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import check_cancel
from stereo_gui.core.util import how_many
from stereo_gui.files.atomic import atomic_path, os_error_text, write_text_atomic

# the record type and its derived error are defined with the log; imported from here too
from stereo_gui.files.measurement_record import MeasurementRecord, record_error
from stereo_gui.files.readers import read_csv_rows

if TYPE_CHECKING:  # only for annotations: the regression module is imported where used
    from stereo_gui.core.stereo_calibration import StereoCalibration

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
MEASUREMENTS_SHEET = "Measurements"
REGRESSION_SHEET = "Regression"
CALIBRATION_SHEET = "Calibration"
# written into the workbook's properties so that a workbook of ours can be recognised
WORKBOOK_KEYWORDS = f"stereo-gui measurements v{FORMAT_VERSION}"
CURVE_POINTS = 60  # points of each fitted curve drawn in the chart


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
def _cell(value: Any) -> Any:
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


def _time_cell(text: str) -> Any:
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


def _record_from_row(values: Sequence[Any], where: str) -> MeasurementRecord:
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


# ---- sheets ---------------------------------------------------------------------------------
def _bold():
    from openpyxl.styles import Font

    return Font(bold=True)


def _file_values(rec: MeasurementRecord) -> tuple:
    """A record's values in the order of a file's columns: the measured fields, the derived
    errors, the note."""
    values = astuple(rec)
    return values[:len(COLUMNS)] + record_error(rec) + (rec.note,)


def _row_values(rec: MeasurementRecord) -> list[Any]:
    values = [_cell(v) for v in _file_values(rec)]
    values[0] = _time_cell(rec.time)
    return values


def _formats() -> list[str]:
    return ([XLSX_TIME_FORMAT if name == "time" else fmt for name, _, fmt, _ in COLUMNS]
            + [c[1] for c in ERROR_COLUMNS] + [NOTE_COLUMN[2]])


_CANCEL_EVERY_ROWS = 500  # a streamed export looks at its cancel flag and reports this often


def _write_measurements_sheet(ws, records: Sequence[MeasurementRecord], cancel=None,
                              progress=None) -> int:
    """Stream the header and one row per record into a write-only sheet; return the count.

    `cancel` (see core.jobs.Cancel) is looked at and `progress(done, total, text)` called
    every _CANCEL_EVERY_ROWS rows."""
    from openpyxl.cell import WriteOnlyCell
    from openpyxl.utils import get_column_letter

    widths = [c[3] for c in COLUMNS] + [c[2] for c in ERROR_COLUMNS] + [NOTE_COLUMN[3]]
    names = [c[0] for c in COLUMNS] + list(ERROR_FIELDS) + [NOTE_COLUMN[0]]
    for i, (name, header, width) in enumerate(zip(names, XLSX_HEADERS, widths, strict=True),
                                              start=1):
        # wide enough for the bold header with its unit ("Expected error (mm)" was cut off)
        width = max(21 if name == "time" else width, round(1.1 * len(header) + 2))
        ws.column_dimensions[get_column_letter(i)].width = width
    ws.freeze_panes = "A2"
    # printed (or made a PDF) landscape, one page wide, the header on every page: it was cut
    # into five pages of columns
    ws.page_setup.orientation = "landscape"
    ws.sheet_properties.pageSetUpPr.fitToPage = True
    ws.page_setup.fitToWidth = 1
    ws.page_setup.fitToHeight = 0
    ws.print_title_rows = "1:1"
    bold = _bold()
    header = []
    for text in XLSX_HEADERS:
        c = WriteOnlyCell(ws, text)
        c.font = bold
        header.append(c)
    ws.append(header)
    formats = _formats()
    n = 0
    for rec in records:
        row = []
        for value, fmt in zip(_row_values(rec), formats, strict=True):
            c = WriteOnlyCell(ws, value)
            c.number_format = fmt
            row.append(c)
        ws.append(row)
        n += 1
        if n % _CANCEL_EVERY_ROWS == 0:
            check_cancel(cancel)
            if progress is not None:
                progress(n, len(records), f"{n:,} of {how_many(len(records), 'row')}")
    return n


def _append_measurement_rows(ws, records: Iterable[MeasurementRecord]) -> int:
    """Append records below the last row of a loaded (not write-only) sheet."""
    # the sheet's size is read once: ws.max_row scans every cell, so asking it per row made a
    # 20,000-row export quadratic
    row = ws.max_row
    formats = _formats()
    n = 0
    for rec in records:
        row += 1
        for col, (value, fmt) in enumerate(zip(_row_values(rec), formats, strict=True), start=1):
            ws.cell(row=row, column=col, value=value).number_format = fmt
        n += 1
    return n


def _predict(fit, d: np.ndarray) -> np.ndarray:
    """The fit evaluated on disparities `d` (px), mm (element by element if it takes scalars)."""
    try:
        out = np.asarray(fit.predict(d), dtype=float)
        if out.shape == d.shape:
            return out
    except (TypeError, ValueError):
        pass
    return np.array([float(fit.predict(float(x))) for x in d], dtype=float)


def _samples(records: Sequence[MeasurementRecord], fits: Sequence) -> list[tuple[float, float]]:
    """The regression samples: those of the fits (in order, no duplicates), else the log's
    valid readings that carry a true distance."""
    seen: dict[tuple[float, float], None] = {}
    if fits:
        for fit in fits:
            for d, z in fit.samples:
                seen.setdefault((float(d), float(z)), None)
    else:
        for r in records:
            if r.true_mm is not None and math.isfinite(r.disparity_px):
                seen.setdefault((float(r.disparity_px), float(r.true_mm)), None)
    return list(seen)


class _Draft:
    """The cells of a small sheet, written in any order and then put into a worksheet in row
    order (a write-only sheet takes rows only from top to bottom)."""

    def __init__(self) -> None:
        self.cells: dict[tuple[int, int], tuple[Any, str | None, bool]] = {}
        self.widths: dict[int, float] = {}
        self.hidden: set[int] = set()
        self.charts: list[tuple[Any, str]] = []
        self.print_one_page_wide = False  # landscape, scaled to the page's width when printed
        self.wrapped: set[tuple[int, int]] = set()

    def set(self, row: int, col: int, value: Any, fmt: str | None = None,
            bold: bool = False, wrap: bool = False) -> None:
        self.cells[(row, col)] = (value, fmt, bold)
        if wrap:  # long text wraps within its column's width, not past the printed page
            self.wrapped.add((row, col))

    def to_sheet(self, ws) -> None:
        from openpyxl.cell import WriteOnlyCell
        from openpyxl.utils import get_column_letter
        from openpyxl.worksheet._write_only import WriteOnlyWorksheet

        for col, width in self.widths.items():
            ws.column_dimensions[get_column_letter(col)].width = width
        for col in self.hidden:
            ws.column_dimensions[get_column_letter(col)].hidden = True
        # a row of wrapped text as tall as its lines (neither Excel nor LibreOffice grows a row
        # written by openpyxl: the lines ran over the rows below)
        heights: dict[int, int] = {}
        for r, c in self.wrapped:
            text = str(self.cells[(r, c)][0] or "")
            per_line = max(1.0, 1.1 * self.widths.get(c, 8.43))
            heights[r] = max(heights.get(r, 1), math.ceil(len(text) / per_line))
        for r, lines in heights.items():
            if lines > 1:
                ws.row_dimensions[r].height = 15 * lines
        if self.print_one_page_wide:
            ws.page_setup.orientation = "landscape"
            ws.sheet_properties.pageSetUpPr.fitToPage = True
            ws.page_setup.fitToWidth = 1
            ws.page_setup.fitToHeight = 0
        from openpyxl.styles import Alignment

        bold = _bold()
        wrap = Alignment(wrap_text=True, vertical="top")
        top = Alignment(vertical="top")  # the other cells of a row of wrapped text
        wrapped_rows = {r for r, _ in self.wrapped}
        if isinstance(ws, WriteOnlyWorksheet):
            n_rows = max((r for r, _ in self.cells), default=0)
            n_cols = max((c for _, c in self.cells), default=0)
            for r in range(1, n_rows + 1):
                row: list[Any] = [None] * n_cols
                for c in range(1, n_cols + 1):
                    if (r, c) in self.cells:
                        value, fmt, is_bold = self.cells[(r, c)]
                        cell = WriteOnlyCell(ws, value)
                        if fmt:
                            cell.number_format = fmt
                        if is_bold:
                            cell.font = bold
                        if (r, c) in self.wrapped:
                            cell.alignment = wrap
                        elif r in wrapped_rows:
                            cell.alignment = top
                        row[c - 1] = cell
                ws.append(row)
        else:
            for (r, c), (value, fmt, is_bold) in self.cells.items():
                cell = ws.cell(row=r, column=c, value=value)
                if fmt:
                    cell.number_format = fmt
                if is_bold:
                    cell.font = bold
                if (r, c) in self.wrapped:
                    cell.alignment = wrap
                elif r in wrapped_rows:
                    cell.alignment = top
        for chart, anchor in self.charts:
            ws.add_chart(chart, anchor)


# Chart colours that read on white in Excel and in LibreOffice (which ignores Excel's chart
# styles and drew the samples as white markers): samples as filled dark markers, each fit a
# colour, dash and width of its own (Okabe-Ito colours, distinct for colour-blind readers too).
# Two good fits lie on top of each other: a thin solid line over or under a wide dashed one
# shows both, whichever order the program draws them in.
SAMPLE_COLOUR = "1F1F1F"
# (colour, dash, width in EMU: 12700 per point)
FIT_STYLES: tuple[tuple[str, str, int], ...] = (
    ("D55E00", "solid", 22225), ("0072B2", "dash", 57150),
    ("009E73", "sysDot", 38100), ("CC79A7", "lgDash", 31750))


def _sample_series(ys, xs):
    from openpyxl.chart import Series
    from openpyxl.chart.shapes import GraphicalProperties
    from openpyxl.drawing.line import LineProperties

    s = Series(ys, xs, title="Samples (true distance)")
    s.marker.symbol = "circle"
    s.marker.size = 7
    s.marker.graphicalProperties = GraphicalProperties(
        solidFill=SAMPLE_COLOUR, ln=LineProperties(solidFill=SAMPLE_COLOUR))
    s.graphicalProperties.line.noFill = True
    return s


def _fit_series(ys, xs, title: str, k: int):
    from openpyxl.chart import Series

    colour, dash, width = FIT_STYLES[k % len(FIT_STYLES)]
    line = Series(ys, xs, title=title)
    line.marker.symbol = "none"
    line.smooth = True
    line.graphicalProperties.line.solidFill = colour
    line.graphicalProperties.line.width = width
    line.graphicalProperties.line.prstDash = dash
    return line


def _write_regression_sheet(ws, samples: list[tuple[float, float]], fits: Sequence) -> None:
    from openpyxl.chart import Reference, ScatterChart

    draft = _Draft()
    draft.set(1, 1, "Regression: distance against disparity", bold=True)

    # the models first, then the samples below them: one page wide when printed (the models
    # beside the samples made the sheet too wide to read on paper); each model's formula on a
    # row of its own, where it runs across the empty cells to its right
    n_coef = max((len(f.coefficients) for f in fits), default=0)
    mheader = ["Model", "R^2", "Samples", "RMS residual (mm)"] + [f"c{i}" for i in range(n_coef)]
    for j, text in enumerate(mheader):
        draft.set(3, 1 + j, text, bold=True)
    for k, fit in enumerate(fits):
        res = np.asarray(fit.residuals_mm, float)
        rms = float(np.sqrt(np.mean(res**2))) if res.size else float("nan")
        values = [fit.model, _cell(fit.r2), len(fit.samples), _cell(rms)]
        values += [_cell(c) for c in fit.coefficients]
        formats = {1: "0.00000", 3: "0.00"}
        for j, v in enumerate(values):
            draft.set(4 + k, 1 + j, v, formats.get(j, "0.0000E+00" if j >= 4 else None))
    row = 4 + len(fits)
    for fit in fits:
        draft.set(row, 1, f"{fit.model} formula", bold=True)
        draft.set(row, 2, fit.formula())
        row += 1
    if not fits:
        draft.set(4, 1, "no fit yet: enter true distances for at least a few measurements "
                        "and fit a model")
        row = 5

    # samples table: A disparity, B true distance, then prediction and residual per fit
    header_row = row + 1
    header = ["Disparity (px)", "True distance (mm)"]
    for fit in fits:
        header += [f"{fit.model} prediction (mm)", f"{fit.model} residual (mm)"]
    for col, text in enumerate(header, start=1):
        draft.set(header_row, col, text, bold=True)
    for table in (header, mheader):  # each column as wide as the wider of its two headers
        for col, text in enumerate(table, start=1):
            draft.widths[col] = max(draft.widths.get(col, 12), len(text) + 3)
    residual_maps = []
    for fit in fits:
        residual_maps.append({(float(d), float(z)): float(r)
                              for (d, z), r in zip(fit.samples, fit.residuals_mm, strict=False)})
    d_arr = np.array([s[0] for s in samples], float)
    predictions = [_predict(fit, d_arr) if samples else np.empty(0) for fit in fits]
    first_sample_row = header_row + 1
    for i, (d, z) in enumerate(samples):
        row = first_sample_row + i
        draft.set(row, 1, _cell(d), "0.000")
        draft.set(row, 2, _cell(z), "0.0")
        for k, fit in enumerate(fits):
            draft.set(row, 3 + 2 * k, _cell(predictions[k][i]), "0.0")
            draft.set(row, 4 + 2 * k, _cell(residual_maps[k].get((d, z))), "0.0")
    last_sample_row = first_sample_row + len(samples) - 1

    # fitted curves on a disparity grid, in hidden columns the chart reads
    gcol = max(len(header), len(mheader)) + 2  # right of both tables
    grid_rows = 0
    if fits and samples:
        lo, hi = float(d_arr.min()), float(d_arr.max())
        pad = 0.05 * (hi - lo) if hi > lo else 1.0
        grid = np.linspace(lo - pad, hi + pad, CURVE_POINTS)
        draft.set(header_row, gcol, "Curve disparity (px)", bold=True)
        curves = [_predict(fit, grid) for fit in fits]
        for k, fit in enumerate(fits):
            draft.set(header_row, gcol + 1 + k, f"{fit.model} curve (mm)", bold=True)
        for i, g in enumerate(grid):
            draft.set(first_sample_row + i, gcol, float(g))
            for k in range(len(fits)):
                draft.set(first_sample_row + i, gcol + 1 + k, _cell(curves[k][i]))
        grid_rows = len(grid)
        draft.hidden.update(range(gcol, gcol + 1 + len(fits)))

    if samples:
        chart = ScatterChart()
        chart.title = "Distance against disparity"
        chart.scatterStyle = "lineMarker"  # required by the schema; openpyxl leaves it out otherwise
        chart.x_axis.axPos = "b"
        chart.x_axis.title = "Disparity (px)"
        chart.y_axis.title = "Distance (mm)"
        # recent Excel hides axes openpyxl does not mark as kept, and skips hidden cells by default
        chart.x_axis.delete = False
        chart.y_axis.delete = False
        chart.visible_cells_only = False
        chart.width, chart.height = 16, 10  # cm: fits a portrait page when printed
        chart.legend.position = "b"  # on the right it was cut off at the page's edge
        xs = Reference(ws, min_col=1, min_row=first_sample_row, max_row=last_sample_row)
        ys = Reference(ws, min_col=2, min_row=first_sample_row, max_row=last_sample_row)
        chart.series.append(_sample_series(ys, xs))
        if grid_rows:
            last = first_sample_row + grid_rows - 1
            gx = Reference(ws, min_col=gcol, min_row=first_sample_row, max_row=last)
            for k, fit in enumerate(fits):
                gy = Reference(ws, min_col=gcol + 1 + k, min_row=first_sample_row, max_row=last)
                chart.series.append(_fit_series(gy, gx, f"{fit.model} fit (R^2 {fit.r2:.4f})", k))
        anchor_row = max(last_sample_row, header_row) + 3
        draft.charts.append((chart, f"A{anchor_row}"))
        draft.print_one_page_wide = True  # printed (or made a PDF), the chart is not cut
    draft.to_sheet(ws)


_MATRIX_NOTES = {
    "M1": "left camera matrix (px)",
    "D1": "left distortion (k1 k2 p1 p2 k3 ...)",
    "M2": "right camera matrix (px)",
    "D2": "right distortion (k1 k2 p1 p2 k3 ...)",
    "R": "rotation left to right camera",
    "T": "translation left to right camera (mm)",
    "P1": "left rectified projection (px)",
    "P2": "right rectified projection (px, mm)",
    "Q": "disparity-to-depth (mm)",
}
CALIBRATION_MATRICES = tuple(_MATRIX_NOTES)


def _calibration_figures(calib: StereoCalibration, calib_file: str | None
                         ) -> list[tuple[str, Any, str, float | None]]:
    """(label with unit, value, number format, 1 sigma or None) of the Calibration sheet."""
    u = calib.uncertainty
    board = calib.board
    return [
        ("File", calib_file or "", "@", None),
        ("Created", calib.created, "@", None),
        ("Made", calib.origin, "@", None),
        ("Method", calib.method, "@", None),
        ("Lens model", calib.model, "@", None),
        ("Image width (px)", calib.width, "0", None),
        ("Image height (px)", calib.height, "0", None),
        ("Board", board.label() if board else "", "@", None),
        ("Square (mm)", board.square_mm if board else None, "0.00", None),
        ("RMS left (px)", calib.rms_left, "0.0000", None),
        ("RMS right (px)", calib.rms_right, "0.0000", None),
        ("RMS stereo (px)", calib.rms_stereo, "0.0000", None),
        ("Epipolar error (px)", calib.epipolar_error_px, "0.0000", None),
        ("Baseline (mm)", calib.baseline_mm, "0.00",
         None if u is None else u.baseline_sigma_mm(calib.T)),
        ("Rectified baseline (mm)", calib.rectified_baseline_mm, "0.00", None),
        ("Rectified focal length (px)", calib.focal_px, "0.00", None),
        ("Relative rotation (deg)", calib.relative_rotation_deg, "0.000",
         None if u is None else u.rotation_sigma_deg(calib.R)),
        ("Alpha", calib.alpha, "0.00", None),
    ]


def _camera_rows(calib: StereoCalibration, side: str) -> list[tuple[str, float, float | None]]:
    """(name with unit, value, 1 sigma or None) of one camera's intrinsics and distortion."""
    from stereo_gui.core.lens import distortion_names
    from stereo_gui.core.uncertainty import corner_sigma_px

    M, D = (calib.M1, calib.D1) if side == "left" else (calib.M2, calib.D2)
    M, D = np.asarray(M, float), np.asarray(D, float).reshape(-1)
    u = calib.uncertainty
    rows: list[tuple[str, float, float | None]] = []
    for name, value in (("fx", M[0, 0]), ("fy", M[1, 1]), ("cx", M[0, 2]), ("cy", M[1, 2])):
        rows.append((f"{name} (px)", float(value),
                     None if u is None else u.sigma(f"{side}.{name}")))
    for name, value in zip(distortion_names(calib.model, D.size), D, strict=False):
        rows.append((name, float(value), None if u is None else u.distortion_sigma(side, name)))
    if u is not None:
        rows.append(("lens at the corners (px)", float("nan"), corner_sigma_px(calib, side)))
    return rows


def _write_calibration_sheet(ws, calib: StereoCalibration | None, calib_file: str | None) -> None:
    """The calibration in use: its figures, each camera's parameters, each with its 1-sigma
    uncertainty where the calibration has one, its warnings, the pairs it was not made from,
    each pair's error, and the matrices. Printed landscape, one page wide."""
    draft = _Draft()
    draft.print_one_page_wide = True
    draft.set(1, 1, "Calibration", bold=True)
    if calib is None:
        draft.set(3, 1, "no calibration given")
        draft.to_sheet(ws)
        return
    sigma_note = ("1 sigma: the true value lies within ± 1 sigma about two times in three"
                  if calib.uncertainty is not None else "no uncertainty recorded")
    draft.set(1, 2, sigma_note)
    for j, text in enumerate(("Figure", "Value", "± (1 sigma)")):
        draft.set(3, 1 + j, text, bold=True)
    row = 4
    for label, value, fmt, sigma in _calibration_figures(calib, calib_file):
        draft.set(row, 1, label, bold=True)
        draft.set(row, 2, _cell(value), fmt, wrap=fmt == "@")
        if sigma is not None:
            draft.set(row, 3, _cell(sigma), fmt)
        row += 1
    row += 1
    for side in ("left", "right"):
        draft.set(row, 1, f"{side.capitalize()} camera", bold=True)
        draft.set(row, 2, "Value", bold=True)
        draft.set(row, 3, "± (1 sigma)", bold=True)
        row += 1
        for name, value, sigma in _camera_rows(calib, side):
            draft.set(row, 1, name)
            draft.set(row, 2, _cell(value), "0.000000" if abs(value) < 10 else "0.00")
            draft.set(row, 3, _cell(sigma), "0.000000" if sigma is not None and sigma < 0.1
                      else "0.00")
            row += 1
        row += 1
    draft.set(row, 1, "Warnings", bold=True)
    row += 1
    for w in calib.warnings or ():
        draft.set(row, 1, w.code)
        draft.set(row, 2, w.message, wrap=True)
        row += 1
    if not calib.warnings:
        draft.set(row, 1, "none")
        row += 1
    row += 1
    draft.set(row, 1, "Pairs left out", bold=True)
    draft.set(row, 2, "Why", bold=True)
    row += 1
    for name, why in calib.left_out:
        draft.set(row, 1, name)
        draft.set(row, 2, why, wrap=True)
        row += 1
    if not calib.left_out:
        draft.set(row, 1, "none")
        row += 1
    row += 1
    if calib.per_pair:
        for j, text in enumerate(("Pair", "Error left (px)", "Error right (px)")):
            draft.set(row, 1 + j, text, bold=True)
        for k, pe in enumerate(calib.per_pair):
            draft.set(row + 1 + k, 1, pe.name)
            draft.set(row + 1 + k, 2, _cell(pe.error_left), "0.0000")
            draft.set(row + 1 + k, 3, _cell(pe.error_right), "0.0000")
    draft.widths[1] = 26
    draft.widths[2] = 44
    draft.widths[3] = 17  # wide enough for "Error right (px)"

    # matrices stacked in columns E.., each under a bold label row
    col0 = 5
    r = 3
    for name, note in _MATRIX_NOTES.items():
        m = np.atleast_2d(calib.matrices()[name])
        draft.set(r, col0, name, bold=True)
        draft.set(r, col0 + 1, note)
        for i in range(m.shape[0]):
            for j in range(m.shape[1]):
                draft.set(r + 1 + i, col0 + j, _cell(m[i, j]), "0.000000")
        r += m.shape[0] + 2
    for j in range(5):
        draft.widths[col0 + j] = 14
    draft.to_sheet(ws)


# ---- workbooks ------------------------------------------------------------------------------
def _check_xlsx_name(path: Path) -> None:
    if path.suffix.lower() != ".xlsx":
        raise InputError(f"{path}: a workbook file name must end in .xlsx")


def _new_workbook(records, fits, calibration, calibration_file, target: Path, cancel=None,
                  progress=None):
    from openpyxl import Workbook

    wb = Workbook(write_only=True)  # streamed: linear in the rows
    try:
        # write-only sheets stream their rows into temporary files as they are appended, so a
        # full disk already shows here
        _write_measurements_sheet(wb.create_sheet(MEASUREMENTS_SHEET), records, cancel,
                                  progress)
        fits = tuple(fits or ())
        _write_regression_sheet(wb.create_sheet(REGRESSION_SHEET), _samples(records, fits), fits)
        _write_calibration_sheet(wb.create_sheet(CALIBRATION_SHEET), calibration,
                                 calibration_file)
    except OSError as exc:
        _discard_write_only(wb)
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; "
                         f"{'it was left untouched' if target.exists() else 'nothing was written'}"
                         ) from exc
    except BaseException:  # cancelled: the streamed rows' temporary files go too
        _discard_write_only(wb)
        raise
    wb.properties.keywords = WORKBOOK_KEYWORDS
    wb.properties.creator = "stereo-gui"
    wb.properties.title = "Stereo GUI measurements"
    return wb


def _verify_xlsx(path: Path) -> None:
    """A workbook that does not read back (a torn zip, a member whose CRC fails) is refused."""
    with zipfile.ZipFile(path) as z:
        bad = z.testzip()
    if bad is not None:
        raise ValueError(f"{bad} is damaged")


def _save(wb, path: Path) -> Path:
    try:
        with atomic_path(path, verify=_verify_xlsx) as tmp:
            wb.save(tmp)
    except BaseException:
        _discard_write_only(wb)
        raise
    return path


def _discard_write_only(wb) -> None:
    """After a failed save, close the streamed sheets of a write-only workbook and remove their
    temporary files (left open, they print a traceback when they are collected later)."""
    if not getattr(wb, "write_only", False):
        return
    for ws in wb.worksheets:
        writer = getattr(ws, "_writer", None)
        if writer is None or ws.closed:
            continue
        try:
            ws.close()
        except Exception:  # noqa: BLE001 - best effort after the real error
            log.debug("closing sheet %s after a failed save", ws.title, exc_info=True)
        try:
            writer.cleanup()
        except Exception:  # noqa: BLE001
            log.debug("removing the temporary file of sheet %s", ws.title, exc_info=True)


def write_workbook(path: str | os.PathLike, records: Iterable[MeasurementRecord],
                   fits: Sequence = (), calibration: StereoCalibration | None = None,
                   calibration_file: str | os.PathLike | None = None, cancel=None,
                   progress=None) -> Path:
    """Write a new workbook (replacing `path` atomically) with the three sheets and the chart.

    `fits` are `stereo_gui.core.regression.FitResult`s; `calibration_file` names the file the
    calibration was loaded from (shown in the Calibration sheet). `cancel` (an Event or a
    callable, see core.jobs.Cancel) stops the export between rows with Cancelled: nothing is
    written, no temporary file is left, `path` stays as it was. `progress(done, total, text)`
    is told the rows written.
    """
    path = Path(path)
    _check_xlsx_name(path)
    records = list(records)
    wb = _new_workbook(records, fits, calibration,
                       None if calibration_file is None else str(calibration_file), path,
                       cancel, progress)
    try:
        check_cancel(cancel)
    except BaseException:
        _discard_write_only(wb)
        raise
    _save(wb, path)
    log.info("wrote %d measurements to %s", len(records), path)
    return path


def _load_ours(path: Path):
    """Load an existing workbook of ours, or raise InputError naming what is wrong (untouched)."""
    from openpyxl import load_workbook
    from openpyxl.utils.exceptions import InvalidFileException

    try:
        wb = load_workbook(path)
    except (InvalidFileException, zipfile.BadZipFile, KeyError, ValueError, OSError, TypeError,
            AttributeError, IndexError, EOFError, SyntaxError, zlib.error, RecursionError) as exc:
        # SyntaxError: xml.etree's ParseError on the junk XML of a damaged zip
        raise InputError(f"{path} is not a readable .xlsx workbook ({exc}); "
                         "it was left untouched") from exc
    if MEASUREMENTS_SHEET not in wb.sheetnames:
        raise InputError(f"{path} is not a measurement workbook of stereo-gui (no "
                         f"{MEASUREMENTS_SHEET!r} sheet); it was left untouched")
    ws = wb[MEASUREMENTS_SHEET]
    header = tuple(c.value for c in next(ws.iter_rows(min_row=1, max_row=1)))
    # workbooks written before the time became a date-time cell head it "Time (ISO 8601)"
    n = len(HEADERS)  # the error columns after them are derived; older workbooks lack them
    if header[:n] not in (XLSX_HEADERS[:n], HEADERS):
        raise InputError(f"{path}: the {MEASUREMENTS_SHEET!r} sheet does not have the columns "
                         "stereo-gui writes; it was left untouched")
    return wb


def read_measurements(path: str | os.PathLike) -> list[MeasurementRecord]:
    """The measurement log of a workbook written by `write_workbook` / `append_measurements`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such workbook")
    return _records_in(_load_ours(path), f"{path}, ")


def append_measurements(path: str | os.PathLike, records: Iterable[MeasurementRecord],
                        fits: Sequence | None = None,
                        calibration: StereoCalibration | None = None,
                        calibration_file: str | os.PathLike | None = None) -> int:
    """Append `records` to the workbook at `path`, keeping every earlier row; return the count.

    The workbook is created if missing. `fits` / `calibration`, when given, replace the
    Regression / Calibration sheets; otherwise those sheets stay as they are (a new workbook gets
    samples from the records' true distances). A file that is not a workbook of ours raises
    InputError and is not touched.
    """
    path = Path(path)
    _check_xlsx_name(path)
    records = list(records)
    if not path.exists():
        write_workbook(path, records, fits or (), calibration, calibration_file)
        return len(records)
    wb = _load_ours(path)
    for col, text in enumerate(XLSX_HEADERS, start=1):  # (older workbooks lack the last ones)
        cell = wb[MEASUREMENTS_SHEET].cell(row=1, column=col)
        cell.value = text
        cell.font = _bold()
    n = _append_measurement_rows(wb[MEASUREMENTS_SHEET], records)
    cf = None if calibration_file is None else str(calibration_file)
    if fits is not None:
        all_records = _records_in(wb)
        _replace_sheet(wb, REGRESSION_SHEET, 1,
                       lambda ws: _write_regression_sheet(ws, _samples(all_records, tuple(fits)),
                                                          tuple(fits)))
    if calibration is not None:
        _replace_sheet(wb, CALIBRATION_SHEET, 2,
                       lambda ws: _write_calibration_sheet(ws, calibration, cf))
    _save(wb, path)
    log.info("appended %d measurements to %s", n, path)
    return n


def _records_in(wb, where: str = "") -> list[MeasurementRecord]:
    ws = wb[MEASUREMENTS_SHEET]
    return [_record_from_row(row, f"{where}row {i}")
            for i, row in enumerate(ws.iter_rows(min_row=2, values_only=True), start=2)
            if row and any(v is not None for v in row)]


def _replace_sheet(wb, title: str, index: int, fill) -> None:
    if title in wb.sheetnames:
        index = wb.sheetnames.index(title)
        wb.remove(wb[title])
    fill(wb.create_sheet(title, index))


# ---- CSV ------------------------------------------------------------------------------------
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
        row = []
        decimals[pct] = pct_decimals(rec.true_mm)
        for v, dec in zip(_file_values(rec), decimals, strict=True):
            v = _cell(v)
            if v is None:
                row.append("")
            elif isinstance(v, float):
                row.append(_csv_number(v, dec))
            else:
                row.append(v)
        w.writerow(row)
    return buf.getvalue()


def write_csv(path: str | os.PathLike, records: Iterable[MeasurementRecord]) -> Path:
    """Write the log as a UTF-8 CSV file (atomically)."""
    return write_text_atomic(path, records_to_csv(records))


def read_csv(path: str | os.PathLike) -> list[MeasurementRecord]:
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
    return [_record_from_row(r, f"{path}, line {i}") for i, r in enumerate(rows, start=2) if r]
