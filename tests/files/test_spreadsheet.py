"""Spreadsheets: every sheet read back with openpyxl, the chart, appending, atomic writes (the
CSV file alone: test_measurement_csv.py)."""

from __future__ import annotations

import datetime as _dt
import math
import re
import zipfile
from dataclasses import astuple, replace
from pathlib import Path

import numpy as np
import openpyxl
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.files import sheet_calibration, sheet_regression, workbook
from stereo_gui.files import spreadsheet as ss
from stereo_gui.files.spreadsheet import (
    HEADERS,
    MeasurementRecord,
    append_measurements,
    read_csv,
    read_measurements,
    write_csv,
    write_workbook,
)

from factories import make_calibration, make_record, make_records

REL = 1e-15  # openpyxl writes 16 significant digits (Excel keeps 15)


# ---- fits ------------------------------------------------------------------------------------
def _make_fits(samples):
    """Both models fitted to `samples` [(disparity px, true mm)] by the application's regression."""
    from stereo_gui.core import regression

    return [regression.fit(m, samples) for m in regression.MODELS]


# ---- data ----------------------------------------------------------------------------------
def _samples(records):
    return [(r.disparity_px, r.true_mm) for r in records if r.true_mm is not None]


def _same(a: MeasurementRecord, b: MeasurementRecord) -> bool:
    for x, y in zip(astuple(a), astuple(b), strict=True):
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            continue
        if isinstance(x, float) and isinstance(y, float):
            if not math.isclose(x, y, rel_tol=REL):
                return False
        elif x != y:
            return False
    return True


def _charts(path: Path) -> list[str]:
    """The XML of each chart in a workbook file, read from the file itself."""
    with zipfile.ZipFile(path) as z:
        names = sorted(n for n in z.namelist() if re.fullmatch(r"xl/charts/chart\d+\.xml", n))
        return [z.read(n).decode() for n in names]


def _series(chart_xml: str) -> list[str]:
    """The XML of each series of a chart."""
    return re.findall(r"<(?:c:)?ser>.*?</(?:c:)?ser>", chart_xml, re.S)


def _no_temp_files(folder: Path) -> bool:
    return not [p for p in folder.iterdir() if p.name.startswith(".")]


# ---- Measurements ----------------------------------------------------------------------------
def test_measurements_sheet_holds_what_was_written(tmp_path):
    recs = make_records()
    path = write_workbook(tmp_path / "log.xlsx", recs, _make_fits(_samples(recs)),
                          make_calibration(), calibration_file="/data/calib.yaml")
    wb = openpyxl.load_workbook(path)
    assert wb.sheetnames == ["Measurements", "Regression", "Calibration"]
    ws = wb["Measurements"]
    header = [c.value for c in ws[1]]
    assert tuple(header) == ss.XLSX_HEADERS
    assert header[0] == "Time (UTC)" and header[-1] == "Note"
    assert header[-1 - len(ss.ERROR_HEADERS):-1] == list(ss.ERROR_HEADERS)
    assert "Disparity (px)" in header and "Z (mm)" in header and "True distance (mm)" in header
    assert ws.max_row == 1 + len(recs)
    for row, rec in zip(ws.iter_rows(min_row=2, values_only=True), recs, strict=True):
        # the time is a real date-time cell (UTC, naive: Excel has no time zones)
        assert row[0] == _dt.datetime.fromisoformat(rec.time).replace(tzinfo=None)
        for value, expected in zip(row[1:len(HEADERS)], astuple(rec)[1:len(HEADERS)],
                                   strict=True):
            if isinstance(expected, float) and math.isnan(expected) or expected in ("", None):
                assert value is None  # Excel has no NaN: an empty cell
            elif isinstance(expected, float):
                assert value == pytest.approx(expected, rel=REL)
            else:
                assert value == expected
    # number formats and units
    col = header.index("Z (mm)") + 1
    assert ws.cell(row=2, column=col).number_format == "0.0"
    col = header.index("Valid fraction") + 1
    assert ws.cell(row=2, column=col).number_format == "0.0%"
    assert ws.cell(row=2, column=1).is_date
    assert ws.cell(row=2, column=1).number_format == "yyyy-mm-dd hh:mm:ss.000"
    assert wb.properties.keywords == workbook.WORKBOOK_KEYWORDS


