"""The Calibration tab: calibrate from a capture session, check the result, save or load it.

Calibrate runs in a JobWorker (detection of every pair, then the core's calibrate_stereo) with a
progress bar and Cancel. The results show what the report showed (camera matrices without and
with rectification, distortion) and what a person can check (RMS per camera and stereo, baseline
against the nominal one, epipolar error, rotation between the cameras, rejected pairs). A bar
chart gives each pair's reprojection error; clicking a bar shows that pair rectified with
horizontal lines, and the pair can be excluded from the session and the rig recalibrated.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import HARTLEY_NOTE, CalibrationResult, calibrate_stereo
from stereo_gui.core.detect import PairDetection, PairInput, detect_pairs
from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.qt.calibration_worker import JobControl, JobWorker, Progress
from stereo_gui.qt.widgets import pane, wrapping_label

log = logging.getLogger(__name__)

LINE_EVERY_PX = 32  # rectification check: a horizontal line every this many rows
_BAR_LEFT = "#4f8fd6"
_BAR_RIGHT = "#e08a3c"
_BAR_SELECTED = "#f5e342"
_MONO = QFont("Monospace")
_MONO.setStyleHint(QFont.StyleHint.TypeWriter)


@dataclass(frozen=True, eq=False)
class CalibrationRun:
    """What a calibration job returns: the result, detections by pair name, rectify maps."""

    result: CalibrationResult
    detections: dict[str, PairDetection]
    files: dict[str, tuple[str, str]]  # pair name -> (left file, right file)
    maps: RectifyMaps
    folder: Path
    excluded: tuple[str, ...]  # pairs left out by the user (session exclusions)


def _read(path: str) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"cannot read image {path}")
    return img


def calibration_job(folder: Path, board: BoardSpec, alpha: float, method: str):
    """A JobWorker job: detect the board in the session's included pairs and calibrate."""

    def job(control: JobControl):
        from stereo_gui.files.session import CaptureSession

        yield Progress(0, 1, f"reading {folder}")
        session = CaptureSession.open(folder)
        included = list(session.included_pairs())
        excluded = tuple(p.name for p in session.pairs if p.excluded)
        if not included:
            raise InputError(f"{folder} has no image pairs to calibrate from"
                             + (f" ({len(excluded)} excluded)" if excluded else ""))
        files = {p.name: (str(p.left), str(p.right)) for p in included}
        inputs = [PairInput(p.name, (lambda f=p.left: _read(f)),
                            (lambda f=p.right: _read(f)),
                            Path(p.left).name, Path(p.right).name) for p in included]
        n = len(inputs)
        total = n + 10
        yield Progress(0, total, f"finding the board in {n} pairs")
        dets = detect_pairs(
            inputs, board, cancel=control,
            progress=lambda d, t, s: control.report(d, total, f"finding the board: {s}"))
        yield Progress(n, total, "calibrating")
        result = calibrate_stereo(
            dets, board, alpha=alpha, method=method, cancel=control,
            progress=lambda d, t, s: control.report(n + round(9 * d / max(t, 1)), total, s))
        control.check()
        yield Progress(n + 9, total, "computing rectification maps")
        maps = result.calibration.rectify_maps()
        return CalibrationRun(result, {d.name: d for d in dets}, files, maps, Path(folder),
                              excluded)

    return job


def _fmt_matrix(m: np.ndarray | None, digits: int = 3) -> str:
    if m is None:
        return "  (not available)"
    m = np.atleast_2d(np.asarray(m, np.float64))
    cells = [[f"{v:.{digits}f}" for v in row] for row in m]
    width = max(len(c) for row in cells for c in row)
    return "\n".join("  [ " + "  ".join(c.rjust(width) for c in row) + " ]" for row in cells)


def _dist_text(d: np.ndarray) -> str:
    d = np.asarray(d, np.float64).reshape(-1)
    names = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty"]
    return "  " + "  ".join(f"{n}={v:+.5f}" for n, v in zip(names, d, strict=False))


