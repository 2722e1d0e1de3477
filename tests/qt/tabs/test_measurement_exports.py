"""The Measurements tab's exports as a part of their own: handed the log, the fits, a button and
a folder, they write the files, say so and keep the button off while an xlsx export runs."""

from __future__ import annotations

import threading

import pytest
from PySide6.QtWidgets import QPushButton, QWidget

import stereo_gui.files.spreadsheet as spreadsheet
from stereo_gui.files.spreadsheet import MeasurementRecord, read_csv
from stereo_gui.qt.tabs.measurement_exports import ExportFolder, MeasurementExports


def _record(z_mm: float) -> MeasurementRecord:
    return MeasurementRecord(time="2026-01-02T10:11:12+00:00", x_px=320.0, y_px=240.0,
                             disparity_px=82500.0 / z_mm, X_mm=0.0, Y_mm=0.0, Z_mm=z_mm,
                             range_mm=z_mm, valid=True, reason="", valid_fraction=1.0,
                             expected_error_mm=1.0)


@pytest.fixture
def exports(qtbot, ctx):
    """(MeasurementExports over the context's log, its xlsx button); no fits."""
    owner = QWidget()
    qtbot.addWidget(owner)
    button = QPushButton("Export .xlsx…", owner)
    made = MeasurementExports(ctx.measurement_log, ctx.calibration_model, lambda: [],
                              ExportFolder(ctx.settings_model), ctx, ctx.workers, button, owner)
    yield made, button
    assert made.stop(2000)


def test_csv_holds_the_log_and_the_next_dialog_starts_beside_it(ctx, exports, tmp_path):
    made, _button = exports
    for z in (800.0, 1500.0):
        ctx.measurement_log.add(_record(z))
    said = []
    ctx.statusMessage.connect(said.append)
    path = tmp_path / "out" / "log.csv"
    path.parent.mkdir()
    assert made.export_csv(path)
    assert [r.Z_mm for r in read_csv(path)] == [800.0, 1500.0]
    assert said == [f"Exported 2 readings to {path}"]
    assert ExportFolder(ctx.settings_model).start() == str(path.parent)


def test_a_csv_that_cannot_be_written_is_reported(ctx, exports, tmp_path):
    made, _button = exports
    errors = []
    ctx.errorOccurred.connect(errors.append)
    target = tmp_path / "no such folder" / "log.csv"
    assert not made.export_csv(target)
    assert len(errors) == 1 and errors[0].startswith(f"could not write {target}")


def test_xlsx_export_holds_its_button_and_refuses_a_second_one(
        qtbot, ctx, exports, tmp_path, monkeypatch):
    made, button = exports
    ctx.measurement_log.add(_record(1000.0))
    gate = threading.Event()
    real = spreadsheet.write_workbook

    def held(*args, **kwargs):
        gate.wait(30)
        return real(*args, **kwargs)

    monkeypatch.setattr(spreadsheet, "write_workbook", held)
    errors, written = [], []
    ctx.errorOccurred.connect(errors.append)
    made.finished.connect(written.append)
    path = tmp_path / "log.xlsx"
    try:
        assert made.export_xlsx(path)
        assert not button.isEnabled()
        qtbot.waitUntil(lambda: made.unfinished_work() == [
            "the export of the measurement log to log.xlsx (1 row)"], timeout=10000)
        assert not made.export_xlsx(tmp_path / "other.xlsx")
        assert errors == ["an export is still running"]
    finally:
        gate.set()
    qtbot.waitUntil(button.isEnabled, timeout=30000)
    assert written == [str(path)] and path.is_file() and made.unfinished_work() == []
