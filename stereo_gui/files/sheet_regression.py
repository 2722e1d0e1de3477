"""The Regression sheet: the (disparity, true distance) samples with each fitted model's
prediction and residual, a table of the models (formula, R^2, coefficients), the fitted curves
evaluated on a disparity grid (hidden columns) and a native Excel scatter chart of distance
against disparity: samples as markers, each fit as a line."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from openpyxl.chart import Reference, ScatterChart, Series
from openpyxl.chart.shapes import GraphicalProperties
from openpyxl.drawing.line import LineProperties

from stereo_gui.core.regression import FitResult
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.sheet_columns import cell_value
from stereo_gui.files.sheet_draft import Sheet, SheetDraft

CURVE_POINTS = 60  # points of each fitted curve drawn in the chart


def _predict(fit: FitResult, d: NDArray[np.float64]) -> NDArray[np.float64]:
    """The fit evaluated on disparities `d` (px), mm (element by element if it takes scalars)."""
    try:
        out = np.asarray(fit.predict(d), dtype=np.float64)
        if out.shape == d.shape:
            return out
    except (TypeError, ValueError):
        pass
    return np.array([float(fit.predict(float(x))) for x in d], dtype=np.float64)


def regression_samples(records: Sequence[MeasurementRecord],
                       fits: Sequence[FitResult]) -> list[tuple[float, float]]:
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


def _sample_series(ys: Reference, xs: Reference) -> Series:
    s = Series(ys, xs, title="Samples (true distance)")
    s.marker.symbol = "circle"
    s.marker.size = 7
    s.marker.graphicalProperties = GraphicalProperties(
        solidFill=SAMPLE_COLOUR, ln=LineProperties(solidFill=SAMPLE_COLOUR))
    s.graphicalProperties.line.noFill = True
    return s


def _fit_series(ys: Reference, xs: Reference, title: str, k: int) -> Series:
    colour, dash, width = FIT_STYLES[k % len(FIT_STYLES)]
    line = Series(ys, xs, title=title)
    line.marker.symbol = "none"
    line.smooth = True
    line.graphicalProperties.line.solidFill = colour
    line.graphicalProperties.line.width = width
    line.graphicalProperties.line.prstDash = dash
    return line



def _models_table(draft: SheetDraft, fits: Sequence[FitResult]) -> tuple[list[str], int]:
    """The models from row 3: a header, one row per fit, then each model's formula on a row of
    its own, where it runs across the empty cells to its right. Returns the header and the first
    row below."""
    n_coef = max((len(f.coefficients) for f in fits), default=0)
    mheader = ["Model", "R^2", "Samples", "RMS residual (mm)"] + [f"c{i}" for i in range(n_coef)]
    for j, text in enumerate(mheader):
        draft.set(3, 1 + j, text, bold=True)
    for k, fit in enumerate(fits):
        res = np.asarray(fit.residuals_mm, float)
        rms = float(np.sqrt(np.mean(res**2))) if res.size else float("nan")
        values = [fit.model, cell_value(fit.r2), len(fit.samples), cell_value(rms)]
        values += [cell_value(c) for c in fit.coefficients]
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
    return mheader, row


def _samples_table(draft: SheetDraft, header_row: int, samples: list[tuple[float, float]],
                   fits: Sequence[FitResult]) -> list[str]:
    """Under a header at `header_row`: A disparity, B true distance, then prediction and
    residual per fit, one row per sample. Returns the header."""
    header = ["Disparity (px)", "True distance (mm)"]
    for fit in fits:
        header += [f"{fit.model} prediction (mm)", f"{fit.model} residual (mm)"]
    for col, text in enumerate(header, start=1):
        draft.set(header_row, col, text, bold=True)
    residual_maps = []
    for fit in fits:
        residual_maps.append({(float(d), float(z)): float(r)
                              for (d, z), r in zip(fit.samples, fit.residuals_mm, strict=False)})
    d_arr = np.array([s[0] for s in samples], float)
    predictions = [_predict(fit, d_arr) if samples else np.empty(0) for fit in fits]
    for i, (d, z) in enumerate(samples):
        row = header_row + 1 + i
        draft.set(row, 1, cell_value(d), "0.000")
        draft.set(row, 2, cell_value(z), "0.0")
        for k, _fit in enumerate(fits):
            draft.set(row, 3 + 2 * k, cell_value(predictions[k][i]), "0.0")
            draft.set(row, 4 + 2 * k, cell_value(residual_maps[k].get((d, z))), "0.0")
    return header


def _curves(draft: SheetDraft, header_row: int, gcol: int, samples: list[tuple[float, float]],
            fits: Sequence[FitResult]) -> int:
    """The fitted curves on a disparity grid over the samples, from column `gcol` in hidden
    columns the chart reads; returns the grid's rows (0 without fits or samples)."""
    if not (fits and samples):
        return 0
    d_arr = np.array([s[0] for s in samples], float)
    lo, hi = float(d_arr.min()), float(d_arr.max())
    pad = 0.05 * (hi - lo) if hi > lo else 1.0
    grid = np.linspace(lo - pad, hi + pad, CURVE_POINTS)
    draft.set(header_row, gcol, "Curve disparity (px)", bold=True)
    curves = [_predict(fit, grid) for fit in fits]
    for k, fit in enumerate(fits):
        draft.set(header_row, gcol + 1 + k, f"{fit.model} curve (mm)", bold=True)
    for i, g in enumerate(grid):
        draft.set(header_row + 1 + i, gcol, float(g))
        for k in range(len(fits)):
            draft.set(header_row + 1 + i, gcol + 1 + k, cell_value(curves[k][i]))
    draft.hidden.update(range(gcol, gcol + 1 + len(fits)))
    return len(grid)


