"""The Measurements tab: log table, true distances -> regression with R^2, model choice, exports."""

from __future__ import annotations

import math
import threading

import pytest
from openpyxl import load_workbook

import stereo_gui.files.spreadsheet as spreadsheet
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.spreadsheet import MeasurementRecord, read_csv
from stereo_gui.qt.tabs.measurements import MeasurementsTab
from stereo_gui.qt.widgets.measurement_table import COLUMNS, TRUE_COL, VALID_COL

F_PX, B_MM = 750.0, 110.0


def _record(d: float, valid: bool = True) -> MeasurementRecord:
    z = F_PX * B_MM / d if valid else float("nan")
    return MeasurementRecord(time="2026-01-02T10:11:12+00:00", x_px=320.0, y_px=240.0,
                             disparity_px=d if valid else float("nan"), X_mm=0.0, Y_mm=0.0,
                             Z_mm=z, range_mm=z, valid=valid,
                             reason="" if valid else "no valid pixels in the patch",
                             valid_fraction=1.0 if valid else 0.0, expected_error_mm=1.0)


@pytest.fixture
def tab(make_tab):
    return make_tab(MeasurementsTab)


DISPARITIES = [20.0, 30.0, 41.0, 55.0, 70.0, 90.0]


def _log_with_truth(ctx, tab, truth_offset_mm=15.0):
    for d in DISPARITIES:
        ctx.measurement_log.add(_record(d))
    ctx.measurement_log.add(_record(0.0, valid=False))
    model = tab.table.model()
    for row, d in enumerate(DISPARITIES):
        # the true distance differs a little from triangulation (what a technician finds)
        true = F_PX * B_MM / d + truth_offset_mm
        assert model.setData(model.index(row, TRUE_COL), f"{true:.1f}")
    return model


def test_log_table_shows_readings(tab, ctx):
    ctx.measurement_log.add(_record(41.25))
    ctx.measurement_log.add(_record(0.0, valid=False))
    model = tab.table.model()
    assert model.rowCount() == 2
    assert model.index(0, 2).data() == "41.250"
    assert model.index(0, 8).data() == f"{F_PX * B_MM / 41.25:.1f}"  # range
    assert model.index(1, VALID_COL).data().startswith("no: no valid pixels")
    assert "2 readings, 0 with a true distance" in tab.count_label.text()


def test_entering_true_distances_fits_both_models_with_r2(tab, ctx):
    _log_with_truth(ctx, tab)
    first = ctx.measurement_log.records[0]
    assert first.true_mm == pytest.approx(F_PX * B_MM / 20.0 + 15.0, abs=0.1)
    assert tab.r2("cubic") is not None and tab.r2("inverse") is not None
    assert tab.r2("inverse") > 0.999
    assert "R² = " in tab.r2_labels["cubic"].text() and "R² = " in tab.r2_labels["inverse"].text()
    assert "6 samples" in tab.sample_label.text()


def test_bad_true_distance_is_refused(tab, ctx):
    errors = []
    ctx.errorOccurred.connect(errors.append)
    ctx.measurement_log.add(_record(40.0))
    model = tab.table.model()
    assert not model.setData(model.index(0, TRUE_COL), "two metres")
    assert not model.setData(model.index(0, TRUE_COL), "-5")
    assert ctx.measurement_log.records[0].true_mm is None and len(errors) == 2
    assert model.setData(model.index(0, TRUE_COL), "1500")
    assert model.setData(model.index(0, TRUE_COL), "")  # clearing is allowed
    assert ctx.measurement_log.records[0].true_mm is None


def test_too_few_samples_explains(tab, ctx):
    ctx.measurement_log.add(_record(40.0))
    tab.table.model().setData(tab.table.model().index(0, TRUE_COL), "2000")
    assert tab.r2("cubic") is None
    assert "not fitted" in tab.r2_labels["cubic"].text()
    assert "at least" in tab.r2_labels["cubic"].text()


def test_model_choice_sets_active_fit(tab, ctx):
    _log_with_truth(ctx, tab)
    with_fit = []
    ctx.measurement_log.activeFitChanged.connect(with_fit.append)
    tab.use_model("inverse")
    assert ctx.active_fit is tab.fits["inverse"] and with_fit[-1].model == "inverse"
    assert ctx.settings.measure_model == "inverse"
    # entering another true distance refits, and live readings follow the new fit
    model = tab.table.model()
    model.setData(model.index(0, TRUE_COL), "4200")
    assert ctx.active_fit is tab.fits["inverse"]
    tab.use_model("triangulation")
    assert ctx.active_fit is None


