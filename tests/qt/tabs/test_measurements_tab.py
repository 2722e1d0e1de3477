"""The Measurements tab: log table, true distances -> regression with R^2, model choice, exports."""

from __future__ import annotations

import math

import pytest
from openpyxl import load_workbook

from stereo_gui.files.spreadsheet import MeasurementRecord, read_csv
from stereo_gui.qt.tabs.measurements import MeasurementsTab
from stereo_gui.qt.widgets.measurement_table import TRUE_COL

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
        ctx.add_measurement(_record(d))
    ctx.add_measurement(_record(0.0, valid=False))
    model = tab.table.model()
    for row, d in enumerate(DISPARITIES):
        # the true distance differs a little from triangulation (what a technician finds)
        true = F_PX * B_MM / d + truth_offset_mm
        assert model.setData(model.index(row, TRUE_COL), f"{true:.1f}")
    return model


def test_log_table_shows_readings(tab, ctx):
    ctx.add_measurement(_record(41.25))
    ctx.add_measurement(_record(0.0, valid=False))
    model = tab.table.model()
    assert model.rowCount() == 2
    assert model.index(0, 2).data() == "41.250"
    assert model.index(0, 5).data() == f"{F_PX * B_MM / 41.25:.1f}"  # range
    assert model.index(1, 7).data().startswith("no: no valid pixels")
    assert "2 readings, 0 with a true distance" in tab.count_label.text()


def test_entering_true_distances_fits_both_models_with_r2(tab, ctx):
    _log_with_truth(ctx, tab)
    assert ctx.measurements[0].true_mm == pytest.approx(F_PX * B_MM / 20.0 + 15.0, abs=0.1)
    assert tab.r2("cubic") is not None and tab.r2("inverse") is not None
    assert tab.r2("inverse") > 0.999
    assert "R² = " in tab.r2_labels["cubic"].text() and "R² = " in tab.r2_labels["inverse"].text()
    assert "6 samples" in tab.sample_label.text()


def test_bad_true_distance_is_refused(tab, ctx):
    errors = []
    ctx.errorOccurred.connect(errors.append)
    ctx.add_measurement(_record(40.0))
    model = tab.table.model()
    assert not model.setData(model.index(0, TRUE_COL), "two metres")
    assert not model.setData(model.index(0, TRUE_COL), "-5")
    assert ctx.measurements[0].true_mm is None and len(errors) == 2
    assert model.setData(model.index(0, TRUE_COL), "1500")
    assert model.setData(model.index(0, TRUE_COL), "")  # clearing is allowed
    assert ctx.measurements[0].true_mm is None


def test_too_few_samples_explains(tab, ctx):
    ctx.add_measurement(_record(40.0))
    tab.table.model().setData(tab.table.model().index(0, TRUE_COL), "2000")
    assert tab.r2("cubic") is None
    assert "not fitted" in tab.r2_labels["cubic"].text()
    assert "at least" in tab.r2_labels["cubic"].text()


def test_model_choice_sets_active_fit(tab, ctx):
    _log_with_truth(ctx, tab)
    with_fit = []
    ctx.activeFitChanged.connect(with_fit.append)
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
    assert len(rows) == len(ctx.measurements)
    headers = [c.value for c in ws[1]]
    d_col, t_col = headers.index("Disparity (px)"), headers.index("True distance (mm)")
    for row, rec in zip(rows, ctx.measurements, strict=True):
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


def test_save_and_load_fit(tab, ctx, tmp_path):
    _log_with_truth(ctx, tab)
    fit = tab.fits["cubic"]
    path = tmp_path / "cubic.json"
    assert tab.save_fit(fit, path) and path.exists()
    ctx.clear_measurements()
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
    ctx.activeFitChanged.connect(changes.append)
    ctx.add_measurement(_record(33.0))  # a live click: no true distance, the samples are the same
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
        ctx.add_measurement(_record(d))
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
    qtbot.waitUntil(lambda: ctx.measurements[0].true_mm == 1000.0, timeout=5000)
    assert (table.currentIndex().row(), table.currentIndex().column()) == (0, TRUE_COL)
    qtbot.keyClick(table, Qt.Key.Key_Down)
    assert (table.currentIndex().row(), table.currentIndex().column()) == (1, TRUE_COL)
    ctx.add_measurement(_record(DISPARITIES[3]))  # a new reading still appears as a new row
    assert table.model().rowCount() == 4


def test_clear_log_asks_first(tab, ctx, monkeypatch):
    """One click on Clear log must not throw away the true distances typed in."""
    from PySide6.QtWidgets import QMessageBox

    _log_with_truth(ctx, tab)
    n = len(ctx.measurements)
    asked = []

    def answer(reply):
        def question(parent, title, text, *args, **kwargs):
            asked.append(text)
            return reply
        return question

    monkeypatch.setattr(QMessageBox, "question", answer(QMessageBox.StandardButton.No))
    tab.clear_button.click()
    assert len(ctx.measurements) == n and f"all {n} readings" in asked[-1]
    monkeypatch.setattr(QMessageBox, "question", answer(QMessageBox.StandardButton.Yes))
    tab.clear_button.click()
    assert ctx.measurements == []
