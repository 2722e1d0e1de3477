"""The Calibration tab: calibrate from a capture session, check the result, save or load it
(single pairs: `calibration_pairs.PairReview`; the warnings' remedies, the swap box, save and
load: `calibration_actions.CalibrationActions`).

Calibrate runs `stereo_gui.pipeline.calibration.calibration_job` in a JobWorker (detection of
every pair, then the core's calibrate_stereo) with a progress bar and Cancel. The results show
what the report showed (camera matrices without and with rectification, distortion) and what a
person can check (RMS per camera and stereo, baseline against the nominal one, epipolar error,
rotation between the cameras, rejected pairs). A bar chart gives each pair's reprojection error;
clicking a bar shows that pair rectified with horizontal lines, and the pair can be excluded
from the session and the rig recalibrated.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFrame,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import HARTLEY_NOTE
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.jobs import Progress
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.pipeline.calibration import (
    CalibrationRun,
    calibration_job,
    matrices_text,
)
from stereo_gui.qt.tabs.calibration_actions import CalibrationActions
from stereo_gui.qt.tabs.calibration_pairs import PairReview
from stereo_gui.qt.widgets.calibration_charts import (
    ErrorBarChart,
    RectifiedPairView,
)
from stereo_gui.qt.widgets.calibration_figures import CalibrationFigures, format_px
from stereo_gui.qt.widgets.calibration_warnings import CalibrationWarnings
from stereo_gui.qt.widgets.flow_layout import FlowLayout
from stereo_gui.qt.widgets.helpers import VerticalScroll, pane
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.job_worker import JobWorker

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

_MONO = QFont("Monospace")
_MONO.setStyleHint(QFont.StyleHint.TypeWriter)


class CalibrationTab(PairReview, CalibrationActions, QWidget):
    """Calibrate, review and save/load the stereo calibration (see module docstring)."""

    calibrationFinished = Signal(object)  # CalibrationRun

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.worker: JobWorker | None = None
        self.run: CalibrationRun | None = None
        self.calibration: StereoCalibration | None = None
        self._maps: RectifyMaps | None = None
        self._maps_for: StereoCalibration | None = None
        self.selected_pair: str | None = None
        self._pair_jobs = JobRunner("pair-view", self)  # reads and rectifies the pair clicked
        ctx.workers.register(self._pair_jobs)
        self._pair_jobs.finished.connect(self._pair_ready)
        self._pair_jobs.failed.connect(self._pair_failed)
        self._pair_job: int | None = None
        self._build()
        s = ctx.settings
        self.baseline_spin.setValue(float(s.nominal_baseline_mm))
        self.model_combo.setCurrentIndex(max(0, self.model_combo.findData(s.lens_model)))
        self.fix_k3_check.setChecked(bool(s.fix_k3))
        self.folder_edit.textChanged.connect(self._show_session_swap)
        self.folder_edit.textChanged.connect(self._folder_changed)
        if s.last_session:
            self.folder_edit.setText(str(s.last_session))
        ctx.calibration_model.changed.connect(self._calibration_changed)
        ctx.settings_model.changed.connect(self._settings_changed)
        if ctx.calibration is not None:
            self._calibration_changed(ctx.calibration)
        else:
            self._show_calibration(None)

    # ---- layout ------------------------------------------------------------------------------
    def _build(self) -> None:
        root = QVBoxLayout(self)

        row = QHBoxLayout()
        row.addWidget(QLabel("Pairs folder:"))
        self.folder_edit = QLineEdit()
        self.folder_edit.setPlaceholderText("a capture session, or a folder of chessboard-L1.png / "
                                            "chessboard-R1.png pairs")
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row.addWidget(self.folder_edit, 1)
        row.addWidget(browse)
        root.addLayout(row)

        # groups that wrap onto a second row on a narrow window (a laptop screen)
        options = QWidget()
        flow = FlowLayout(options, spacing=14)

        group = flow.add_group

        self.method_combo = QComboBox()
        self.method_combo.addItem("Bouguet (metric, from the board)", "bouguet")
        self.method_combo.addItem("Hartley (no metric scale)", "hartley")
        self.method_combo.setToolTip(HARTLEY_NOTE)
        group(QLabel("Method:"), self.method_combo)
        self.model_combo = QComboBox()
        self.model_combo.addItem("Pinhole (5)", "pinhole")
        self.model_combo.addItem("Rational (8)", "rational")
        self.model_combo.addItem("Fisheye", "fisheye")
        self.model_combo.setToolTip("Lens model: pinhole with 5 distortion coefficients (usual "
                                    "webcams), rational with 8, or fisheye for wide-angle webcams")
        self.model_combo.currentIndexChanged.connect(
            lambda: self.ctx.settings_model.update(lens_model=self.model_combo.currentData()))
        self.fix_k3_check = QCheckBox("Fix k3")
        self.fix_k3_check.setToolTip("Hold k3 (and the higher terms) at zero when the pairs cannot "
                                     "determine them; the warnings say when")
        self.fix_k3_check.toggled.connect(
            lambda on: self.ctx.settings_model.update(fix_k3=bool(on)))
        group(QLabel("Lens:"), self.model_combo, self.fix_k3_check)
        self.swap_check = QCheckBox("Swap L/R")
        self.swap_check.setToolTip("The cameras are swapped: exchange the left and right images "
                                   "of the session's pairs (the session remembers; the images stay "
                                   "as they were taken)")
        self.swap_check.toggled.connect(self._swap_toggled)
        self.alpha_spin = QDoubleSpinBox()
        self.alpha_spin.setRange(0.0, 1.0)
        self.alpha_spin.setSingleStep(0.1)
        self.alpha_spin.setValue(0.0)
        self.alpha_spin.setToolTip("stereoRectify alpha: 0 keeps only valid pixels (zoomed in), "
                                   "1 keeps every source pixel (black borders)")
        group(self.swap_check, QLabel("Alpha:"), self.alpha_spin)
        self.baseline_spin = QDoubleSpinBox()
        self.baseline_spin.setRange(1.0, 5000.0)
        self.baseline_spin.setDecimals(1)
        self.baseline_spin.setSuffix(" mm")
        self.baseline_spin.setValue(110.0)
        self.baseline_spin.valueChanged.connect(self._baseline_edited)
        group(QLabel("Nominal baseline:"), self.baseline_spin)
        self.calibrate_button = QPushButton("Calibrate")
        self.calibrate_button.clicked.connect(self.start_calibration)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.cancel_calibration)
        self.cancel_button.setEnabled(False)
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        self.progress.setFormat("%p%")
        self.progress.setMinimumWidth(160)
        group(self.calibrate_button, self.cancel_button, self.progress)
        root.addWidget(options)
        self.progress_label = QLabel("")
        self.progress_label.setStyleSheet("color: gray")
        root.addWidget(self.progress_label)

        split = QSplitter(Qt.Orientation.Horizontal)
        root.addWidget(split, 1)

        # left: figures and matrices
        left, ll = pane()
        self.figures = CalibrationFigures()
        ll.addWidget(self.figures)
        self.warnings = CalibrationWarnings()
        self.warnings.actionRequested.connect(self.apply_remedy)
        ll.addWidget(self.warnings)
        self.rejected_list = QListWidget()
        self.rejected_list.setMaximumHeight(56)
        self.rejected_list.setToolTip(
            "Click a pair to look at it (and include an excluded one again)")
        self.rejected_list.itemClicked.connect(
            lambda item: self.select_pair(item.data(Qt.ItemDataRole.UserRole)))
        ll.addWidget(QLabel("Rejected or excluded pairs:"))
        ll.addWidget(self.rejected_list)
        self.matrices_text = QPlainTextEdit()
        self.matrices_text.setReadOnly(True)
        self.matrices_text.setFont(_MONO)
        self.matrices_text.setLineWrapMode(QPlainTextEdit.LineWrapMode.NoWrap)
        self.matrices_text.setMinimumHeight(48)
        ll.addWidget(QLabel("Camera matrices (px) and distortion:"))
        ll.addWidget(self.matrices_text, 1)
        files = QHBoxLayout()
        self.load_button = QPushButton("Load calibration…")
        self.save_button = QPushButton("Save calibration…")
        self.load_button.clicked.connect(self._choose_load)
        self.save_button.clicked.connect(self._choose_save)
        files.addWidget(self.load_button)
        files.addWidget(self.save_button)
        files.addStretch(1)
        # scrolls rather than making the window taller than a laptop screen (1280x720: the
        # figures and the warnings alone are taller than the room left)
        left_scroll = VerticalScroll()
        left_scroll.setWidgetResizable(True)
        left_scroll.setFrameShape(QFrame.Shape.NoFrame)
        left_scroll.setWidget(left)
        # Load and Save stay in view under the scrolled figures: a new calibration is not saved
        # until Save is clicked, and at 1366x768 it was below the fold
        left_box, lb = pane()
        lb.addWidget(left_scroll, 1)
        lb.addLayout(files)
        split.addWidget(left_box)

        # right: chart and rectification check
        right = QSplitter(Qt.Orientation.Vertical)
        chart_box, cl = pane()
        self.chart = ErrorBarChart()
        self.chart.pairClicked.connect(self.select_pair)
        cl.addWidget(self.chart, 1)
        pair_row = QHBoxLayout()
        self.pair_label = QLabel("Click a bar to see that pair")
        self.exclude_button = QPushButton("Exclude pair")
        self.exclude_button.setToolTip("Mark the pair as excluded in the session (its files stay)")
        self.exclude_button.clicked.connect(self._toggle_exclude_selected)
        self.recalibrate_button = QPushButton("Recalibrate")
        self.recalibrate_button.clicked.connect(self.start_calibration)
        pair_row.addWidget(self.pair_label, 1)
        pair_row.addWidget(self.exclude_button)
        pair_row.addWidget(self.recalibrate_button)
        cl.addLayout(pair_row)
        above_row = QHBoxLayout()
        above_row.addWidget(QLabel("Threshold (red line, drag it):"))
        self.threshold_spin = QDoubleSpinBox()
        self.threshold_spin.setRange(0.0, 100.0)
        self.threshold_spin.setDecimals(3)
        self.threshold_spin.setSingleStep(0.01)
        self.threshold_spin.setSuffix(" px")
        self.threshold_spin.setToolTip("Pairs whose error in either camera is above this can be "
                                       "excluded at once")
        self.threshold_spin.valueChanged.connect(self._threshold_edited)
        self.chart.thresholdMoved.connect(self.threshold_spin.setValue)
        self.exclude_above_button = QPushButton("Exclude pairs above")
        self.exclude_above_button.clicked.connect(
            lambda: self.exclude_above(self.threshold_spin.value()))
        above_row.addWidget(self.threshold_spin)
        above_row.addWidget(self.exclude_above_button)
        above_row.addStretch(1)
        cl.addLayout(above_row)
        right.addWidget(chart_box)
        self.rect_view = RectifiedPairView()
        right.addWidget(self.rect_view)
        right.setSizes([300, 400])
        split.addWidget(right)
        split.setSizes([520, 760])
        self._update_buttons()

    # ---- settings ------------------------------------------------------------------------------
    def _settings_changed(self, s) -> None:
        # follow the capture tab's session unless a calibration is running
        if s.last_session and self.worker is None \
                and self.folder_edit.text() != str(s.last_session):
            self.folder_edit.setText(str(s.last_session))

    def _baseline_edited(self, v: float) -> None:
        if float(self.ctx.settings.nominal_baseline_mm) != v:
            self.ctx.settings_model.update(nominal_baseline_mm=float(v))
        self._show_figures()

    def set_active(self, active: bool) -> None:
        """Shown or hidden by the main window; this tab needs no live frames."""
        if active:
            self.ctx.frames.set_processor(None)

    def _browse(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Folder of calibration pairs",
                                                  self.folder_edit.text() or str(Path.home()))
        if folder:
            self.folder_edit.setText(folder)

    @property
    def board(self) -> BoardSpec:
        return self.ctx.settings.board

    # ---- calibration run -----------------------------------------------------------------------
    def start_calibration(self) -> bool:
        """Start calibrating the folder's included pairs; False if it cannot start."""
        if self.worker is not None:
            return False
        text = self.folder_edit.text().strip()
        if not text:
            self.ctx.report_error("choose the folder of calibration pairs first")
            return False
        folder = Path(text)
        if not folder.is_dir():
            self.ctx.report_error(f"folder {folder} does not exist")
            return False
        board = self._folder_board(folder) or self.board
        job = calibration_job(folder, board, float(self.alpha_spin.value()),
                              self.method_combo.currentData(), self.model_combo.currentData(),
                              self.fix_k3_check.isChecked())
        w = JobWorker(job, "calibration")
        w.progress.connect(self._progress)
        w.finished_ok.connect(self.use_run)
        w.failed.connect(self._failed)
        w.cancelled.connect(self._cancelled)
        w.done.connect(self._worker_done)
        self.ctx.workers.register(w)
        self.worker = w
        self.progress.setValue(0)
        self.progress_label.setText(f"Calibrating {folder} with a {board.label()} board…")
        self._update_buttons()
        w.start()
        return True

    def _folder_board(self, folder: Path) -> BoardSpec | None:
        """The board recorded in the session manifest, if any (it wins over the settings)."""
        try:
            from stereo_gui.files.session import CaptureSession

            b = CaptureSession.open(folder).board
        except (StereoGuiError, OSError):
            return None
        return b if isinstance(b, BoardSpec) else None

    def cancel_calibration(self) -> None:
        if self.worker is not None:
            self.worker.cancel()
            self.progress_label.setText("Cancelling at the next step…")

    def is_running(self) -> bool:
        return self.worker is not None

    def unsaved_calibration(self) -> str:
        """What closing now would lose: the calibration this tab computed, in use and not saved
        to a file ("" when there is none), e.g. "calibrated from /x/session (stereo RMS
        0.312 px)"."""
        run = self.run
        if run is None or self.ctx.calibration is not run.result.calibration \
                or self.ctx.calibration_path is not None:
            return ""
        rep = run.result.report
        quality = (f"stereo RMS {format_px(rep.rms_stereo)}" if rep.method != "hartley" else
                   f"epipolar error {format_px(rep.epipolar_error_px)}")
        return f"calibrated from {run.folder} ({rep.pairs_used} pairs, {quality})"

    def _progress(self, p: Progress) -> None:
        self.progress.setValue(p.percent)
        if p.text:
            self.progress_label.setText(p.text)

    def use_run(self, run: CalibrationRun) -> None:
        """Show a finished calibration run and use its calibration at once (what the tab does
        when its job ends)."""
        self.run = run
        self._maps = run.maps
        self._maps_for = run.result.calibration
        self.progress.setValue(100)
        rep = run.result.report
        quality = (f"stereo RMS {format_px(rep.rms_stereo)}" if rep.method != "hartley" else
                   f"epipolar error {format_px(rep.epipolar_error_px)}, Hartley: no metric scale")
        self.progress_label.setText(
            f"Done: {rep.pairs_used} of {rep.pairs_found} pairs used, {quality}. "
            f"Not saved yet: use Save calibration… to keep it.")
        # the new calibration is in use at once (live view, measurements)
        self.ctx.calibration_model.set(run.result.calibration, None)
        self.ctx.show_status(f"Calibrated from {rep.pairs_used} pairs in {run.folder}")
        self.calibrationFinished.emit(run)

    def _failed(self, message: str) -> None:
        self.progress.setValue(0)
        self.progress_label.setText(f"Calibration failed: {message}")
        self.ctx.report_error(message)

    def _cancelled(self) -> None:
        self.progress.setValue(0)
        self.progress_label.setText("Calibration cancelled")

    def _worker_done(self) -> None:
        w = self.worker
        self.worker = None
        if w is not None:
            self.ctx.workers.unregister(w)
            w.wait(2000)
            w.deleteLater()
        self._update_buttons()

    def unfinished_work(self) -> list[str]:
        """Nothing to wait for: a running calibration is cancelled on close (a computed one not
        saved is asked about, see `unsaved_calibration`)."""
        return []

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        return []

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Cancel a running calibration and join its thread."""
        if self.worker is None:
            return True
        return self.worker.stop(timeout_ms)

    # ---- showing a calibration -----------------------------------------------------------------
    def _calibration_changed(self, calib) -> None:
        if self.run is not None and calib is not self.run.result.calibration:
            self.run = None  # a loaded file replaces the last run
        elif self.run is not None and self.ctx.calibration_path is not None:
            # the run just saved: "Not saved yet" would be stale
            text = self.progress_label.text()
            if "Not saved yet" in text:
                self.progress_label.setText(text[:text.index("Not saved yet")]
                                            + f"Saved as {self.ctx.calibration_path.name}.")
        self._show_calibration(calib)

    def _show_calibration(self, calib: StereoCalibration | None) -> None:
        self.calibration = calib
        if calib is not self._maps_for:
            self._maps = None
            self._maps_for = None
        self._show_figures()
        self.warnings.show_warnings(self._warnings_of(calib))
        if calib is None:
            self.matrices_text.setPlainText("")
            self.chart.set_errors([], [], [])
            self.rect_view.clear_pair()
            self.rejected_list.clear()
            self._update_buttons()
            return
        self.matrices_text.setPlainText(matrices_text(calib))
        names = [p.name for p in calib.per_pair]
        self.chart.set_errors(names, [p.error_left for p in calib.per_pair],
                              [p.error_right for p in calib.per_pair])
        if self.chart.mean_px is not None:  # a start: twice the mean error
            self.threshold_spin.setValue(round(2.0 * self.chart.mean_px, 3))
        self._show_exclusions()
        if names and self.run is not None:
            keep = self.selected_pair
            if keep is not None and (keep in names or keep in self.run.excluded):
                self.select_pair(keep)  # an excluded pair stays in view, to include it again
            else:
                self.select_pair(names[0])
        else:
            self.rect_view.clear_pair()
        self._update_buttons()

    def _folder_changed(self) -> None:
        if self.calibration is not None and self.run is None:
            self._show_exclusions()  # the exclusions of the session now named

    def _show_figures(self) -> None:
        c = self.calibration
        nominal = float(self.baseline_spin.value())
        if c is None:
            self.figures.show_none()
            return
        path = self.ctx.calibration_path if self.ctx.calibration is c else None
        if path is not None:
            src = f"{Path(path).name} ({path})"
        elif self.run is not None and self.run.result.calibration is c:
            src = f"calibrated from {self.run.folder}, NOT SAVED"
        else:
            src = "not saved"
        if self.run is not None and self.run.result.calibration is c:
            rep = self.run.result.report
            txt = f"{rep.pairs_used} used of {rep.pairs_found}"
            if rep.rejected:
                txt += f", {len(rep.rejected)} rejected"
            if self.run.excluded:
                txt += f", {len(self.run.excluded)} excluded by you"
        else:
            txt = f"{len(c.per_pair)} used"
        self.figures.show_calibration(c, src, nominal, txt)

    def _warnings_of(self, calib):
        if calib is None:
            return ()
        if self.run is not None and self.run.result.calibration is calib:
            return self.run.result.report.warnings
        return tuple(calib.warnings)

    def _update_buttons(self) -> None:
        running = self.worker is not None
        self.calibrate_button.setEnabled(not running)
        self.recalibrate_button.setEnabled(not running and self.run is not None)
        self.cancel_button.setEnabled(running)
        self.save_button.setEnabled(self.calibration is not None and not running)
        self.load_button.setEnabled(not running)
        sel = self.selected_pair
        # after a restart (no run) a pair of the session can still be excluded or included
        pair = self._session_pair(sel) if sel is not None else None  # (one read of the session)
        known = sel is not None and (self.run is not None or pair is not None)
        self.exclude_button.setEnabled(not running and known)
        n_above = len(self.pairs_above(self.threshold_spin.value())) if not running else 0
        self.exclude_above_button.setText(
            f"Exclude {n_above} pair{'s' if n_above != 1 else ''} above")
        self.exclude_above_button.setEnabled(n_above > 0)
        if known:
            excluded = pair is not None and pair.excluded
            self.exclude_button.setText("Include pair again" if excluded else "Exclude pair")