def test_export_xlsx_and_csv_hold_logged_values(tab, ctx, qtbot, tmp_path):
    _log_with_truth(ctx, tab)
    path = tmp_path / "log.xlsx"
    with qtbot.waitSignal(tab.exportFinished, timeout=30000):
        assert tab.export_xlsx(path)
    qtbot.waitUntil(lambda: tab.xlsx_button.isEnabled(), timeout=30000)
    wb = load_workbook(path)
    ws = wb["Measurements"]
    rows = list(ws.iter_rows(min_row=2, values_only=True))
    assert len(rows) == len(ctx.measurement_log.records)
    headers = [c.value for c in ws[1]]
    d_col, t_col = headers.index("Disparity (px)"), headers.index("True distance (mm)")
    for row, rec in zip(rows, ctx.measurement_log.records, strict=True):
        if math.isfinite(rec.disparity_px):
            assert row[d_col] == pytest.approx(rec.disparity_px)
        assert (row[t_col] is None) == (rec.true_mm is None)
        if rec.true_mm is not None:
            assert row[t_col] == pytest.approx(rec.true_mm)
    assert "Regression" in wb.sheetnames
    csv_path = tmp_path / "log.csv"
    assert tab.export_csv(csv_path)
    back = read_csv(csv_path)
    assert [r.disparity_px for r in back[:6]] == pytest.approx(DISPARITIES)


def test_an_export_that_fails_says_how_far_it_got_then_why(tab, ctx, qtbot, tmp_path,
                                                            monkeypatch):
    gate = threading.Event()

    def full_disk(path, *args, progress=None, **kwargs):
        progress(1, 2, "1 of 2 rows")
        gate.wait(30)
        raise StereoGuiError(f"could not write {path}: no space left on device")

    monkeypatch.setattr(spreadsheet, "write_workbook", full_disk)
    _log_with_truth(ctx, tab)
    errors = []
    ctx.errorOccurred.connect(errors.append)
    path = tmp_path / "log.xlsx"
    try:
        assert tab.export_xlsx(path)
        qtbot.waitUntil(lambda: tab.unfinished_work() == [
            "the export of the measurement log to log.xlsx (1 of 2 rows)"], timeout=30000)
    finally:
        gate.set()
    qtbot.waitUntil(lambda: tab.xlsx_button.isEnabled(), timeout=30000)
    assert errors == [f"export to {path} failed: could not write {path}: no space left on "
                      "device"]
    assert not path.exists() and tab.unfinished_work() == []


def test_save_and_load_fit(tab, ctx, tmp_path):
    _log_with_truth(ctx, tab)
    fit = tab.fits["cubic"]
    path = tmp_path / "cubic.json"
    assert tab.save_fit(fit, path) and path.exists()
    ctx.measurement_log.clear()
    assert tab.r2("cubic") is None
    assert tab.load_fit(path)
    assert ctx.active_fit is not None and ctx.active_fit.model == "cubic"
    assert ctx.active_fit.coefficients == pytest.approx(fit.coefficients)
    assert tab.model_combo.currentData() == "cubic"
    assert "loaded from file" in tab.r2_labels["cubic"].text()


def test_new_reading_without_truth_keeps_the_active_fit(tab, ctx):
    _log_with_truth(ctx, tab)
    tab.use_model("cubic")
    fit = ctx.active_fit
    changes = []
    ctx.measurement_log.activeFitChanged.connect(changes.append)
    # a live click: no true distance, the samples are the same
    ctx.measurement_log.add(_record(33.0))
    assert ctx.active_fit is fit and changes == []


def test_empty_log_states_the_sample_counts_the_fits_need(tab):
    """The hint above the plot and each model's 'not fitted' reason give the same minimum."""
    import re

    tab.refit()
    hint = tab.sample_label.text()
    for model in ("cubic", "inverse"):
        need = re.search(r"at least (\d+) samples", tab.fit_errors[model]).group(1)
        said = re.search(rf"{model}[^,.]*? (\d+)", hint)
        assert said and said.group(1) == need, (model, hint, tab.fit_errors[model])


