"""The Calibration tab: calibrate from a capture session, check the result, save or load it
(single pairs: `calibration_pairs.PairReview`; the warnings' remedies, the swap box, save and
load: `calibration_actions.CalibrationActions`; both are parts the tab owns and hands what they
use). The calibration shown is the one in use (the calibration model's); where the tab's run
stands is a `calibration_state.CalibrationState`, moved through its table.

Calibrate runs `stereo_gui.pipeline.calibration.calibration_job` in a JobWorker (detection of
every pair, then the core's calibrate_stereo) with a progress bar and Cancel. The results show
what the reference program showed (camera matrices without and with rectification, distortion)
and what a person can check (RMS per camera and stereo, baseline against the nominal one,
epipolar error, rotation between the cameras, rejected pairs). A bar chart gives each pair's reprojection error;
clicking a bar shows that pair rectified with horizontal lines, and the pair can be excluded
from the session and the rig recalibrated.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
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
from stereo_gui.core.stereo_calibration import ALPHA, StereoCalibration
from stereo_gui.core.uncertainty import CalibrationWarning
from stereo_gui.files.session import CaptureSession
from stereo_gui.files.settings import Settings
from stereo_gui.pipeline.calibration import (
    CalibrationRun,
    calibration_job,
    matrices_text,
)
from stereo_gui.qt.tabs.calibration_actions import CalibrationActions
from stereo_gui.qt.tabs.calibration_pairs import PairReview, SessionFolder
from stereo_gui.qt.tabs.calibration_state import CALIBRATION_MOVES, CalibrationState
from stereo_gui.qt.widgets.calibration_figures import CalibrationFigures, format_px
from stereo_gui.qt.widgets.calibration_warnings import CalibrationWarnings
from stereo_gui.qt.widgets.flow_layout import FlowLayout
from stereo_gui.qt.widgets.helpers import VerticalScroll, pane
from stereo_gui.qt.workers.job_worker import JobWorker

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

_MONO = QFont("Monospace")
_MONO.setStyleHint(QFont.StyleHint.TypeWriter)


def _alpha_declared() -> tuple[float, float, float]:
    """The alpha box's range and default: the calibration's declaration (ALPHA) of them."""
    lo, hi, default = ALPHA.lo, ALPHA.hi, ALPHA.default
    if lo is None or hi is None or not isinstance(default, int | float):
        raise TypeError("the calibration's alpha is declared without its range or default")
    return float(lo), float(hi), float(default)


class CalibrationTab(QWidget):
    """Calibrate, review and save/load the stereo calibration (see module docstring)."""

    calibrationFinished = Signal(CalibrationRun)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.worker: JobWorker | None = None
        self.run: CalibrationRun | None = None
        self._state = CalibrationState.IDLE
        self._done_line = ""  # what the line says of the run in use: "Done: 11 of 12 pairs..."
        self._session = SessionFolder(self._session_folder)
        self._build()
        s = ctx.settings
        self.baseline_spin.setValue(float(s.nominal_baseline_mm))
        self.model_combo.setCurrentIndex(max(0, self.model_combo.findData(s.lens_model)))
        self.fix_k3_check.setChecked(bool(s.fix_k3))
        self.folder_edit.textChanged.connect(self.calibration_actions.show_session_swap)
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
        root.addLayout(self._build_folder_row())
        root.addWidget(self._build_options())
        self.progress_label = QLabel("")
        self.progress_label.setStyleSheet("color: gray")
        root.addWidget(self.progress_label)

        split = QSplitter(Qt.Orientation.Horizontal)
        root.addWidget(split, 1)
        split.addWidget(self._build_results())
        split.addWidget(self._build_review())
        split.setSizes([520, 760])
        self._update_buttons()

    def _build_folder_row(self) -> QHBoxLayout:
        """The pairs folder and its Browse… button."""
        row = QHBoxLayout()
        row.addWidget(QLabel("Pairs folder:"))
        self.folder_edit = QLineEdit()
        self.folder_edit.setPlaceholderText("a capture session, or a folder of chessboard-L1.png / "
                                            "chessboard-R1.png pairs")
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        row.addWidget(self.folder_edit, 1)
        row.addWidget(browse)
        return row

    def _build_options(self) -> QWidget:
        """Method, lens, swap, alpha, baseline and Calibrate, with the parts they drive
        (`CalibrationActions`, `PairReview`)."""
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
        self._build_parts()
        self.alpha_spin = QDoubleSpinBox()
        lo, hi, default = _alpha_declared()
        self.alpha_spin.setRange(lo, hi)  # as declared
        self.alpha_spin.setSingleStep(0.1)
        self.alpha_spin.setValue(default)
        self.alpha_spin.setToolTip(ALPHA.help)
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
        return options

    def _build_parts(self) -> None:
        """The parts the tab owns: `CalibrationActions` (Load, Save, the warnings' remedies,
        the swap box) and `PairReview` (the pairs' chart and rectification check)."""
        model = self.ctx.calibration_model
        self.calibration_actions = CalibrationActions(
            model, self._session, self.ctx, self.start_calibration, self.fix_k3_check,
            self.folder_edit.text, self)
        self.review = PairReview(model, lambda: self.run, self._session, self.ctx,
                                 self.ctx.workers, self.is_running, self)
        self.swap_check = self.calibration_actions.swap_check

    def _build_results(self) -> QWidget:
        """The left side: figures, warnings, rejected pairs and matrices, over Load and Save."""
        left, ll = pane()
        self.figures = CalibrationFigures()
        ll.addWidget(self.figures)
        self.warnings = CalibrationWarnings()
        self.warnings.actionRequested.connect(self.calibration_actions.apply_remedy)
        ll.addWidget(self.warnings)
        self.rejected_list = self.review.rejected_list
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
        self.load_button.clicked.connect(self.calibration_actions.choose_load)
        self.save_button.clicked.connect(self.calibration_actions.choose_save)
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
        return left_box

    def _build_review(self) -> QSplitter:
        """The right side: the pairs' error chart over the rectification check."""
        right = QSplitter(Qt.Orientation.Vertical)
        chart_box, cl = pane()
        self.chart = self.review.chart
        cl.addWidget(self.chart, 1)
        pair_row = QHBoxLayout()
        self.pair_label = self.review.pair_label
        self.exclude_button = self.review.exclude_button
        self.recalibrate_button = QPushButton("Recalibrate")
        self.recalibrate_button.clicked.connect(self.start_calibration)
        pair_row.addWidget(self.pair_label, 1)
        pair_row.addWidget(self.exclude_button)
        pair_row.addWidget(self.recalibrate_button)
        cl.addLayout(pair_row)
        above_row = QHBoxLayout()
        above_row.addWidget(QLabel("Threshold (red line, drag it):"))
        self.threshold_spin = self.review.threshold_spin
        self.exclude_above_button = self.review.exclude_above_button
        above_row.addWidget(self.threshold_spin)
        above_row.addWidget(self.exclude_above_button)
        above_row.addStretch(1)
        cl.addLayout(above_row)
        right.addWidget(chart_box)
        self.rect_view = self.review.rect_view
        right.addWidget(self.rect_view)
        right.setSizes([300, 400])
        return right

    # ---- settings ------------------------------------------------------------------------------
    def _settings_changed(self, s: Settings) -> None:
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

    @property
    def calibration(self) -> StereoCalibration | None:
        """The calibration shown: the one in use (the calibration model's)."""
        return self.ctx.calibration_model.calibration

    @property
    def state(self) -> CalibrationState:
        """Where the tab's run stands (what the line under the options says)."""
        return self._state

    def _move(self, to: CalibrationState, line: str | None = None) -> None:
        """Move to `to` and say `line` (None: the line stays as it is); a move
        CALIBRATION_MOVES refuses is a bug (TransitionError)."""
        self._state = CALIBRATION_MOVES.check(self._state, to)
        if line is not None:
            self.progress_label.setText(line)

    def _session_folder(self) -> Path | None:
        """The folder of the session worked on: the last run's, else the Pairs folder typed."""
        if self.run is not None:
            return self.run.folder
        text = self.folder_edit.text()
        return Path(text) if text.strip() else None

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
        self._move(CalibrationState.RUNNING, f"Calibrating {folder} with a {board.label()} board…")
        self._update_buttons()
        w.start()
        return True

    def _folder_board(self, folder: Path) -> BoardSpec | None:
        """The board recorded in the session manifest, if any (it wins over the settings)."""
        try:
            b = CaptureSession.open(folder).board
        except (StereoGuiError, OSError):
            return None
        return b if isinstance(b, BoardSpec) else None

    def cancel_calibration(self) -> None:
        if self.worker is not None:
            self.worker.cancel()
            if self._state is CalibrationState.RUNNING:
                self._move(CalibrationState.CANCELLING, "Cancelling at the next step…")

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
        self.review.use_maps(run.maps, run.result.calibration)
        self.progress.setValue(100)
        rep = run.result.report
        quality = (f"stereo RMS {format_px(rep.rms_stereo)}" if rep.method != "hartley" else
                   f"epipolar error {format_px(rep.epipolar_error_px)}, Hartley: no metric scale")
        self._done_line = f"Done: {rep.pairs_used} of {rep.pairs_found} pairs used, {quality}. "
        self._move(CalibrationState.UNSAVED,
                   self._done_line + "Not saved yet: use Save calibration… to keep it.")
        # the new calibration is in use at once (live view, measurements)
        self.ctx.calibration_model.set(run.result.calibration, None)
        self.ctx.show_status(f"Calibrated from {rep.pairs_used} pairs in {run.folder}")
        self.calibrationFinished.emit(run)

    def _failed(self, message: str) -> None:
        self.progress.setValue(0)
        self._move(CalibrationState.FAILED, f"Calibration failed: {message}")
        self.ctx.report_error(message)

    def _cancelled(self) -> None:
        self.progress.setValue(0)
        self._move(CalibrationState.CANCELLED, "Calibration cancelled")

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
    def _calibration_changed(self, calib: StereoCalibration | None) -> None:
        run_replaced = self.run is not None and calib is not self.run.result.calibration
        if run_replaced:
            self.run = None  # a loaded file replaces the last run
            if self._state in (CalibrationState.UNSAVED, CalibrationState.SAVED):
                self._move(CalibrationState.IDLE)  # (the line still says what the run did)
        elif (self._state is CalibrationState.UNSAVED
              and self.ctx.calibration_path is not None):  # the run's calibration just saved
            self._move(CalibrationState.SAVED,
                       self._done_line + f"Saved as {self.ctx.calibration_path.name}.")
        self._show_calibration(calib)

    def _show_calibration(self, calib: StereoCalibration | None) -> None:
        self._show_figures()
        self.warnings.show_warnings(self._warnings_of(calib))
        self.matrices_text.setPlainText(matrices_text(calib) if calib is not None else "")
        self.review.show(calib)
        self._update_buttons()

    def _folder_changed(self) -> None:
        if self.calibration is not None and self.run is None:
            self.review.show_exclusions()  # the exclusions of the session now named

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

    def _warnings_of(self, calib: StereoCalibration | None) -> Sequence[CalibrationWarning]:
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
        self.review.update_buttons()