def test_times_in_other_zones_and_with_milliseconds_become_utc_date_times(tmp_path):
    recs = [replace(make_record(1), time="2026-11-22T11:30:05.250+01:00"),
            replace(make_record(2), time="2026-11-22T10:30:06Z")]
    path = write_workbook(tmp_path / "log.xlsx", recs)
    ws = openpyxl.load_workbook(path)["Measurements"]
    assert ws["A2"].value == _dt.datetime(2026, 11, 22, 10, 30, 5, 250000)
    assert ws["A3"].value == _dt.datetime(2026, 11, 22, 10, 30, 6)
    back = read_measurements(path)
    assert [r.time for r in back] == ["2026-11-22T10:30:05.250+00:00",
                                      "2026-11-22T10:30:06+00:00"]


def test_a_workbook_with_text_times_from_before_is_read_and_appended_to(tmp_path):
    """Workbooks written before the time became a date-time cell head it 'Time (ISO 8601)'."""
    path = tmp_path / "old.xlsx"
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "Measurements"
    ws.append(list(HEADERS))
    old = make_record(0)
    ws.append([None if isinstance(v, float) and math.isnan(v) else v for v in astuple(old)])
    wb.save(path)
    append_measurements(path, [make_record(1)])
    back = read_measurements(path)
    assert [r.time for r in back] == [old.time, make_record(1).time]
    ws = openpyxl.load_workbook(path)["Measurements"]
    assert ws["A1"].value == "Time (UTC)" and isinstance(ws["A3"].value, _dt.datetime)


def test_a_long_append_lands_every_row_once_below_the_earlier_ones(tmp_path):
    """A thousand readings appended at once to a short log: each lands once, in order, under
    the rows already there, and the workbook still holds its other sheets. (Appending reads the
    sheet's size once: asked per row, a 20,000-row append took minutes.)"""
    path = tmp_path / "log.xlsx"
    first = make_records(3)
    write_workbook(path, first, calibration=make_calibration())
    more = [replace(make_record(i % 10), time=f"2026-11-23T{i // 3600:02d}:{i // 60 % 60:02d}:"
                    f"{i % 60:02d}+00:00") for i in range(1000)]
    assert append_measurements(path, more) == len(more)
    back = read_measurements(path)
    assert len(back) == len(first) + len(more)
    assert all(_same(a, b) for a, b in zip(back, first + more, strict=True))
    assert openpyxl.load_workbook(path).sheetnames == ["Measurements", "Regression", "Calibration"]


def test_new_workbooks_are_streamed_in_write_only_mode(tmp_path, monkeypatch):
    made = []
    real_init = openpyxl.Workbook.__init__

    def init(self, *a, **kw):
        real_init(self, *a, **kw)
        made.append(self.write_only)

    monkeypatch.setattr(openpyxl.Workbook, "__init__", init)
    write_workbook(tmp_path / "log.xlsx", make_records(3), calibration=make_calibration())
    assert made == [True]


def test_read_measurements_round_tripsmake_records(tmp_path):
    recs = make_records()
    write_workbook(tmp_path / "log.xlsx", recs)
    back = read_measurements(tmp_path / "log.xlsx")
    assert len(back) == len(recs)
    assert all(_same(a, b) for a, b in zip(back, recs, strict=True))
    assert back[-1].valid is False and back[-1].reason == "no valid pixels"
    assert back[0].true_mm is not None and recs[0].true_mm == back[0].true_mm