def matrices_text(calib: StereoCalibration) -> str:
    """The camera matrices and distortion as the report shows them, plus the rectified ones."""
    parts = []
    for side, M, opt, D, P in (("left", calib.M1, calib.optimal_M1, calib.D1, calib.P1),
                               ("right", calib.M2, calib.optimal_M2, calib.D2, calib.P2)):
        parts += [
            f"Matrix M without rectification ({side} camera, {'M1' if side == 'left' else 'M2'}):",
            _fmt_matrix(M, 2),
            f"Matrix Mrekt rectified ({side} camera, getOptimalNewCameraMatrix alpha=1):",
            _fmt_matrix(opt, 2),
            f"Rectified projection {'P1' if side == 'left' else 'P2'} ({side}, used for depth):",
            _fmt_matrix(P, 2),
            f"Distortion {'D1' if side == 'left' else 'D2'} ({side}):",
            _dist_text(D),
            "",
        ]
    parts += ["Rotation R (left camera frame -> right camera frame):", _fmt_matrix(calib.R, 5),
              "Translation T (mm):", _fmt_matrix(np.asarray(calib.T).reshape(1, 3), 3)]
    return "\n".join(parts)


class ErrorBarChart(pg.PlotWidget):
    """Reprojection error per pair (left and right bars); a click selects a pair."""

    pairClicked = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setLabel("left", "reprojection error", units="px")
        self.getAxis("left").enableAutoSIPrefix(False)  # not "mpx"
        self.getAxis("bottom").enableAutoSIPrefix(False)  # not "pair (x0.001)" while empty
        self.setLabel("bottom", "pair")
        self.setMouseEnabled(x=False, y=False)
        self.hideButtons()
        self.setMenuEnabled(False)
        self.addLegend(offset=(-10, 10))
        self.names: list[str] = []
        self.selected: str | None = None
        self._left = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_LEFT, name="left")
        self._right = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_RIGHT, name="right")
        self._mark = pg.BarGraphItem(x=[], height=[], width=0.9, brush=pg.mkBrush(245, 227, 66, 90),
                                     pen=pg.mkPen(_BAR_SELECTED, width=2))
        for it in (self._mark, self._left, self._right):
            self.addItem(it)
        self.scene().sigMouseClicked.connect(self._clicked)
        self.setToolTip("Click a bar to look at that pair (and exclude it if it is bad)")

    def set_errors(self, names: list[str], left: list[float], right: list[float]) -> None:
        self.names = list(names)
        x = np.arange(len(names), dtype=float)
        self._left.setOpts(x=x - 0.2, height=np.asarray(left, float))
        self._right.setOpts(x=x + 0.2, height=np.asarray(right, float))
        ax = self.getAxis("bottom")
        step = max(1, math.ceil(len(names) / 25))
        ax.setTicks([[(i, _short(n)) for i, n in enumerate(names) if i % step == 0], []])
        top = max([*left, *right, 0.1])
        self.setXRange(-0.7, max(len(names) - 0.3, 0.5), padding=0)
        self.setYRange(0, top * 1.15, padding=0)
        self.select(self.selected if self.selected in self.names else None)

    def bar_count(self) -> int:
        return len(self.names)

    def heights(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(self._left.opts["height"]), np.asarray(self._right.opts["height"]))

    def select(self, name: str | None) -> None:
        self.selected = name
        if name is None or name not in self.names:
            self._mark.setOpts(x=[], height=[])
            return
        i = self.names.index(name)
        lh, rh = self.heights()
        self._mark.setOpts(x=[float(i)], height=[float(max(lh[i], rh[i])) * 1.05 + 1e-3])

    def _clicked(self, ev) -> None:
        if not self.names:
            return
        p = self.plotItem.vb.mapSceneToView(ev.scenePos())
        i = int(round(p.x()))
        inside = self.plotItem.vb.sceneBoundingRect().contains(ev.scenePos())
        if inside and 0 <= i < len(self.names):
            self.select(self.names[i])
            self.pairClicked.emit(self.names[i])


def _short(name: str) -> str:
    """A short tick label: the number of 'chessboard-L3' style names, else the name."""
    digits = "".join(ch for ch in name if ch.isdigit())
    return digits if digits and len(name) > 6 else name