def _chart(ws: Sheet, first_row: int, last_row: int, gcol: int, grid_rows: int,
           fits: Sequence[FitResult]) -> ScatterChart:
    """The scatter chart: the samples (columns A and B, `first_row` to `last_row`) as markers,
    each fit's curve (from column `gcol`) as a line."""
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
    xs = Reference(ws, min_col=1, min_row=first_row, max_row=last_row)
    ys = Reference(ws, min_col=2, min_row=first_row, max_row=last_row)
    chart.series.append(_sample_series(ys, xs))
    if grid_rows:
        last = first_row + grid_rows - 1
        gx = Reference(ws, min_col=gcol, min_row=first_row, max_row=last)
        for k, fit in enumerate(fits):
            gy = Reference(ws, min_col=gcol + 1 + k, min_row=first_row, max_row=last)
            chart.series.append(_fit_series(gy, gx, f"{fit.model} fit (R^2 {fit.r2:.4f})", k))
    return chart


def write_regression_sheet(ws: Sheet, samples: list[tuple[float, float]],
                           fits: Sequence[FitResult]) -> None:
    draft = SheetDraft()
    draft.set(1, 1, "Regression: distance against disparity", bold=True)
    # the models first, then the samples below them: one page wide when printed (the models
    # beside the samples made the sheet too wide to read on paper)
    mheader, row = _models_table(draft, fits)
    header_row = row + 1
    header = _samples_table(draft, header_row, samples, fits)
    for table in (header, mheader):  # each column as wide as the wider of its two headers
        for col, text in enumerate(table, start=1):
            draft.widths[col] = max(draft.widths.get(col, 12), len(text) + 3)
    gcol = max(len(header), len(mheader)) + 2  # right of both tables
    grid_rows = _curves(draft, header_row, gcol, samples, fits)
    if samples:
        first_sample_row = header_row + 1
        last_sample_row = first_sample_row + len(samples) - 1
        chart = _chart(ws, first_sample_row, last_sample_row, gcol, grid_rows, fits)
        anchor_row = max(last_sample_row, header_row) + 3
        draft.charts.append((chart, f"A{anchor_row}"))
        draft.print_one_page_wide = True  # printed (or made a PDF), the chart is not cut
    draft.to_sheet(ws)