# ---- Regression and chart --------------------------------------------------------------------
def test_regression_sheet_and_native_chart(tmp_path):
    recs = make_records()
    fits = _make_fits(_samples(recs))
    write_workbook(tmp_path / "log.xlsx", recs, fits)
    ws = openpyxl.load_workbook(tmp_path / "log.xlsx")["Regression"]
    rows = list(ws.iter_rows(values_only=True))
    # the models first: R^2, samples, RMS and coefficients, then each formula on a row of its own
    assert rows[2][:4] == ("Model", "R^2", "Samples", "RMS residual (mm)")
    for k, fit in enumerate(fits):
        assert rows[3 + k][0] == fit.model and rows[3 + k][1] == pytest.approx(fit.r2)
        assert rows[3 + len(fits) + k][:2] == (f"{fit.model} formula", fit.formula())
    # then the samples with each fit's prediction and residual
    h = next(i for i, r in enumerate(rows) if r[0] == "Disparity (px)")
    header = rows[h]
    assert header[:2] == ("Disparity (px)", "True distance (mm)")
    samples = _samples(recs)
    for i, (d, z) in enumerate(samples):
        assert rows[h + 1 + i][:2] == pytest.approx((d, z), rel=REL)
    for k, fit in enumerate(fits):
        coefs = list(rows[3 + k][4:4 + len(fit.coefficients)])
        assert coefs == pytest.approx(list(fit.coefficients))
        rcol = header.index(f"{fit.model} residual (mm)")
        pcol = header.index(f"{fit.model} prediction (mm)")
        for i, (d, z) in enumerate(samples):
            assert rows[h + 1 + i][rcol] == pytest.approx(fit.residuals_mm[i])
            assert rows[h + 1 + i][pcol] == pytest.approx(float(fit.predict(np.array([d]))[0]))
    assert 0.99 < fits[1].r2 <= 1.0

    # the curve grid lives in hidden columns and holds each fit's prediction
    gcol = header.index("Curve disparity (px)")
    from openpyxl.utils import get_column_letter

    assert ws.column_dimensions[get_column_letter(gcol + 1)].hidden
    grid_rows = rows[h + 1:h + 1 + sheet_regression.CURVE_POINTS]
    grid = np.array([r[gcol] for r in grid_rows], float)
    assert grid.min() < min(s[0] for s in samples) and grid.max() > max(s[0] for s in samples)
    for k, fit in enumerate(fits):
        curve = np.array([r[gcol + 1 + k] for r in grid_rows], float)
        np.testing.assert_allclose(curve, fit.predict(grid), rtol=1e-9)

    # a native scatter chart: samples as markers plus one line per fit
    (xml,) = _charts(tmp_path / "log.xlsx")
    series = _series(xml)
    assert re.search(r"<(?:c:)?scatterChart>", xml) and len(series) == 1 + len(fits)
    assert '<symbol val="circle"' in series[0]
    # the chart's references point at the sample cells
    first = f"${h + 2}"  # the first sample's row (1-based)
    assert re.search(rf"<(?:c:)?xVal>.*?'Regression'!\$A\{first}:", series[0], re.S)
    assert re.search(rf"<(?:c:)?yVal>.*?'Regression'!\$B\{first}:", series[0], re.S)
    assert xml.count('<symbol val="none"') == len(fits)
    assert xml.count('<symbol val="circle"') == 1
    # the hidden curve columns are still drawn
    assert '<plotVisOnly val="0"' in xml and "<scatterStyle" in xml


def test_chart_markers_and_fit_lines_have_colours_of_their_own(tmp_path):
    """LibreOffice ignores Excel's chart style: without explicit colours the samples were white
    markers on white and both fits similar greens."""
    recs = make_records()
    fits = _make_fits(_samples(recs))
    write_workbook(tmp_path / "log.xlsx", recs, fits)
    (xml,) = _charts(tmp_path / "log.xlsx")
    series = _series(xml)
    assert len(series) == 1 + len(fits)
    marker = re.search(r"<(?:c:)?marker>.*?</(?:c:)?marker>", series[0], re.S).group(0)
    assert f'srgbClr val="{sheet_regression.SAMPLE_COLOUR}"' in marker  # a filled, dark marker
    assert sheet_regression.SAMPLE_COLOUR.upper() not in ("FFFFFF",)
    colours, dashes = [], []
    for ser in series[1:]:
        colours.append(re.search(r'<a:ln[^>]*>.*?srgbClr val="([0-9A-F]{6})"', ser, re.S).group(1))
        dashes.append(re.search(r'prstDash val="(\w+)"', ser).group(1))
    assert len(set(colours)) == len(fits) and len(set(dashes)) == len(fits)
    assert sheet_regression.SAMPLE_COLOUR not in colours


def test_samples_without_fits_come_from_true_distances(tmp_path):
    recs = make_records(3)
    write_workbook(tmp_path / "log.xlsx", recs)
    ws = openpyxl.load_workbook(tmp_path / "log.xlsx")["Regression"]
    rows = list(ws.iter_rows(max_col=2, values_only=True))
    h = next(i for i, r in enumerate(rows) if r[0] == "Disparity (px)")
    got = [v for r in rows[h + 1:] if r[0] is not None for v in r]
    assert got == pytest.approx([v for s in _samples(recs) for v in s], rel=REL)
    (xml,) = _charts(tmp_path / "log.xlsx")
    assert len(_series(xml)) == 1