def test_entering_a_true_distance_keeps_the_current_cell(tab, ctx, qtbot):
    """Type a distance, Return, Down: the next reading's true-distance cell, ready for the next
    entry (the model was reset on every entry, which dropped the current cell)."""
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QLineEdit

    for d in DISPARITIES[:3]:
        ctx.measurement_log.add(_record(d))
    tab.resize(1000, 600)
    tab.show()
    table = tab.table
    first = table.model().index(0, TRUE_COL)
    table.setCurrentIndex(first)
    table.edit(first)
    editor = table.viewport().findChild(QLineEdit)  # the default delegate's editor
    assert editor is not None
    qtbot.keyClicks(editor, "1000")
    qtbot.keyClick(editor, Qt.Key.Key_Return)  # the delegate commits in a queued call
    qtbot.waitUntil(lambda: ctx.measurement_log.records[0].true_mm == 1000.0, timeout=5000)
    assert (table.currentIndex().row(), table.currentIndex().column()) == (0, TRUE_COL)
    qtbot.keyClick(table, Qt.Key.Key_Down)
    assert (table.currentIndex().row(), table.currentIndex().column()) == (1, TRUE_COL)
    ctx.measurement_log.add(_record(DISPARITIES[3]))  # a new reading still appears as a new row
    assert table.model().rowCount() == 4


def test_clear_log_asks_first(tab, ctx, questions):
    """One click on Clear log must not throw away the true distances typed in."""
    from PySide6.QtWidgets import QMessageBox

    _log_with_truth(ctx, tab)
    n = len(ctx.measurement_log.records)
    questions.reply = QMessageBox.StandardButton.No
    tab.clear_button.click()
    assert len(ctx.measurement_log.records) == n and f"all {n} readings" in questions.asked[-1]
    questions.reply = QMessageBox.StandardButton.Yes
    tab.clear_button.click()
    assert ctx.measurement_log.records == ()


def test_error_columns_and_triangulation_rms_beside_each_fit(tab, ctx):
    _log_with_truth(ctx, tab, truth_offset_mm=15.0)
    headers = [c[0] for c in COLUMNS]
    model = tab.table.model()
    err_mm, err_pct = headers.index("Error (mm)"), headers.index("Error (%)")
    assert model.index(0, err_mm).data() == "-15.0"  # Z - true
    true0 = F_PX * B_MM / 20.0 + 15.0
    assert model.index(0, err_pct).data() == f"{-1500.0 / true0:.2f}"
    assert model.index(len(DISPARITIES), err_mm).data() == "—"  # no true distance: no error
    # every triangulated reading is 15 mm short: triangulation's RMS is 15 mm, the fits' less
    assert tab.triangulation_rms_mm == pytest.approx(15.0, abs=0.06)
    assert "RMS 15.0 mm" in tab.triangulation_label.text()
    for m in ("cubic", "inverse"):
        assert "(triangulation 15.0 mm)" in tab.r2_labels[m].text()


def test_too_few_true_distances_say_so_instead_of_a_perfect_fit(tab, ctx):
    model = tab.table.model()
    for row, (d, true) in enumerate(((40.0, 2000.0), (40.5, 2000.0), (20.0, 4000.0),
                                     (20.2, 4000.0))):
        ctx.measurement_log.add(_record(d))
        model.setData(model.index(row, TRUE_COL), f"{true}")
    assert tab.r2("cubic") is None  # not R^2 1.00000 and RMS 0.0 mm
    assert "4 or more different distances, got 2" in tab.r2_labels["cubic"].text()
    assert tab.r2("inverse") is not None  # two parameters, two distances, four readings
    ctx.measurement_log.clear()
    for row, (d, true) in enumerate(((40.0, 2000.0), (20.0, 4000.0))):
        ctx.measurement_log.add(_record(d))
        model.setData(model.index(row, TRUE_COL), f"{true}")
    assert "passes exactly through its 2 samples" in tab.r2_labels["inverse"].text()


