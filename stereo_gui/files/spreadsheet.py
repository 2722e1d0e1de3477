"""Measurement logs as real Excel workbooks (openpyxl) and CSV files.

A workbook written here has three sheets:

- **Measurements**: one row per `MeasurementRecord`, units in the headers (see `COLUMNS`).
- **Regression**: the (disparity, true distance) samples with each fitted model's prediction and
  residual, a table of the models (formula, R^2, coefficients), the fitted curves evaluated on a
  disparity grid (hidden columns) and a native Excel scatter chart of distance against disparity:
  samples as markers, each fit as a line. This replaces the report's manual Excel step.
- **Calibration**: the figures (RMS, baseline, board, date) and the matrices M1 D1 M2 D2 R T P1 P2 Q
  as small tables.

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
from collections.abc import Iterable, Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import atomic_path, write_text_atomic
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

    @classmethod
    def from_measurement(cls, m, *, time: str | None = None, true_mm: float | None = None,
                         calibration_file: str | os.PathLike = "",
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
HEADERS = tuple(c[1] for c in COLUMNS)
# derived from each record and written after its columns (readers ignore them): how far Z is
# from the true distance once one was entered
ERROR_COLUMNS: tuple[tuple[str, str, int], ...] = (
    ("Error Z - true (mm)", "0.0", 12), ("Error (%)", "0.00", 10))
ERROR_HEADERS = tuple(c[0] for c in ERROR_COLUMNS)
_FIELD_NAMES = tuple(f.name for f in fields(MeasurementRecord))
assert tuple(c[0] for c in COLUMNS) == _FIELD_NAMES  # the layout covers every field, in order


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


def _record_from_row(values: Sequence[Any], where: str) -> MeasurementRecord:
    kw: dict[str, Any] = {}
    for (name, header, _, _), v in zip(COLUMNS, values, strict=False):
        if name in ("time", "reason", "method", "calibration_file"):
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


def _write_measurements_sheet(ws, records: Iterable[MeasurementRecord]) -> None:
    from openpyxl.utils import get_column_letter

    ws.append(list(HEADERS + ERROR_HEADERS))
    for c in ws[1]:
        c.font = _bold()
    widths = [c[3] for c in COLUMNS] + [c[2] for c in ERROR_COLUMNS]
    for i, width in enumerate(widths, start=1):
        ws.column_dimensions[get_column_letter(i)].width = width
    ws.freeze_panes = "A2"
    _append_measurement_rows(ws, records)


def _append_measurement_rows(ws, records: Iterable[MeasurementRecord]) -> int:
    n = 0
    formats = [c[2] for c in COLUMNS] + [c[1] for c in ERROR_COLUMNS]
    for rec in records:
        ws.append([_cell(v) for v in astuple(rec) + record_error(rec)])
        row = ws.max_row
        for col, fmt in enumerate(formats, start=1):
            ws.cell(row=row, column=col).number_format = fmt
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


def _write_regression_sheet(ws, samples: list[tuple[float, float]], fits: Sequence) -> None:
    from openpyxl.chart import Reference, ScatterChart, Series
    from openpyxl.utils import get_column_letter

    bold = _bold()
    ws["A1"] = "Regression: distance against disparity"
    ws["A1"].font = bold

    # samples table: A disparity, B true distance, then prediction and residual per fit
    header = ["Disparity (px)", "True distance (mm)"]
    for fit in fits:
        header += [f"{fit.model} prediction (mm)", f"{fit.model} residual (mm)"]
    for col, text in enumerate(header, start=1):
        c = ws.cell(row=3, column=col, value=text)
        c.font = bold
        ws.column_dimensions[get_column_letter(col)].width = max(12, len(text) + 2)
    residual_maps = []
    for fit in fits:
        residual_maps.append({(float(d), float(z)): float(r)
                              for (d, z), r in zip(fit.samples, fit.residuals_mm, strict=False)})
    d_arr = np.array([s[0] for s in samples], float)
    predictions = [_predict(fit, d_arr) if samples else np.empty(0) for fit in fits]
    for i, (d, z) in enumerate(samples):
        row = 4 + i
        ws.cell(row=row, column=1, value=_cell(d)).number_format = "0.000"
        ws.cell(row=row, column=2, value=_cell(z)).number_format = "0.0"
        for k, fit in enumerate(fits):
            pc = ws.cell(row=row, column=3 + 2 * k, value=_cell(predictions[k][i]))
            rc = ws.cell(row=row, column=4 + 2 * k, value=_cell(residual_maps[k].get((d, z))))
            pc.number_format = rc.number_format = "0.0"
    first_sample_row, last_sample_row = 4, 3 + len(samples)

    # models table, right of the samples
    mcol = len(header) + 2
    n_coef = max((len(f.coefficients) for f in fits), default=0)
    mheader = ["Model", "Formula", "R^2", "Samples", "RMS residual (mm)"] + [
        f"c{i}" for i in range(n_coef)]
    for j, text in enumerate(mheader):
        c = ws.cell(row=3, column=mcol + j, value=text)
        c.font = bold
    ws.column_dimensions[get_column_letter(mcol)].width = 12
    ws.column_dimensions[get_column_letter(mcol + 1)].width = 48
    for k, fit in enumerate(fits):
        row = 4 + k
        res = np.asarray(fit.residuals_mm, float)
        rms = float(np.sqrt(np.mean(res**2))) if res.size else float("nan")
        values = [fit.model, fit.formula(), _cell(fit.r2), len(fit.samples), _cell(rms)]
        values += [_cell(c) for c in fit.coefficients]
        for j, v in enumerate(values):
            ws.cell(row=row, column=mcol + j, value=v)
        ws.cell(row=row, column=mcol + 2).number_format = "0.00000"
        ws.cell(row=row, column=mcol + 4).number_format = "0.00"
    if not fits:
        ws.cell(row=4, column=mcol, value="no fit yet: enter true distances for at least "
                                          "a few measurements and fit a model")

    # fitted curves on a disparity grid, in hidden columns the chart reads
    gcol = mcol + len(mheader) + 1
    grid_rows = 0
    if fits and samples:
        lo, hi = float(d_arr.min()), float(d_arr.max())
        pad = 0.05 * (hi - lo) if hi > lo else 1.0
        grid = np.linspace(lo - pad, hi + pad, CURVE_POINTS)
        ws.cell(row=3, column=gcol, value="Curve disparity (px)").font = bold
        curves = [_predict(fit, grid) for fit in fits]
        for k, fit in enumerate(fits):
            ws.cell(row=3, column=gcol + 1 + k, value=f"{fit.model} curve (mm)").font = bold
        for i, g in enumerate(grid):
            ws.cell(row=4 + i, column=gcol, value=float(g))
            for k in range(len(fits)):
                ws.cell(row=4 + i, column=gcol + 1 + k, value=_cell(curves[k][i]))
        grid_rows = len(grid)
        for c in range(gcol, gcol + 1 + len(fits)):
            ws.column_dimensions[get_column_letter(c)].hidden = True

    if not samples:
        return
    chart = ScatterChart()
    chart.title = "Distance against disparity"
    chart.style = 13
    chart.scatterStyle = "lineMarker"  # required by the schema; openpyxl leaves it out otherwise
    chart.x_axis.axPos = "b"
    chart.x_axis.title = "Disparity (px)"
    chart.y_axis.title = "Distance (mm)"
    # recent Excel hides axes openpyxl does not mark as kept, and skips hidden cells by default
    chart.x_axis.delete = False
    chart.y_axis.delete = False
    chart.visible_cells_only = False
    chart.width, chart.height = 18, 10
    xs = Reference(ws, min_col=1, min_row=first_sample_row, max_row=last_sample_row)
    ys = Reference(ws, min_col=2, min_row=first_sample_row, max_row=last_sample_row)
    s = Series(ys, xs, title="Samples (true distance)")
    s.marker.symbol = "circle"
    s.marker.size = 7
    s.graphicalProperties.line.noFill = True
    chart.series.append(s)
    if grid_rows:
        gx = Reference(ws, min_col=gcol, min_row=4, max_row=3 + grid_rows)
        for k, fit in enumerate(fits):
            gy = Reference(ws, min_col=gcol + 1 + k, min_row=4, max_row=3 + grid_rows)
            line = Series(gy, gx, title=f"{fit.model} fit (R^2 {fit.r2:.4f})")
            line.marker.symbol = "none"
            line.smooth = True
            chart.series.append(line)
    anchor_row = max(last_sample_row, 3 + len(fits)) + 3
    ws.add_chart(chart, f"A{anchor_row}")


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


def _write_calibration_sheet(ws, calib: StereoCalibration | None, calib_file: str | None) -> None:
    from openpyxl.utils import get_column_letter

    bold = _bold()
    ws["A1"] = "Calibration"
    ws["A1"].font = bold
    if calib is None:
        ws["A3"] = "no calibration given"
        return
    board = calib.board
    figures: list[tuple[str, Any, str]] = [
        ("File", calib_file or "", "@"),
        ("Created", calib.created, "@"),
        ("Method", calib.method, "@"),
        ("Image width (px)", calib.width, "0"),
        ("Image height (px)", calib.height, "0"),
        ("Board (inner corners)", f"{board.cols}x{board.rows}" if board else "", "@"),
        ("Square (mm)", board.square_mm if board else None, "0.00"),
        ("RMS left (px)", calib.rms_left, "0.0000"),
        ("RMS right (px)", calib.rms_right, "0.0000"),
        ("RMS stereo (px)", calib.rms_stereo, "0.0000"),
        ("Epipolar error (px)", calib.epipolar_error_px, "0.0000"),
        ("Baseline (mm)", calib.baseline_mm, "0.00"),
        ("Rectified baseline (mm)", calib.rectified_baseline_mm, "0.00"),
        ("Rectified focal length (px)", calib.focal_px, "0.00"),
        ("Relative rotation (deg)", calib.relative_rotation_deg, "0.000"),
        ("Alpha", calib.alpha, "0.00"),
    ]
    for i, (label, value, fmt) in enumerate(figures):
        ws.cell(row=3 + i, column=1, value=label).font = bold
        ws.cell(row=3 + i, column=2, value=_cell(value)).number_format = fmt
    ws.column_dimensions["A"].width = 26
    ws.column_dimensions["B"].width = 28
    row = 3 + len(figures) + 1
    if calib.per_pair:
        for j, text in enumerate(("Pair", "Error left (px)", "Error right (px)")):
            ws.cell(row=row, column=1 + j, value=text).font = bold
        for k, pe in enumerate(calib.per_pair):
            ws.cell(row=row + 1 + k, column=1, value=pe.name)
            ws.cell(row=row + 1 + k, column=2, value=_cell(pe.error_left)).number_format = "0.0000"
            ws.cell(row=row + 1 + k, column=3, value=_cell(pe.error_right)).number_format = "0.0000"

    # matrices stacked in columns E.., each under a bold label row
    col0 = 5
    r = 3
    for name, note in _MATRIX_NOTES.items():
        m = np.atleast_2d(np.asarray(getattr(calib, name), float))
        ws.cell(row=r, column=col0, value=name).font = bold
        ws.cell(row=r, column=col0 + 1, value=note)
        for i in range(m.shape[0]):
            for j in range(m.shape[1]):
                c = ws.cell(row=r + 1 + i, column=col0 + j, value=_cell(m[i, j]))
                c.number_format = "0.000000"
        r += m.shape[0] + 2
    for j in range(5):
        ws.column_dimensions[get_column_letter(col0 + j)].width = 14


# ---- workbooks ------------------------------------------------------------------------------
def _check_xlsx_name(path: Path) -> None:
    if path.suffix.lower() != ".xlsx":
        raise InputError(f"{path}: a workbook file name must end in .xlsx")


def _new_workbook(records, fits, calibration, calibration_file):
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.title = MEASUREMENTS_SHEET
    _write_measurements_sheet(ws, records)
    fits = tuple(fits or ())
    _write_regression_sheet(wb.create_sheet(REGRESSION_SHEET), _samples(records, fits), fits)
    _write_calibration_sheet(wb.create_sheet(CALIBRATION_SHEET), calibration, calibration_file)
    wb.properties.keywords = WORKBOOK_KEYWORDS
    wb.properties.creator = "stereo-gui"
    wb.properties.title = "Stereo GUI measurements"
    return wb


def _save(wb, path: Path) -> Path:
    with atomic_path(path) as tmp:
        wb.save(tmp)
    return path


def write_workbook(path: str | os.PathLike, records: Iterable[MeasurementRecord],
                   fits: Sequence = (), calibration: StereoCalibration | None = None,
                   calibration_file: str | os.PathLike | None = None) -> Path:
    """Write a new workbook (replacing `path` atomically) with the three sheets and the chart.

    `fits` are `stereo_gui.core.regression.FitResult`s; `calibration_file` names the file the
    calibration was loaded from (shown in the Calibration sheet).
    """
    path = Path(path)
    _check_xlsx_name(path)
    records = list(records)
    wb = _new_workbook(records, fits, calibration,
                       None if calibration_file is None else str(calibration_file))
    _save(wb, path)
    log.info("wrote %d measurements to %s", len(records), path)
    return path


def _load_ours(path: Path):
    """Load an existing workbook of ours, or raise InputError naming what is wrong (untouched)."""
    from openpyxl import load_workbook
    from openpyxl.utils.exceptions import InvalidFileException

    try:
        wb = load_workbook(path)
    except (InvalidFileException, zipfile.BadZipFile, KeyError, ValueError, OSError) as exc:
        raise InputError(f"{path} is not a readable .xlsx workbook ({exc}); "
                         "it was left untouched") from exc
    if MEASUREMENTS_SHEET not in wb.sheetnames:
        raise InputError(f"{path} is not a measurement workbook of stereo-gui (no "
                         f"{MEASUREMENTS_SHEET!r} sheet); it was left untouched")
    ws = wb[MEASUREMENTS_SHEET]
    header = tuple(c.value for c in next(ws.iter_rows(min_row=1, max_row=1)))
    if header[: len(HEADERS)] != HEADERS:
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
def records_to_csv(records: Iterable[MeasurementRecord]) -> str:
    """The log as CSV text: a header with units, one row per record; empty where no number."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADERS + ERROR_HEADERS)
    for rec in records:
        row = []
        for v in astuple(rec) + record_error(rec):
            v = _cell(v)
            row.append("" if v is None else repr(v) if isinstance(v, float) else v)
        w.writerow(row)
    return buf.getvalue()


def write_csv(path: str | os.PathLike, records: Iterable[MeasurementRecord]) -> Path:
    """Write the log as a UTF-8 CSV file (atomically)."""
    return write_text_atomic(path, records_to_csv(records))


def read_csv(path: str | os.PathLike) -> list[MeasurementRecord]:
    """Read a CSV file written by `write_csv` (with the error columns or, older, without)."""
    try:
        rows = read_csv_rows(path, HEADERS + ERROR_HEADERS, "a measurement CSV of stereo-gui")
    except InputError:
        rows = read_csv_rows(path, HEADERS, "a measurement CSV of stereo-gui")
    return [_record_from_row(r, f"{path}, line {i}") for i, r in enumerate(rows, start=2) if r]