# ---- Calibration -----------------------------------------------------------------------------
def test_calibration_sheet_holds_matrices_and_figures(tmp_path):
    calib = make_calibration(created="2026-11-22T09:00:00+00:00")
    write_workbook(tmp_path / "log.xlsx", [], calibration=calib, calibration_file="/x/calib.yaml")
    ws = openpyxl.load_workbook(tmp_path / "log.xlsx")["Calibration"]
    figures = {r[0]: r[1] for r in ws.iter_rows(min_row=3, max_col=2, values_only=True) if r[0]}
    assert figures["File"] == "/x/calib.yaml"
    assert figures["RMS stereo (px)"] == pytest.approx(calib.rms_stereo)
    assert figures["RMS left (px)"] == pytest.approx(calib.rms_left)
    assert figures["Baseline (mm)"] == pytest.approx(calib.baseline_mm)
    assert figures["Board"] == BoardSpec(9, 6, 24.5).label()
    assert figures["Square (mm)"] == 24.5
    assert figures["Created"] == "2026-11-22T09:00:00+00:00"
    assert figures["chessboard-1"] == pytest.approx(0.1)

    # matrices in column E, each under its name
    col_e = [c.value for c in ws["E"]]
    for name in sheet_calibration.CALIBRATION_MATRICES:
        expected = np.atleast_2d(getattr(calib, name))
        r0 = col_e.index(name) + 2  # 1-based row of the first matrix row
        got = np.array([[ws.cell(row=r0 + i, column=5 + j).value for j in range(expected.shape[1])]
                        for i in range(expected.shape[0])], float)
        np.testing.assert_allclose(got, expected, rtol=REL, atol=0, err_msg=name)


# ---- appending -------------------------------------------------------------------------------
def test_append_creates_then_keeps_every_earlier_row(tmp_path):
    path = tmp_path / "log.xlsx"
    recs = make_records(4)
    assert append_measurements(path, recs[:2]) == 2
    assert append_measurements(path, recs[2:3]) == 1
    assert append_measurements(path, recs[3:]) == len(recs) - 3
    back = read_measurements(path)
    assert len(back) == len(recs)
    assert all(_same(a, b) for a, b in zip(back, recs, strict=True))
    assert _no_temp_files(tmp_path)


def test_append_keeps_chart_and_calibration_and_can_refresh_the_fits(tmp_path):
    path = tmp_path / "log.xlsx"
    recs = make_records()
    fits = _make_fits(_samples(recs))
    write_workbook(path, recs[:3], fits, make_calibration())
    append_measurements(path, recs[3:])
    wb = openpyxl.load_workbook(path)
    assert wb.sheetnames == ["Measurements", "Regression", "Calibration"]
    assert len(_charts(path)) == 1
    assert wb["Calibration"]["A1"].value == "Calibration"
    assert wb["Measurements"].max_row == 1 + len(recs)
    # new fits replace the Regression sheet, the log stays
    append_measurements(path, [], fits=fits[:1])
    wb = openpyxl.load_workbook(path)
    assert wb.sheetnames == ["Measurements", "Regression", "Calibration"]
    (xml,) = _charts(path)
    assert len(_series(xml)) == 2
    assert len(read_measurements(path)) == len(recs)


@pytest.mark.parametrize("kind", ["text", "other_workbook", "other_columns"])
def test_append_refuses_files_that_are_not_ours_and_leaves_them_alone(tmp_path, kind):
    path = tmp_path / "data.xlsx"
    if kind == "text":
        path.write_text("not a workbook")
    else:
        wb = openpyxl.Workbook()
        ws = wb.active
        ws.title = "Measurements" if kind == "other_columns" else "Budget"
        ws.append(["Item", "Cost"])
        wb.save(path)
    before = path.read_bytes()
    with pytest.raises(InputError, match="data.xlsx"):
        append_measurements(path, make_records(1))
    assert path.read_bytes() == before
    assert _no_temp_files(tmp_path)


