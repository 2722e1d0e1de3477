"""The Measurements tab: the log of readings, the regression the reference program did in Excel,
exports.

The log is `ctx.measurement_log` (MeasurementRecord). Entering the true distance of a reading (the
editable column) makes it a regression sample (disparity px, true distance mm); both models are
fitted again at once: the reference program's cubic and Z = a / (d - d0). The plot shows samples,
both curves and the residuals with R^2. The model chosen for live readings goes to
`ctx.measurement_log.set_active_fit`. Exports (`measurement_exports.MeasurementExports`, owned
by the tab): the log and regression to .xlsx (in a worker) and CSV; Open log... brings back a
log exported before (CSV or xlsx). Beside each fit, triangulation's own RMS against the same true
distances shows whether the fit helps.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QStandardItemModel
from PySide6.QtWidgets import (
    QAbstractItemDelegate,
    QAbstractItemView,
    QApplication,
    QComboBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QMessageBox,
    QPushButton,
    QSplitter,
    QTableView,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core import regression
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.regression import FitResult
from stereo_gui.core.util import how_many
from stereo_gui.files.fit_file import load_fit, save_fit
from stereo_gui.files.spreadsheet import read_csv, read_measurements
from stereo_gui.qt.tabs.measurement_exports import ExportFolder, MeasurementExports
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.widgets.helpers import pane, wrapping_label
from stereo_gui.qt.widgets.measurement_table import (
    NOTE_COL,
    MeasurementModel,
    samples_from,
    triangulation_errors_mm,
)
from stereo_gui.qt.widgets.regression_plot import MODELS, RegressionPlot

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

_LABEL_COLOURS = {"cubic": "#b9570b", "inverse": "#1f6fa8"}  # the same hues, darker, for text
_MODEL_TEXT = {"triangulation": "Triangulation (calibration)",
               "cubic": "Cubic fit (the reference program's model)",
               "inverse": "Inverse fit Z = a / (d − d0)"}


class MeasurementsTab(QWidget):
    """The measurement log, the regression and the exports (see module docstring)."""

    fitsChanged = Signal()
    exportFinished = Signal(str)  # path written

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.fits: dict[str, FitResult] = {}  # model name -> its fit
        self.fit_errors: dict[str, str] = {}
        # a fit loaded from a file (not refitted from the log)
        self._loaded_fit: FitResult | None = None
        self._folder = ExportFolder(ctx.settings_model)  # where the file dialogs start
        self._build()
        ctx.measurement_log.changed.connect(self.refit)
        ctx.measurement_log.changed.connect(self._update_undo)
        ctx.calibration_model.changed.connect(lambda _c: self.refit())
        ctx.measurement_log.activeFitChanged.connect(self._active_fit_changed)
        self.refit()

    # ---- layout ------------------------------------------------------------------------------
    def _build(self) -> None:
        root = QVBoxLayout(self)
        split = QSplitter(Qt.Orientation.Horizontal)
        root.addWidget(split, 1)
        split.addWidget(self._build_log())
        split.addWidget(self._build_regression())
        split.setSizes([700, 560])

    def _build_log(self) -> QWidget:
        """The left side: the readings' table over its buttons."""
        left, ll = pane()
        self.count_label = wrapping_label()
        ll.addWidget(self.count_label)
        self.model = MeasurementModel(self.ctx, self)
        self.table = QTableView()
        self.table.setModel(self.model)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.DoubleClicked
                                   | QAbstractItemView.EditTrigger.EditKeyPressed
                                   | QAbstractItemView.EditTrigger.AnyKeyPressed)
        self.table.setAlternatingRowColors(True)
        hh = self.table.horizontalHeader()
        hh.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        # room to type a note before there is one; a long one does not push the numbers away
        hh.setSectionResizeMode(NOTE_COL, QHeaderView.ResizeMode.Interactive)
        hh.resizeSection(NOTE_COL, 160)
        hh.setStretchLastSection(True)
        self.table.verticalHeader().setDefaultSectionSize(22)
        ll.addWidget(self.table, 1)
        ll.addLayout(self._build_log_buttons())
        return left

    def _build_log_buttons(self) -> QHBoxLayout:
        """Remove, Clear, Undo clear; Open log and the exports (`MeasurementExports`)."""
        row = QHBoxLayout()
        self.remove_button = QPushButton("Remove selected")
        self.remove_button.clicked.connect(self._remove_selected)
        self.clear_button = QPushButton("Clear log")
        self.clear_button.clicked.connect(self._clear_log)
        self.undo_button = QPushButton("Undo clear")
        self.undo_button.setToolTip("Bring back the readings of the last Clear log (possible "
                                    "until the next reading)")
        self.undo_button.clicked.connect(self._undo_clear)
        self.undo_button.hide()
        self.open_button = QPushButton("Open log…")
        self.open_button.setToolTip("Bring back a log exported before (.csv or .xlsx written by "
                                    "Stereo GUI)")
        self.open_button.clicked.connect(self._choose_open_log)
        self.xlsx_button = QPushButton("Export .xlsx…")
        self.exports = MeasurementExports(
            self.ctx.measurement_log, self.ctx.calibration_model,
            lambda: [self.fits[m] for m in MODELS if m in self.fits], self._folder, self.ctx,
            self.ctx.workers, self.xlsx_button, self)
        self.exports.finished.connect(self.exportFinished)
        self.xlsx_button.clicked.connect(self.exports.choose_xlsx)
        self.csv_button = QPushButton("Export CSV…")
        self.csv_button.clicked.connect(self.exports.choose_csv)
        for b in (self.remove_button, self.clear_button, self.undo_button):
            row.addWidget(b)
        row.addStretch(1)
        row.addWidget(self.open_button)
        row.addWidget(self.xlsx_button)
        row.addWidget(self.csv_button)
        return row

    def _build_regression(self) -> QWidget:
        """The right side: the fits' figures, their plot, the model the live readings use,
        and Save fit / Load fit."""
        right, rl = pane()
        box = QGroupBox("Regression: true distance against disparity")
        bl = QVBoxLayout(box)
        self.sample_label = wrapping_label()
        bl.addWidget(self.sample_label)
        self.triangulation_label = wrapping_label()
        self.triangulation_label.setTextInteractionFlags(
            Qt.TextInteractionFlag.TextSelectableByMouse)
        bl.addWidget(self.triangulation_label)
        self.r2_labels: dict[str, QLabel] = {}
        for m in MODELS:
            lab = wrapping_label()
            lab.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
            lab.setStyleSheet(f"color: {_LABEL_COLOURS[m]}")
            self.r2_labels[m] = lab
            bl.addWidget(lab)
        self.plot = RegressionPlot()
        self.plot.setMinimumHeight(280)
        bl.addWidget(self.plot, 1)
        use = QHBoxLayout()
        use.addWidget(QLabel("Live readings use:"))
        self.model_combo = QComboBox()
        for key in ("triangulation", *MODELS):
            self.model_combo.addItem(_MODEL_TEXT[key], key)
        self.model_combo.currentIndexChanged.connect(self._model_chosen)
        use.addWidget(self.model_combo, 1)
        bl.addLayout(use)
        fits = QHBoxLayout()
        self.save_fit_button = QPushButton("Save fit…")
        self.save_fit_button.clicked.connect(self._choose_save_fit)
        self.load_fit_button = QPushButton("Load fit…")
        self.load_fit_button.clicked.connect(self._choose_load_fit)
        fits.addStretch(1)
        fits.addWidget(self.save_fit_button)
        fits.addWidget(self.load_fit_button)
        bl.addLayout(fits)
        rl.addWidget(box, 1)
        return right

    def set_active(self, active: bool) -> None:
        """This tab shows no live frames: while it is shown, frames are not processed."""
        if active:
            self.ctx.frames.set_processor(None)

    # ---- regression --------------------------------------------------------------------------
    def refit(self) -> None:
        """Fit both models to the current samples and show them."""
        recs = self.ctx.measurement_log.records
        n_true = sum(1 for r in recs if r.true_mm is not None)
        samples = samples_from(recs)
        self.count_label.setText(
            f"{how_many(len(recs), 'reading')}, {n_true} with a true distance. Double-click the True distance "
            f"cell of a reading to enter what you measured (mm).")
        self.fits, self.fit_errors = {}, {}
        for m, fn in (("cubic", regression.fit_cubic), ("inverse", regression.fit_inverse)):
            try:
                self.fits[m] = fn(samples)
            except (StereoGuiError, ValueError, np.linalg.LinAlgError) as exc:
                self.fit_errors[m] = str(exc)
        if self._loaded_fit is not None and self._loaded_fit.model not in self.fits:
            self.fits[self._loaded_fit.model] = self._loaded_fit
        self.sample_label.setText(
            f"{how_many(len(samples), 'sample')} ("
            + ("a valid reading" if len(samples) == 1 else "valid readings")
            + " with a true distance)." if samples else
            "No samples yet: enter true distances in the log. The cubic needs at least 4 "
            "samples, the inverse model 2.")
        tri = triangulation_errors_mm(recs, self.ctx.calibration)
        tri_rms = float(np.sqrt(np.mean(np.square(tri)))) if tri else float("nan")
        self.triangulation_rms_mm = tri_rms
        self.triangulation_label.setText(
            f"<b>triangulation</b> (the calibration alone): RMS {tri_rms:.1f} mm against the "
            f"true distances of {how_many(len(tri), 'reading')}" if tri else
            "<b>triangulation</b> (the calibration alone): no reading with a true distance yet")
        for m in MODELS:
            fit = self.fits.get(m)
            lab = self.r2_labels[m]
            if fit is not None:
                src = " (loaded from file)" if fit is self._loaded_fit else ""
                if fit.exactly_determined:
                    quality = (f"passes exactly through its {how_many(len(fit.samples), 'sample')}: R² and "
                               f"residuals say nothing yet, add readings at other distances")
                else:
                    quality = (f"R² = {fit.r2:.5f}, residual RMS {fit.rms_mm:.1f} mm"
                               + (f" (triangulation {tri_rms:.1f} mm)" if tri else "")
                               + f", {how_many(len(fit.samples), 'sample')}")
                lab.setText(f"<b>{m}</b>{src}: {quality}<br>"
                            f"<span style='font-family: monospace'>{fit.formula()}</span>")
            else:
                lab.setText(f"<b>{m}</b>: not fitted ({self.fit_errors.get(m, 'no samples')})")
        self.plot.draw(samples, self.fits)
        self._update_model_choices()
        # a live reading that uses a fit follows its refit
        key = self.model_combo.currentData()
        if key in MODELS:
            new = self.fits.get(key)
            if new is not None and new == self.ctx.active_fit:
                self.fits[key] = self.ctx.active_fit  # same samples, same fit: no new announcement
            elif new is not self.ctx.active_fit:
                self.ctx.measurement_log.set_active_fit(new)
        self.save_fit_button.setEnabled(bool(self.fits))
        self.fitsChanged.emit()

    def r2(self, model: str) -> float | None:
        fit = self.fits.get(model)
        return None if fit is None else float(fit.r2)

    def _update_model_choices(self) -> None:
        view = self.model_combo.model()
        items = view if isinstance(view, QStandardItemModel) else None  # (a combo box's own)
        for i in range(self.model_combo.count()):
            key = self.model_combo.itemData(i)
            item = items.item(i) if items is not None else None
            if item is not None and key in MODELS:
                item.setEnabled(key in self.fits)
        key = self.model_combo.currentData()
        if key in MODELS and key not in self.fits:
            self.model_combo.setCurrentIndex(0)

    def use_model(self, key: str) -> None:
        """Make live readings use 'triangulation', 'cubic' or 'inverse'."""
        i = self.model_combo.findData(key)
        if i >= 0:
            self.model_combo.setCurrentIndex(i)

    def _model_chosen(self, _index: int) -> None:
        key = self.model_combo.currentData()
        fit = self.fits.get(key) if key in MODELS else None
        if key in MODELS and fit is None:
            self.model_combo.setCurrentIndex(0)
            return
        if fit is not self.ctx.active_fit:
            self.ctx.measurement_log.set_active_fit(fit)
        if self.ctx.settings.measure_model != key:
            self.ctx.settings_model.update(measure_model=key)

    def _active_fit_changed(self, fit: FitResult | None) -> None:
        key = "triangulation" if fit is None else fit.model
        if fit is not None and key in MODELS and self.fits.get(key) != fit:
            # a fit that the log does not give (loaded from a file, restored at start-up)
            self._loaded_fit = fit
            self.fits[key] = fit
            self.refit()
        if key != self.model_combo.currentData():
            i = self.model_combo.findData(key)
            if i >= 0:
                self.model_combo.blockSignals(True)
                self.model_combo.setCurrentIndex(i)
                self.model_combo.blockSignals(False)

    # ---- log editing ---------------------------------------------------------------------------
    def _clear_log(self) -> None:
        """Empty the log after asking: the true distances typed in exist nowhere else."""
        n = len(self.ctx.measurement_log.records)
        if not n:
            return
        with_truth = sum(r.true_mm is not None for r in self.ctx.measurement_log.records)
        answer = QMessageBox.question(
            self, "Clear the log",
            f"Remove {'the' if n == 1 else 'all'} {how_many(n, 'reading')} ({with_truth} with a "
            "true distance) from the log? "
            "Readings not exported are lost.")
        if answer == QMessageBox.StandardButton.Yes:
            self.ctx.measurement_log.clear()
            self.ctx.show_status(f"Cleared {how_many(n, 'reading')} (Undo clear brings them back until the "
                                 f"next reading)")

    def _undo_clear(self) -> None:
        n = len(self.ctx.measurement_log.cleared)
        if self.ctx.measurement_log.undo_clear():
            self.ctx.show_status(f"{how_many(n, 'cleared reading is', 'cleared readings are')} "
                                 "back in the log")

    def _update_undo(self) -> None:
        self.undo_button.setVisible(self.ctx.measurement_log.can_undo_clear)

    # ---- a log exported before -----------------------------------------------------------------
    def _choose_open_log(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "Open a measurement log", self._folder.start(),
            "Measurement logs (*.csv *.xlsx);;All files (*)")
        if not path:
            return
        replace = False
        n = len(self.ctx.measurement_log.records)
        if n:
            box = QMessageBox(QMessageBox.Icon.Question, "Open log",
                              f"The log holds {how_many(n, 'reading')}. Add the "
                              f"readings of {Path(path).name} after them, or replace them?",
                              parent=self)
            add = box.addButton("Add", QMessageBox.ButtonRole.AcceptRole)
            rep = box.addButton("Replace", QMessageBox.ButtonRole.DestructiveRole)
            box.addButton(QMessageBox.StandardButton.Cancel)
            box.exec()
            if box.clickedButton() not in (add, rep):
                return
            replace = box.clickedButton() is rep
        self.open_log(path, replace=replace)

    def open_log(self, path: str | Path, replace: bool = False) -> bool:
        """Read a log exported by Stereo GUI (.csv or .xlsx) into the log (after the readings
        there, or instead of them); False (with a message) when it cannot be read."""
        path = Path(path)
        reader = read_measurements if path.suffix.lower() == ".xlsx" else read_csv
        try:
            records = reader(path)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"Cannot open the log {path}: {exc}")
            return False
        if replace and self.ctx.measurement_log.records:
            self.ctx.measurement_log.clear()  # undoable, like Clear log
        self.ctx.measurement_log.add_many(records)
        self._folder.remember(path)
        self.ctx.show_status(f"Opened {how_many(len(records), 'reading')} from {path}")
        return True

    def _remove_selected(self) -> None:
        rows = sorted({i.row() for i in self.table.selectionModel().selectedRows()}, reverse=True)
        for r in rows:
            self.ctx.measurement_log.remove(r)

    # ---- fits as files -------------------------------------------------------------------------
    def _choose_save_fit(self) -> None:
        key = self.model_combo.currentData()
        fit = self.fits.get(key) if key in MODELS else (
            self.fits.get("inverse") or self.fits.get("cubic"))
        if fit is None:
            return
        path, _ = folder_dialog.save_file_name(self, f"Save the {fit.model} fit",
                                              str(Path(self._folder.start())
                                                  / f"{fit.model}-fit.json"),
                                              "Fit (*.json)")
        if path:
            self.save_fit(fit, path)

    def save_fit(self, fit: FitResult, path: str | Path) -> bool:
        try:
            save_fit(fit, path)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not save the fit: {exc}")
            return False
        self._folder.remember(path)
        self.ctx.show_status(f"Saved the {fit.model} fit to {path}")
        return True

    def _choose_load_fit(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Load a fit", self._folder.start(),
                                              "Fit (*.json);;All files (*)")
        if path:
            self.load_fit(path)

    def load_fit(self, path: str | Path) -> bool:
        """Load a saved fit and make live readings use it."""
        try:
            fit = load_fit(path)
        except (StereoGuiError, OSError, ValueError) as exc:
            self.ctx.report_error(f"could not load the fit {path}: {exc}")
            return False
        self._loaded_fit = fit
        self.refit()
        self.fits[fit.model] = fit  # the loaded one wins over a refit from the log
        self._update_model_choices()
        self.use_model(fit.model)
        self.ctx.measurement_log.set_active_fit(fit)
        self._folder.remember(path)
        self.ctx.show_status(f"Loaded the {fit.model} fit from {path}; live readings use it")
        return True

    # ---- closing -------------------------------------------------------------------------------
    def commit_edits(self) -> None:
        """Put a true distance still being typed in its cell (the window closes, or the log
        is exported) into the log."""
        editor = QApplication.focusWidget()
        if (self.table.state() == QAbstractItemView.State.EditingState and editor is not None
                and self.table.isAncestorOf(editor)):
            self.table.commitData(editor)
            self.table.closeEditor(editor, QAbstractItemDelegate.EndEditHint.NoHint)

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Put an edit still open into the log and stop a running export (joined)."""
        self.commit_edits()
        return self.exports.stop(timeout_ms)

    # ---- exports (see MeasurementExports) -------------------------------------------------------
    def export_xlsx(self, path: str | Path) -> bool:
        """Write the log, the regression and the calibration to `path` in a worker."""
        return self.exports.export_xlsx(path)

    def export_csv(self, path: str | Path) -> bool:
        return self.exports.export_csv(path)

    def unfinished_work(self) -> list[str]:
        """What closing now would cut short: the xlsx export running, if any."""
        return self.exports.unfinished_work()

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        return self.exports.cancel_unfinished_work(timeout_ms)