def test_clear_log_is_undoable_until_the_next_reading(tab, ctx, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    _log_with_truth(ctx, tab)
    n = len(ctx.measurement_log.records)
    monkeypatch.setattr(QMessageBox, "question",
                        lambda *a, **k: QMessageBox.StandardButton.Yes)
    tab.clear_button.click()
    assert ctx.measurement_log.records == () and tab.undo_button.isVisibleTo(tab)
    tab.undo_button.click()
    assert len(ctx.measurement_log.records) == n and not tab.undo_button.isVisibleTo(tab)
    assert tab.r2("cubic") is not None  # the true distances came back with them
    tab.clear_button.click()
    ctx.measurement_log.add(_record(33.0))
    assert not ctx.measurement_log.can_undo_clear and not tab.undo_button.isVisibleTo(tab)
    assert not ctx.measurement_log.undo_clear() and len(ctx.measurement_log.records) == 1


def test_open_log_brings_back_an_exported_csv_or_xlsx(tab, ctx, qtbot, tmp_path):
    _log_with_truth(ctx, tab)
    before = [(r.disparity_px, r.true_mm, r.valid) for r in ctx.measurement_log.records]
    assert tab.export_csv(tmp_path / "log.csv")
    with qtbot.waitSignal(tab.exportFinished, timeout=30000):
        assert tab.export_xlsx(tmp_path / "log.xlsx")
    for name in ("log.csv", "log.xlsx"):
        assert tab.open_log(tmp_path / name, replace=True)
        after = [(r.disparity_px, r.true_mm, r.valid) for r in ctx.measurement_log.records]
        assert len(after) == len(before)
        for a, b in zip(after, before, strict=True):
            assert a[2] == b[2] and (a[1] is None) == (b[1] is None)
            if b[2]:
                assert a[0] == pytest.approx(b[0], abs=1e-3)
            if b[1] is not None:
                assert a[1] == pytest.approx(b[1], abs=0.05)
        assert tab.r2("inverse") is not None
    assert tab.open_log(tmp_path / "log.csv")  # added after the readings there
    assert len(ctx.measurement_log.records) == 2 * len(before)
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    assert not tab.open_log(tmp_path / "other.csv")
    assert len(ctx.measurement_log.records) == 2 * len(before)


def test_log_and_active_fit_survive_a_restart(qtbot, tmp_path):
    """Quit and start again: the readings with their true distances, the fit live readings use
    and an undoable Clear log are back (the log is saved as it changes, atomically)."""
    from stereo_gui.qt.context import AppContext

    path = tmp_path / "data" / "measurement-log.json"
    ctx = AppContext()
    assert ctx.measurement_log.keep(path) == []
    tab = MeasurementsTab(ctx)
    qtbot.addWidget(tab)
    _log_with_truth(ctx, tab)
    tab.use_model("inverse")
    fit = ctx.active_fit
    assert fit is not None and fit.model == "inverse"
    qtbot.waitUntil(lambda: path.is_file() and "inverse" in path.read_text(), timeout=5000)
    n = len(ctx.measurement_log.records)
    assert ctx.shutdown(2000)

    ctx2 = AppContext()
    tab2 = MeasurementsTab(ctx2)
    qtbot.addWidget(tab2)
    assert ctx2.measurement_log.keep(path) == []
    assert len(ctx2.measurement_log.records) == n
    assert ctx2.measurement_log.records[0].true_mm == ctx.measurement_log.records[0].true_mm
    assert ctx2.active_fit == fit
    assert tab2.model_combo.currentData() == "inverse"
    ctx2.measurement_log.clear()
    assert ctx2.shutdown(2000)  # a pending save is written on the way out

    ctx3 = AppContext()
    assert ctx3.measurement_log.keep(path) == []
    assert ctx3.measurement_log.records == () and ctx3.measurement_log.can_undo_clear
    assert ctx3.measurement_log.undo_clear() and len(ctx3.measurement_log.records) == n
    assert ctx3.shutdown(2000)


def test_an_unreadable_kept_log_is_set_aside_and_said(qtbot, tmp_path):
    from stereo_gui.qt.context import AppContext

    path = tmp_path / "measurement-log.json"
    path.write_text("{ half a log")
    ctx = AppContext()
    warnings = ctx.measurement_log.keep(path)
    assert len(warnings) == 1 and "could not be restored" in warnings[0]
    assert (tmp_path / "measurement-log.json.unreadable").read_text() == "{ half a log"
    assert ctx.measurement_log.records == ()
    assert ctx.shutdown(2000)


def test_one_reading_is_one_reading_not_one_readings(tab, ctx, questions):
    """With one reading and one true distance the tab says "1 reading", "1 sample" and "of
    1 reading" (it said "1 samples" and "of 1 readings"), and two are plural again."""
    ctx.measurement_log.add(_record(41.0))
    assert tab.table.model().setData(tab.table.model().index(0, TRUE_COL), "2000")
    texts = [tab.count_label.text(), tab.sample_label.text(), tab.triangulation_label.text()]
    joined = " | ".join(texts)
    assert "1 reading," in texts[0] and texts[1].startswith("1 sample (a valid reading ")
    assert "of 1 reading" in texts[2] and "1 readings" not in joined and "1 samples" not in joined
    tab.clear_button.click()
    assert "Remove the 1 reading (1 with a true distance)" in questions.asked[-1]
    ctx.measurement_log.add(_record(30.0))
    ctx.measurement_log.add(_record(20.0))
    assert "2 readings," in tab.count_label.text()


def test_how_many_says_a_count_in_the_right_number():
    from stereo_gui.core.util import how_many

    assert [how_many(n, "sample") for n in (0, 1, 2)] == ["0 samples", "1 sample", "2 samples"]
    assert how_many(20000, "reading") == "20,000 readings"
    assert how_many(1, "cleared reading is", "cleared readings are") == "1 cleared reading is"


def test_a_note_is_typed_in_the_log_kept_exported_and_read_back(qtbot, tmp_path):
    """The Note column says what was measured: typed in the table, kept across a restart,
    written to the .xlsx and .csv exports (the last column), and read back from them; a CSV
    written before notes existed still opens."""
    import dataclasses

    from PySide6.QtCore import Qt

    from stereo_gui.files.spreadsheet import FILE_HEADERS, read_measurements, records_to_csv
    from stereo_gui.qt.context import AppContext
    from stereo_gui.qt.widgets.measurement_table import NOTE_COL

    path = tmp_path / "data" / "measurement-log.json"
    ctx = AppContext()
    assert ctx.measurement_log.keep(path) == []
    tab = MeasurementsTab(ctx)
    qtbot.addWidget(tab)
    ctx.measurement_log.add(_record(41.0))
    ctx.measurement_log.add(_record(30.0))
    model = tab.table.model()
    assert model.headerData(NOTE_COL, Qt.Orientation.Horizontal) == "Note"
    assert model.flags(model.index(0, NOTE_COL)) & Qt.ItemFlag.ItemIsEditable
    assert model.setData(model.index(0, NOTE_COL), "door frame,\n left edge ")
    assert model.index(0, NOTE_COL).data() == "door frame, left edge"
    qtbot.waitUntil(lambda: path.is_file() and "door frame" in path.read_text(), timeout=5000)
    assert ctx.shutdown(2000)

    ctx2 = AppContext()
    assert ctx2.measurement_log.keep(path) == []
    assert [r.note for r in ctx2.measurement_log.records] == ["door frame, left edge", ""]
    tab2 = MeasurementsTab(ctx2)
    qtbot.addWidget(tab2)
    assert tab2.table.model().index(0, NOTE_COL).data() == "door frame, left edge"
    xlsx, csv = tmp_path / "log.xlsx", tmp_path / "log.csv"
    with qtbot.waitSignal(tab2.exportFinished, timeout=30000):
        assert tab2.export_xlsx(xlsx)
    qtbot.waitUntil(lambda: tab2.xlsx_button.isEnabled(), timeout=30000)
    assert tab2.export_csv(csv)
    assert load_workbook(xlsx)["Measurements"].cell(row=1, column=len(FILE_HEADERS)).value == "Note"
    assert csv.read_text().splitlines()[0].endswith(",Note")
    assert [r.note for r in read_measurements(xlsx)] == ["door frame, left edge", ""]
    assert [r.note for r in read_csv(csv)] == ["door frame, left edge", ""]
    old = tmp_path / "old.csv"  # as written before the Note column
    without = [dataclasses.replace(r, note="") for r in ctx2.measurement_log.records]
    lines = records_to_csv(without).splitlines()
    assert lines[0].endswith(",Note") and all(line.endswith(",") for line in lines[1:])
    old.write_text("\n".join(line.rsplit(",", 1)[0] for line in lines) + "\n")
    assert [r.note for r in read_csv(old)] == ["", ""]
    assert [r.Z_mm for r in read_csv(old)] == pytest.approx([r.Z_mm for r in without], abs=0.05)
    tab2.shutdown()
    assert ctx2.shutdown(2000)


def test_the_residual_axis_is_in_millimetres_not_in_rounding_errors(tab, ctx):
    """Two samples: the inverse model goes through both, residuals ~1e-13 mm; the axis shows
    +-1 mm or more, not +-5e-14."""
    ctx.measurement_log.add(_record(20.0))
    ctx.measurement_log.add(_record(40.0))
    model = tab.table.model()
    for row, d in enumerate((20.0, 40.0)):
        assert model.setData(model.index(row, TRUE_COL), f"{F_PX * B_MM / d:.1f}")
    lo, hi = tab.plot.resid.getViewBox().viewRange()[1]
    assert hi >= 1.0 and lo <= -1.0