class RectifiedPairView(pg.GraphicsLayoutWidget):
    """A rectified pair side by side with horizontal lines: matching points sit on one line."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setBackground("#202020")
        self.title = pg.LabelItem("Rectification check: select a pair", color="w")
        self.addItem(self.title, row=0, col=0)
        self.vb = self.addViewBox(row=1, col=0, lockAspect=True, enableMouse=True)
        self.vb.invertY(True)
        self.image = pg.ImageItem(axisOrder="row-major")
        self.vb.addItem(self.image)
        self.lines = pg.PlotCurveItem(pen=pg.mkPen((80, 255, 80, 150), width=1), connect="pairs")
        self.vb.addItem(self.lines)
        self.shown: str | None = None

    def show_pair(self, name: str, left_rect: np.ndarray, right_rect: np.ndarray,
                  note: str = "") -> None:
        h, w = left_rect.shape[:2]
        gap = np.zeros((h, 6, 3), np.uint8)
        both = np.ascontiguousarray(np.hstack([left_rect, gap, right_rect])[:, :, ::-1])
        self.image.setImage(both, levels=(0, 255), autoLevels=False)
        ys = np.arange(LINE_EVERY_PX // 2, h, LINE_EVERY_PX, dtype=float)
        xs = np.tile([0.0, float(both.shape[1])], len(ys))
        self.lines.setData(xs, np.repeat(ys, 2))
        self.vb.setRange(xRange=(0, both.shape[1]), yRange=(0, h), padding=0.01)
        self.title.setText(f"Rectified pair {name}: left | right. A point should lie on the same "
                           f"row in both{note}")
        self.shown = name

    def clear_pair(self) -> None:
        self.image.clear()
        self.lines.setData([], [])
        self.title.setText("Rectification check: select a pair")
        self.shown = None


class CalibrationTab(QWidget):
    """Calibrate, review and save/load the stereo calibration (see module docstring)."""

    calibrationFinished = Signal(object)  # CalibrationRun

    def __init__(self, ctx, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.worker: JobWorker | None = None
        self.run: CalibrationRun | None = None
        self.calibration: StereoCalibration | None = None
        self._maps: RectifyMaps | None = None
        self._maps_for: StereoCalibration | None = None
        self.selected_pair: str | None = None
        self._build()
        s = ctx.settings
        self.baseline_spin.setValue(float(s.nominal_baseline_mm))
        if s.last_session:
            self.folder_edit.setText(str(s.last_session))
        ctx.calibrationChanged.connect(self._calibration_changed)
        ctx.settingsChanged.connect(self._settings_changed)
        ctx.currentTabChanged.connect(lambda name: self.set_active(name == "calibration"))
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

        row = QHBoxLayout()
        row.addWidget(QLabel("Method:"))
        self.method_combo = QComboBox()
        self.method_combo.addItem("Bouguet (metric, from the board)", "bouguet")
        self.method_combo.addItem("Hartley (no metric scale)", "hartley")
        self.method_combo.setToolTip(HARTLEY_NOTE)
        row.addWidget(self.method_combo)
        row.addWidget(QLabel("Alpha:"))
        self.alpha_spin = QDoubleSpinBox()
        self.alpha_spin.setRange(0.0, 1.0)
        self.alpha_spin.setSingleStep(0.1)
        self.alpha_spin.setValue(0.0)
        self.alpha_spin.setToolTip("stereoRectify alpha: 0 keeps only valid pixels (zoomed in), "
                                   "1 keeps every source pixel (black borders)")
        row.addWidget(self.alpha_spin)
        row.addWidget(QLabel("Nominal baseline:"))
        self.baseline_spin = QDoubleSpinBox()
        self.baseline_spin.setRange(1.0, 5000.0)
        self.baseline_spin.setDecimals(1)
        self.baseline_spin.setSuffix(" mm")
        self.baseline_spin.setValue(110.0)
        self.baseline_spin.valueChanged.connect(self._baseline_edited)
        row.addWidget(self.baseline_spin)
        row.addSpacing(16)
        self.calibrate_button = QPushButton("Calibrate")
        self.calibrate_button.clicked.connect(self.start_calibration)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.cancel_calibration)
        self.cancel_button.setEnabled(False)
        row.addWidget(self.calibrate_button)
        row.addWidget(self.cancel_button)
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        self.progress.setFormat("%p%")
        row.addWidget(self.progress, 1)
        root.addLayout(row)
        self.progress_label = QLabel("")
        self.progress_label.setStyleSheet("color: gray")
        root.addWidget(self.progress_label)

        split = QSplitter(Qt.Orientation.Horizontal)
        root.addWidget(split, 1)

        # left: figures and matrices
        left, ll = pane()
        figures = QGroupBox("Result")
        form = QFormLayout(figures)
        self.source_label = wrapping_label()
        self.rms_left_label = QLabel()
        self.rms_right_label = QLabel()
        self.rms_stereo_label = QLabel()
        self.epipolar_label = QLabel()
        self.baseline_label = QLabel()
        self.rotation_label = QLabel()
        self.pairs_label = wrapping_label()
        form.addRow("Calibration:", self.source_label)
        form.addRow("RMS left camera:", self.rms_left_label)
        form.addRow("RMS right camera:", self.rms_right_label)
        form.addRow("RMS stereo:", self.rms_stereo_label)
        form.addRow("Epipolar error:", self.epipolar_label)
        form.addRow("Baseline:", self.baseline_label)
        form.addRow("Rotation between cameras:", self.rotation_label)
        form.addRow("Pairs:", self.pairs_label)
        self.note_label = wrapping_label()
        self.note_label.setStyleSheet("color: #b03a2e; font-weight: bold")
        form.addRow(self.note_label)
        ll.addWidget(figures)
        self.rejected_list = QListWidget()
        self.rejected_list.setMaximumHeight(80)
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
        ll.addLayout(files)
        split.addWidget(left)

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
            self.ctx.update_settings(nominal_baseline_mm=float(v))
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
                              self.method_combo.currentData())
        w = JobWorker(job, "calibration")
        w.progress.connect(self._progress)
        w.finished_ok.connect(self._finished)
        w.failed.connect(self._failed)
        w.cancelled.connect(self._cancelled)
        w.done.connect(self._worker_done)
        self.ctx.register_worker(w)
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

            b = getattr(CaptureSession.open(folder), "board", None)
        except (StereoGuiError, OSError):
            return None
        return b if isinstance(b, BoardSpec) else None

    def cancel_calibration(self) -> None:
        if self.worker is not None:
            self.worker.cancel()
            self.progress_label.setText("Cancelling at the next step…")

    def is_running(self) -> bool:
        return self.worker is not None

    def _progress(self, p: Progress) -> None:
        self.progress.setValue(p.percent)
        if p.text:
            self.progress_label.setText(p.text)

    def _finished(self, run: CalibrationRun) -> None:
        self.run = run
        self._maps = run.maps
        self._maps_for = run.result.calibration
        self.progress.setValue(100)
        rep = run.result.report
        quality = (f"stereo RMS {_px(rep.rms_stereo)}" if rep.method != "hartley" else
                   f"epipolar error {_px(rep.epipolar_error_px)}, Hartley: no metric scale")
        self.progress_label.setText(
            f"Done: {rep.pairs_used} of {rep.pairs_found} pairs used, {quality}. "
            f"Not saved yet: use Save calibration… to keep it.")
        # the new calibration is in use at once (live view, measurements)
        self.ctx.set_calibration(run.result.calibration, None)
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
            self.ctx.unregister_worker(w)
            w.wait(2000)
            w.deleteLater()
        self._update_buttons()

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Cancel a running calibration and join its thread."""
        if self.worker is None:
            return True
        return self.worker.stop(timeout_ms)

    # ---- showing a calibration -----------------------------------------------------------------
    def _calibration_changed(self, calib) -> None:
        if self.run is not None and calib is not self.run.result.calibration:
            self.run = None  # a loaded file replaces the last run
        self._show_calibration(calib)

    def _show_calibration(self, calib: StereoCalibration | None) -> None:
        self.calibration = calib
        if calib is not self._maps_for:
            self._maps = None
            self._maps_for = None
        self._show_figures()
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
        self.rejected_list.clear()
        if self.run is not None:
            entries = [(r.name, f"{r.name}: {r.reason}") for r in self.run.result.report.rejected]
            entries += [(n, f"{n}: excluded by you") for n in self.run.excluded]
            for name, text in entries:
                item = QListWidgetItem(text)
                item.setData(Qt.ItemDataRole.UserRole, name)
                item.setToolTip(text)
                self.rejected_list.addItem(item)
        if self.rejected_list.count() == 0:
            item = QListWidgetItem("none")
            item.setFlags(Qt.ItemFlag.NoItemFlags)
            self.rejected_list.addItem(item)
        if names and self.run is not None:
            keep = self.selected_pair
            if keep is not None and (keep in names or keep in self.run.excluded):
                self.select_pair(keep)  # an excluded pair stays in view, to include it again
            else:
                self.select_pair(names[0])
        else:
            self.rect_view.clear_pair()
        self._update_buttons()

    def _show_figures(self) -> None:
        c = self.calibration
        nominal = float(self.baseline_spin.value())
        if c is None:
            for lab in (self.rms_left_label, self.rms_right_label, self.rms_stereo_label,
                        self.epipolar_label, self.baseline_label, self.rotation_label,
                        self.pairs_label):
                lab.setText("—")
            self.source_label.setText("none yet: calibrate, or load a calibration file")
            self.note_label.setText("")
            return
        path = self.ctx.calibration_path if self.ctx.calibration is c else None
        if path is not None:
            src = f"{Path(path).name} ({path})"
        elif self.run is not None and self.run.result.calibration is c:
            src = f"calibrated from {self.run.folder}, NOT SAVED"
        else:
            src = "not saved"
        self.source_label.setText(f"{src}; {c.image_size[0]}x{c.image_size[1]} px, "
                                  f"board {c.board.label() if c.board else 'unknown'}, "
                                  f"method {c.method}, alpha {c.alpha:g}, created {c.created}")
        self.rms_left_label.setText(_px(c.rms_left))
        self.rms_right_label.setText(_px(c.rms_right))
        self.rms_stereo_label.setText(_px(c.rms_stereo) if math.isfinite(c.rms_stereo)
                                      else "— (no stereo solve in Hartley's method)")
        self.epipolar_label.setText(f"{_px(c.epipolar_error_px)} mean |y left − y right| of the "
                                    f"corners after rectification")
        if c.metric:
            b = c.baseline_mm
            diff = b - nominal + 0.0  # + 0.0: no "-0.00"
            if abs(diff) < 0.005:
                diff = 0.0
            self.baseline_label.setText(
                f"{b:.2f} mm (nominal {nominal:.1f} mm, difference {diff:+.2f} mm, "
                f"{100 * diff / nominal:+.2f} %)")
            self.note_label.setText("")
        else:
            self.baseline_label.setText("no metric scale (Hartley): distances are not in mm")
            self.note_label.setText(HARTLEY_NOTE)
        self.rotation_label.setText(f"{c.relative_rotation_deg:.3f}°")
        if self.run is not None and self.run.result.calibration is c:
            rep = self.run.result.report
            txt = f"{rep.pairs_used} used of {rep.pairs_found}"
            if rep.rejected:
                txt += f", {len(rep.rejected)} rejected"
            if self.run.excluded:
                txt += f", {len(self.run.excluded)} excluded by you"
            self.pairs_label.setText(txt)
        else:
            self.pairs_label.setText(f"{len(c.per_pair)} used")

    # ---- pairs: select, rectification check, exclude --------------------------------------------
    def select_pair(self, name: str) -> None:
        """Show pair `name` rectified (when its files are known) and offer to exclude it."""
        self.selected_pair = name
        self.chart.select(name)
        c = self.calibration
        err = next((p for p in (c.per_pair if c else ()) if p.name == name), None)
        txt = f"Pair {name}"
        if err is not None:
            txt += f": error left {err.error_left:.3f} px, right {err.error_right:.3f} px"
        self.pair_label.setText(txt)
        self._update_buttons()
        files = self._pair_files(name)
        if c is None or files is None:
            self.rect_view.clear_pair()
            self.rect_view.title.setText(f"Pair {name}: images not available (calibrate from "
                                         f"the session to see them)")
            return
        try:
            left, right = _read(files[0]), _read(files[1])
        except StereoGuiError as exc:
            self.ctx.report_error(str(exc))
            return
        if (left.shape[1], left.shape[0]) != tuple(c.image_size):
            self.rect_view.clear_pair()
            return
        maps = self._rectify_maps(c)
        lr = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
        rr = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
        note = " (Hartley: row-aligned, no metric scale)" if not c.metric else ""
        self.rect_view.show_pair(name, lr, rr, note)

    def _rectify_maps(self, c: StereoCalibration) -> RectifyMaps:
        if self._maps is None or self._maps_for is not c:
            self._maps = c.rectify_maps()
            self._maps_for = c
        return self._maps

    def _pair_files(self, name: str) -> tuple[str, str] | None:
        if self.run is not None and name in self.run.files:
            return self.run.files[name]
        if self.run is not None:  # an excluded pair: not in the run, but in the session
            try:
                p = self._session().pair(name)
            except (StereoGuiError, OSError):
                return None
            return (str(p.left), str(p.right))
        return None

    def rejected_lines(self) -> list[str]:
        """The texts of the rejected/excluded list (for tests and screenshots)."""
        return [self.rejected_list.item(i).text() for i in range(self.rejected_list.count())]

    def _session(self):
        from stereo_gui.files.session import CaptureSession

        folder = self.run.folder if self.run is not None else Path(self.folder_edit.text())
        return CaptureSession.open(folder)

    def _is_excluded(self, name: str) -> bool:
        try:
            s = self._session()
        except (StereoGuiError, OSError):
            return False
        return any(p.name == name and getattr(p, "excluded", False) for p in s.pairs)

    def _toggle_exclude_selected(self) -> None:
        name = self.selected_pair
        if name is None:
            return
        self.set_excluded(name, not self._is_excluded(name))

    def set_excluded(self, name: str, excluded: bool = True) -> None:
        """Exclude (or include again) a pair in the session; Recalibrate then leaves it out."""
        try:
            self._session().set_excluded(name, excluded)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not change pair {name}: {exc}")
            return
        self.ctx.show_status(f"Pair {name} {'excluded' if excluded else 'included again'}: "
                             f"press Recalibrate")
        self.pair_label.setText(f"Pair {name} {'excluded' if excluded else 'included'}: press "
                                f"Recalibrate")
        self._update_buttons()

    # ---- files ---------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        if self.calibration is None:
            return
        start = str(self.ctx.calibration_path or (Path(self.folder_edit.text() or Path.home())
                                                   / "calibration.yaml"))
        path, _ = QFileDialog.getSaveFileName(self, "Save calibration", start,
                                              "OpenCV YAML (*.yaml *.yml)")
        if path:
            self.save_calibration(path)

    def save_calibration(self, path: str | Path) -> bool:
        return self.ctx.save_calibration_file(self.calibration, path)

    def _choose_load(self) -> None:
        cp = self.ctx.calibration_path
        start = str(cp.parent) if cp else str(Path.home())
        path, _ = QFileDialog.getOpenFileName(
            self, "Load calibration (ours, OpenCV's, ROS's or Middlebury's)", start,
            "Calibration files (*.yaml *.yml *.xml *.txt);;All files (*)")
        if path:
            self.load_calibration(path)

    def load_calibration(self, path: str | Path) -> bool:
        return self.ctx.open_calibration_file(path)

    def _update_buttons(self) -> None:
        running = self.worker is not None
        self.calibrate_button.setEnabled(not running)
        self.recalibrate_button.setEnabled(not running and self.run is not None)
        self.cancel_button.setEnabled(running)
        self.save_button.setEnabled(self.calibration is not None and not running)
        self.load_button.setEnabled(not running)
        sel = self.selected_pair
        self.exclude_button.setEnabled(not running and sel is not None and self.run is not None)
        if sel is not None and self.run is not None:
            self.exclude_button.setText("Include pair again" if self._is_excluded(sel)
                                        else "Exclude pair")


def _px(v: float) -> str:
    return f"{v:.3f} px" if v is not None and math.isfinite(v) else "—"