def test_non_xlsx_name_is_refused(tmp_path):
    with pytest.raises(InputError, match=r"\.xlsx"):
        write_workbook(tmp_path / "log.xls", make_records(1))


# ---- interrupted writes ----------------------------------------------------------------------
def _failing_save(exc):
    def save(self, filename):
        Path(filename).write_bytes(b"PK\x03\x04 half a zip file")  # partial data, then the crash
        raise exc

    return save


@pytest.mark.parametrize("exc", [RuntimeError("crash mid-write"),
                                 OSError(28, "No space left on device")])
@pytest.mark.parametrize("how", ["write", "append"])
def test_interrupted_write_leaves_the_old_file_intact(tmp_path, monkeypatch, exc, how):
    path = tmp_path / "log.xlsx"
    write_workbook(path, make_records(2), calibration=make_calibration())
    before = path.read_bytes()
    monkeypatch.setattr(openpyxl.Workbook, "save", _failing_save(exc))
    expected = InputError if isinstance(exc, OSError) else RuntimeError
    with pytest.raises(expected):
        if how == "write":
            write_workbook(path, make_records(5))
        else:
            append_measurements(path, make_records(5))
    assert path.read_bytes() == before
    assert _no_temp_files(tmp_path)
    monkeypatch.undo()
    assert len(read_measurements(path)) == len(make_records(2))


def test_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        write_workbook(tmp_path / "nowhere" / "log.xlsx", make_records(1))


def test_a_cancelled_export_writes_nothing_and_leaves_no_temporary_file(tmp_path):
    from stereo_gui.core.detect import Cancelled

    path = tmp_path / "log.xlsx"
    path.write_bytes(b"the earlier export")
    records = [make_record(i) for i in range(1200)]
    seen = []

    def progress(done, total, text):
        seen.append((done, total, text))

    with pytest.raises(Cancelled):
        write_workbook(path, records, cancel=lambda: len(seen) >= 2, progress=progress)
    assert seen == [(500, 1200, "500 of 1,200 rows"), (1000, 1200, "1,000 of 1,200 rows")]
    assert path.read_bytes() == b"the earlier export"
    assert _no_temp_files(tmp_path) and sorted(p.name for p in tmp_path.iterdir()) == ["log.xlsx"]
    # not cancelled: the same rows are written
    write_workbook(path, records, cancel=lambda: False, progress=progress)
    assert len(read_measurements(path)) == 1200


def test_calibration_sheet_gives_each_value_its_uncertainty_the_warnings_and_pairs_left_out(
        tmp_path):
    """The Calibration sheet: every value with its 1-sigma ± where the calibration has one
    (baseline, rotation, each camera's fx fy cx cy and distortion, the lens at the corners), the
    warnings in words and the pairs it was not made from, with why."""
    from stereo_gui.core.calibrate import calibrate_stereo
    from stereo_gui.core.detect import detect_pair
    from stereo_gui.sources.sim import SimRig

    rig = SimRig(seed=5)
    board = BoardSpec()
    dets = [detect_pair(f"pair-{i}", left, right, board)
            for i, (left, right) in enumerate(rig.calibration_set(10, seed=3))]
    blank = np.full_like(rig.calibration_set(1, seed=3)[0][0], 128)
    dets.append(detect_pair("pair-blank", blank, blank, board))  # no board: rejected
    calib = calibrate_stereo(dets, board).calibration
    calib = calib.with_updates(left_out=(("pair-7", "excluded by you"),) + calib.left_out)
    assert calib.uncertainty is not None and calib.warnings
    write_workbook(tmp_path / "log.xlsx", [], calibration=calib, calibration_file="c.yaml")
    ws = openpyxl.load_workbook(tmp_path / "log.xlsx")["Calibration"]
    rows = [r[:3] for r in ws.iter_rows(values_only=True)]
    by_label = {}
    for r in rows:
        by_label.setdefault(r[0], []).append(r)
    u = calib.uncertainty
    assert by_label["Baseline (mm)"][0][2] == pytest.approx(u.baseline_sigma_mm(calib.T))
    assert by_label["Relative rotation (deg)"][0][2] == pytest.approx(
        u.rotation_sigma_deg(calib.R))
    left, right = by_label["fx (px)"]
    assert left[1:] == pytest.approx((calib.M1[0, 0], u.sigma("left.fx")))
    assert right[1:] == pytest.approx((calib.M2[0, 0], u.sigma("right.fx")))
    assert by_label["k1"][0][2] == pytest.approx(u.distortion_sigma("left", "k1"))
    assert len(by_label["lens at the corners (px)"]) == 2
    start = next(i for i, r in enumerate(rows) if r[0] == "Warnings")
    for k, w in enumerate(calib.warnings):
        assert rows[start + 1 + k][:2] == (w.code, w.message)
    start = next(i for i, r in enumerate(rows) if r[0] == "Pairs left out")
    assert rows[start + 1][:2] == ("pair-7", "excluded by you")
    assert rows[start + 2][0] == "pair-blank" and "not found" in rows[start + 2][1]
    # printed landscape, one page wide
    assert ws.page_setup.orientation == "landscape" and ws.page_setup.fitToWidth == 1


def test_every_sheet_prints_landscape_one_page_wide_with_the_header_on_every_page(tmp_path):
    """Printed or made a PDF, the Measurements sheet was five pages of columns; now every sheet
    is one page wide, landscape, and the Measurements header repeats on each page."""
    recs = make_records()
    write_workbook(tmp_path / "log.xlsx", recs, _make_fits(_samples(recs)),
                   calibration=make_calibration())
    wb = openpyxl.load_workbook(tmp_path / "log.xlsx")
    for ws in wb.worksheets:
        assert ws.page_setup.orientation == "landscape", ws.title
        assert ws.sheet_properties.pageSetUpPr.fitToPage, ws.title
        assert (ws.page_setup.fitToWidth, ws.page_setup.fitToHeight) == (1, 0), ws.title
    assert wb["Measurements"].print_title_rows.replace("$", "") == "1:1"
    # no bold header wider than its column (they ran over each other: "RMS resid" over "c0")
    from openpyxl.utils import get_column_letter

    for ws in wb.worksheets:
        for row in ws.iter_rows():
            for c in row:
                dim = ws.column_dimensions[get_column_letter(c.column)]
                if (c.font.b and isinstance(c.value, str) and c.row > 1 and not dim.hidden
                        and ws.title != "Calibration" and not c.value.endswith(" formula")):
                    assert len(c.value) <= dim.width, (ws.title, c.value, dim.width)


# ---- the error columns, in a workbook and a CSV ------------------------------------------
def test_error_columns_say_how_far_z_is_from_the_true_distance(tmp_path):
    import csv

    rec = make_records(1)[0]
    rec = ss.MeasurementRecord(**{**rec.__dict__, "Z_mm": 1512.0, "valid": True,
                                  "true_mm": 1500.0})
    assert ss.record_error(rec) == pytest.approx((12.0, 0.8))
    blank = ss.MeasurementRecord(**{**rec.__dict__, "true_mm": None})
    assert all(math.isnan(v) for v in ss.record_error(blank))
    write_csv(tmp_path / "log.csv", [rec, blank])
    rows = list(csv.reader((tmp_path / "log.csv").read_text(encoding="utf-8").splitlines()))
    i = rows[0].index("Error Z - true (mm)")
    assert float(rows[1][i]) == pytest.approx(12.0) and float(rows[1][i + 1]) == pytest.approx(0.8)
    assert rows[2][i] == "" and rows[2][i + 1] == ""
    assert len(read_csv(tmp_path / "log.csv")) == 2  # the derived columns are not read back
    path = write_workbook(tmp_path / "log.xlsx", [rec, blank])
    ws = openpyxl.load_workbook(path)["Measurements"]
    header = [c.value for c in ws[1]]
    j = header.index("Error (%)") + 1
    assert ws.cell(row=2, column=j).value == pytest.approx(0.8)
    assert ws.cell(row=3, column=j).value is None
    assert len(read_measurements(path)) == 2


def test_a_hand_edited_cell_that_is_not_a_number_is_named(tmp_path):
    path = write_workbook(tmp_path / "log.xlsx", make_records(1))
    wb = openpyxl.load_workbook(path)
    wb["Measurements"].cell(row=2, column=HEADERS.index("Z (mm)") + 1, value="about a metre")
    wb.save(path)
    with pytest.raises(InputError, match=r"row 2: column 'Z \(mm\)'"):
        read_measurements(path)
