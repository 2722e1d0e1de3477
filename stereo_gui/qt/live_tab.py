"""The Live tab: rectified pair, disparity views, the WLS colour view, parameters, click-to-measure.

Work is split by thread:
- the frame worker runs `stereo_gui.pipeline.live.LiveProcessor` on every frame: the pipeline
  (rectify, SGBM, closing, WLS, colour map) and the conversion of each view into a displayable
  uint8 image;
- a double-click becomes a `measure_point` job on the context's job thread, run on the result
  that was on screen when the user clicked;
- the UI thread only hands arrays to pyqtgraph, reads one pixel for the hover readout, and draws
  markers.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from pathlib import Path

import cv2
import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QMenu,
    QPushButton,
    QScrollArea,
    QSplitter,
    QStackedWidget,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.matching import COLORMAPS, MatcherParams
from stereo_gui.pipeline.live import LiveOutput, LiveProcessor
from stereo_gui.qt.widgets.image_view import ImagePanel, marker_color
from stereo_gui.qt.widgets.params_panel import ParamsPanel, load_preset
from stereo_gui.qt.widgets.playback_bar import PlaybackBar
from stereo_gui.qt.workers.recorder import (
    describe_result,
    format_elapsed,
    new_recording_folder,
    recordings_dir,
)
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

# view key -> title; all views are in rectified-left pixel coordinates except "right"
VIEWS: dict[str, str] = {
    "left": "Rectified left",
    "right": "Rectified right",
    "raw": "Raw disparity (SGBM), bright = near, dark red = no match",
    "closed": "After the closing filter, dark red = no match",
    "wls": "WLS filtered, colour = distance, dark red = no match",
}
SHORT_NAMES = {"left": "Left", "right": "Right", "raw": "Raw", "closed": "Closed", "wls": "WLS"}
DEFAULT_VIEWS = ("left", "raw", "closed", "wls")
MEASURABLE = ("left", "raw", "closed", "wls")  # views sharing the left image's pixel frame
TRUE_CALIBRATION_NOTE = "simulated rig's TRUE calibration"
RECORD_TEXT = "● Record"
# depth exports of the frame shown: key -> (menu text, file suffix, what the file holds)
EXPORTS: dict[str, tuple[str, str, str]] = {
    "disparity_png": ("Disparity, 16-bit PNG (x16)…", "-disparity-x16.png",
                      "disparity as 16-bit PNG (OpenCV's x16 fixed point, 0 = invalid)"),
    "disparity_npy": ("Disparity, float32 .npy…", "-disparity.npy",
                      "disparity in px as float32 .npy (NaN = invalid)"),
    "depth_png": ("Depth in mm, 16-bit PNG…", "-depth-mm.png",
                  "depth in mm as 16-bit PNG (0 = invalid)"),
    "ply": ("Point cloud, coloured PLY…", "-cloud.ply", "coloured point cloud (binary PLY, mm)"),
}


def _stamp() -> str:
    return _dt.datetime.now().strftime("%Y%m%d-%H%M%S")


def format_distance(mm: float) -> str:
    """A distance for a label: metres with mm resolution from 1 m on, else millimetres."""
    if not math.isfinite(mm):
        return "–"
    return f"{mm / 1000:.3f} m" if abs(mm) >= 1000 else f"{mm:.1f} mm"


# ---- the tab ----------------------------------------------------------------------------------
class _NoCalibrationPage(QWidget):
    """Shown instead of the views while there is no calibration."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        title = QLabel("<h2>No calibration loaded</h2>")
        text = QLabel("The live depth view needs a calibration of the stereo camera. "
                      "Calibrate it from chessboard pairs, or load a calibration file.")
        text.setWordWrap(True)
        self.calibrate = QPushButton("Calibrate…")
        self.load = QPushButton("Load a calibration file…")
        self.use_true = QPushButton("Use the simulated rig's true calibration")
        self.use_true.setToolTip("Only for the simulated rig: the calibration it was built with. "
                                 "It is labelled as such in the status bar.")
        col = QVBoxLayout(self)
        col.addStretch(1)
        for w in (title, text):
            w.setAlignment(Qt.AlignmentFlag.AlignCenter)
            col.addWidget(w)
        row = QHBoxLayout()
        row.addStretch(1)
        for b in (self.calibrate, self.load, self.use_true):
            row.addWidget(b)
        row.addStretch(1)
        col.addLayout(row)
        col.addStretch(2)


class LiveTab(QWidget):
    """The Live tab. `ctx` is the AppContext."""

    calibrateRequested = Signal()
    loadCalibrationRequested = Signal()
    measured = Signal(object)  # Measurement, after its marker was drawn
    frameShown = Signal()  # a new frame was drawn (for tests and benchmarks)

    def __init__(self, ctx, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._active = False
        self._processor: LiveProcessor | None = None
        self._output: LiveOutput | None = None
        self._hover: tuple[str, float, float] | None = None
        self._pending: dict[int, tuple[str, bool]] = {}  # job id -> (view key, ruler click)
        self._ruler_a = None  # first Measurement of a ruler pair
        self._bar_state = None
        self._scale_note = ""
        self._exports: dict[int, str] = {}  # job id -> what is being exported
        self.shown_frame: StereoFrame | None = None  # the raw frame of the result shown
        self.last_export: list[Path] = []  # files written by the last finished export
        self.frames_shown = 0

        # params
        self.params_panel = ParamsPanel(self._initial_params())
        self.params_panel.paramsChanged.connect(self._params_changed)
        scroll = QScrollArea()
        scroll.setWidget(self.params_panel)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        scroll.setMinimumWidth(self.params_panel.sizeHint().width()
                               + scroll.verticalScrollBar().sizeHint().width() + 4)

        # views
        self.panels: dict[str, ImagePanel] = {}
        self.view_checks: dict[str, QCheckBox] = {}
        shown = tuple(v for v in (ctx.settings.visible_views or DEFAULT_VIEWS)
                      if v in VIEWS) or DEFAULT_VIEWS
        for key, title in VIEWS.items():
            panel = ImagePanel(key, title, color_bar=(key == "wls"))
            panel.hovered.connect(self._hovered)
            panel.doubleClicked.connect(self._double_clicked)
            self.panels[key] = panel
            check = QCheckBox(SHORT_NAMES[key])
            check.setToolTip(title)
            check.setChecked(key in shown)
            check.toggled.connect(self._layout_views)
            self.view_checks[key] = check
        self._grid_host = QWidget()
        self._grid = QGridLayout(self._grid_host)
        self._grid.setContentsMargins(0, 0, 0, 0)
        self._grid.setSpacing(4)

        # toolbar
        self.pause_button = QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.pause_button.toggled.connect(self.set_paused)
        self.snapshot_button = QPushButton("Snapshot…")
        self.snapshot_button.setToolTip("Save the views shown as PNG files")
        self.snapshot_button.clicked.connect(self._snapshot_clicked)
        self.ruler_button = QPushButton("Ruler")
        self.ruler_button.setCheckable(True)
        self.ruler_button.setToolTip("Double-click two points to measure the 3D distance between them")
        self.ruler_button.toggled.connect(self._ruler_toggled)
        self.clear_button = QPushButton("Clear")
        self.clear_button.setToolTip("Remove all distance markers")
        self.clear_button.clicked.connect(self.clear_markers)
        self.fit_button = QPushButton("Fit")
        self.fit_button.setToolTip("Show the whole image in every view again (after zooming with "
                                   "the mouse wheel or panning)")
        self.fit_button.clicked.connect(self.fit_views)
        self.export_button = QToolButton()
        self.export_button.setText("Export frame ▾")
        # the arrow is in the text: the style's own indicator overlaps it
        self.export_button.setStyleSheet("QToolButton::menu-indicator { image: none; }")
        self.export_button.setToolTip("Write the depth of the frame shown for other tools")
        self.export_button.setPopupMode(QToolButton.ToolButtonPopupMode.InstantPopup)
        export_menu = QMenu(self.export_button)
        for key, (text, _suffix, _what) in EXPORTS.items():
            export_menu.addAction(text, lambda k=key: self._export_clicked(k))
        export_menu.addSeparator()
        export_menu.addAction("All four into a folder…", self._export_all_clicked)
        self.export_button.setMenu(export_menu)
        self.record_button = QToolButton()
        self.record_button.setText(RECORD_TEXT)
        self.record_button.setCheckable(True)
        self.record_button.setPopupMode(QToolButton.ToolButtonPopupMode.MenuButtonPopup)
        self.record_button.setStyleSheet(
            "QToolButton:checked { background: #c62828; color: white; font-weight: bold; }")
        # wide enough for the running time, so the toolbar does not jump (the frame count is in
        # the status bar and the tooltip)
        self.record_button.setMinimumWidth(self.record_button.fontMetrics().horizontalAdvance(
            "■ Stop 00:00") + 40)
        self.record_button.clicked.connect(self._record_clicked)
        record_menu = QMenu(self.record_button)
        record_menu.addAction("Record into a folder…", self._record_into_clicked)
        record_menu.addAction("Change the recordings folder…", self._choose_recordings_dir)
        self.record_button.setMenu(record_menu)
        self._update_record_tooltip()
        self._record_timer = QTimer(self)
        self._record_timer.setInterval(250)
        self._record_timer.timeout.connect(self._update_record_button)
        ctx.recorder.started.connect(self._recording_started)
        ctx.recorder.stopped.connect(self._recording_stopped)
        tools = QHBoxLayout()
        tools.addWidget(QLabel("Show:"))
        for c in self.view_checks.values():
            tools.addWidget(c)
        tools.addStretch(1)
        for b in (self.ruler_button, self.clear_button, self.fit_button, self.pause_button,
                  self.snapshot_button, self.export_button, self.record_button):
            tools.addWidget(b)
        for b in (self.export_button, self.record_button):  # as tall as the push buttons
            b.setSizePolicy(b.sizePolicy().horizontalPolicy(),
                            self.pause_button.sizePolicy().verticalPolicy())
        self.playback = PlaybackBar(ctx)
        self.playback.used.connect(lambda: self.set_paused(False))

        self.readout = QLabel("Double-click a view to measure the distance there.")
        self.readout.setTextFormat(Qt.TextFormat.PlainText)
        self.readout.setStyleSheet("font-family: monospace; padding: 2px 4px;")
        self.calib_note = QLabel()
        self.calib_note.setStyleSheet("background: #ffd54f; color: #3e2700; padding: 2px 6px;")
        self.calib_note.hide()
        self.scale_label = QLabel()
        self.scale_label.setStyleSheet("background: #b3e5fc; color: #01304a; padding: 2px 6px;")
        self.scale_label.hide()

        views_page = QWidget()
        vcol = QVBoxLayout(views_page)
        vcol.setContentsMargins(4, 4, 4, 4)
        vcol.addLayout(tools)
        vcol.addWidget(self.playback)
        vcol.addWidget(self.calib_note)
        vcol.addWidget(self.scale_label)
        vcol.addWidget(self._grid_host, 1)
        vcol.addWidget(self.readout)

        self.no_calib = _NoCalibrationPage()
        self.no_calib.calibrate.clicked.connect(self.calibrateRequested)
        self.no_calib.load.clicked.connect(self.loadCalibrationRequested)
        self.no_calib.use_true.clicked.connect(self.use_true_calibration)
        self.stack = QStackedWidget()
        self.stack.addWidget(self.no_calib)
        self.stack.addWidget(views_page)

        splitter = QSplitter()
        splitter.addWidget(self.stack)
        splitter.addWidget(scroll)
        splitter.setStretchFactor(0, 1)
        splitter.setSizes([1000, scroll.minimumWidth()])
        splitter.setCollapsible(0, False)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(splitter)

        self._layout_views()
        ctx.calibrationChanged.connect(self._calibration_changed)
        ctx.frames.frameReady.connect(self._frame_ready)
        ctx.frames.sourceChanged.connect(lambda _name: self._update_no_calib_page())
        ctx.jobs.finished.connect(self._job_finished)
        ctx.jobs.failed.connect(self._job_failed)
        self._calibration_changed(ctx.calibration)

    # ---- set-up ------------------------------------------------------------------------------
    def _initial_params(self) -> MatcherParams:
        name = self.ctx.settings.preset or "live"
        for candidate in (name, "live", "seed"):
            try:
                return load_preset(candidate).replace(name=candidate)
            except StereoGuiError as exc:
                log.warning("preset %s: %s", candidate, exc)
        return MatcherParams(name="seed")

    def _layout_views(self, *_args) -> None:
        for panel in self.panels.values():
            self._grid.removeWidget(panel)
            panel.hide()
        keys = [k for k in VIEWS if self.view_checks[k].isChecked()]
        cols = 1 if len(keys) == 1 else 2
        for i, key in enumerate(keys):
            self._grid.addWidget(self.panels[key], i // cols, i % cols)
            self.panels[key].show()
        self.ctx.update_settings(visible_views=tuple(keys)) if self.ctx.settings else None

    def visible_views(self) -> list[str]:
        return [k for k in VIEWS if self.view_checks[k].isChecked()]

    def set_visible_views(self, keys) -> None:
        for k, c in self.view_checks.items():
            c.blockSignals(True)
            c.setChecked(k in keys)
            c.blockSignals(False)
        self._layout_views()

    # ---- activation, calibration, parameters -------------------------------------------------
    def set_active(self, active: bool) -> None:
        """Called by the main window: the shown tab owns the frame worker's processor."""
        self._active = active
        if active:
            self._install_processor()
            self._frame_ready()
        elif self.pause_button.isChecked():
            self.pause_button.setChecked(False)  # other tabs need frames

    def _install_processor(self) -> None:
        if self._active:
            self.ctx.frames.set_processor(self._processor)

    def _calibration_changed(self, calib) -> None:
        self._processor = (LiveProcessor(calib, self.params_panel.params())
                           if calib is not None else None)
        self._output = None
        self.clear_markers()
        self._install_processor()
        note = self.ctx.calibration_note
        self.calib_note.setVisible(calib is not None and note == TRUE_CALIBRATION_NOTE)
        self.calib_note.setText("Using the simulated rig's TRUE calibration (the one it was "
                                "built with), not one you calibrated.")
        self.stack.setCurrentIndex(0 if calib is None else 1)
        self._update_no_calib_page()

    def _update_no_calib_page(self) -> None:
        self.no_calib.use_true.setVisible(self._sim_rig() is not None)

    def _sim_rig(self):
        rig = getattr(self.ctx.frames.source(), "rig", None)
        return rig if hasattr(rig, "true_calibration") else None

    def use_true_calibration(self) -> bool:
        """On the simulated rig: use the calibration it was built with (clearly labelled)."""
        rig = self._sim_rig()
        if rig is None:
            self.ctx.report_error("The true calibration exists only for the simulated rig.")
            return False
        self.ctx.set_calibration(rig.true_calibration(), None, note=TRUE_CALIBRATION_NOTE)
        return True

    def _params_changed(self, params: MatcherParams) -> None:
        if self._processor is not None:
            self._processor.set_params(params)
        if not params.name.endswith("(edited)"):
            self.ctx.update_settings(preset=params.name)

    # ---- drawing -----------------------------------------------------------------------------
    def _frame_ready(self) -> None:
        if not self._active:
            return
        # latest() re-arms frameReady: call it even when paused, or the view never updates again
        pf = self.ctx.frames.latest()
        if self.pause_button.isChecked():
            return
        if pf is None or not isinstance(pf.output, LiveOutput):
            return
        self.shown_frame = pf.frame
        self.show_output(pf.output)

    def show_output(self, out: LiveOutput) -> None:
        """Draw one processed frame (UI thread: array hand-over only)."""
        self._output = out
        for key in self.visible_views():
            self.panels[key].set_image(out.images[key])
        if "wls" in self.visible_views():
            self._update_color_bar(out)
        wls = out.result.wls_px is not None
        self.panels["wls"].set_title(VIEWS["wls"] if wls else
                                     "Closed disparity (no WLS), colour = distance, "
                                     "dark red = no match")
        if self._hover is not None:
            self._show_readout(*self._hover)
        if out.scale_note != self._scale_note:
            self._scale_note = out.scale_note
            self.scale_label.setText(out.scale_note)
            self.scale_label.setVisible(bool(out.scale_note))
            if out.scale_note:
                self.ctx.show_status(out.scale_note)
        self.frames_shown += 1
        self.frameShown.emit()

    def _update_color_bar(self, out: LiveOutput) -> None:
        calib = out.result.calibration
        if calib is None or self.panels["wls"].color_bar is None:
            return
        scale = out.result.color_scale
        if scale is None:
            return
        state = (out.result.params.colormap, scale.kind, round(scale.far, 1), round(scale.near, 1))
        if state == self._bar_state:
            return  # the ticks change only when the range does
        self._bar_state = state
        self.panels["wls"].color_bar.set_scale(COLORMAPS[out.result.params.colormap], scale)

    # ---- hover readout -----------------------------------------------------------------------
    def _disparity_of_view(self, key: str) -> np.ndarray | None:
        if self._output is None:
            return None
        r = self._output.result
        return {"raw": r.disparity_px, "closed": r.closed_px}.get(key, r.final_px)

    def _hovered(self, key: str, x: float, y: float) -> None:
        self._hover = None if math.isnan(x) else (key, x, y)
        if self._hover is None:
            self.readout.setText("Double-click a view to measure the distance there.")
        else:
            self._show_readout(key, x, y)

    def _show_readout(self, key: str, x: float, y: float) -> None:
        self.readout.setText(self.readout_text(key, x, y))

    def readout_text(self, key: str, x: float, y: float) -> str:
        """What the readout line says for the pointer at (x, y) px of view `key`."""
        disp = self._disparity_of_view(key)
        if disp is None:
            return "no frame yet"
        h, w = disp.shape[:2]
        xi, yi = int(round(x)), int(round(y))
        if not (0 <= xi < w and 0 <= yi < h):
            return f"x {xi}  y {yi}: outside the image"
        if key == "right":
            return f"x {xi}  y {yi} (right image: measure on the left or a disparity view)"
        d = float(disp[yi, xi])
        where = f"x {xi:4d}  y {yi:4d}   "
        if not math.isfinite(d):
            return where + "invalid: no match here (occluded, textureless or filtered out)"
        from stereo_gui.core.measure import triangulate

        lo, hi = self._output.result.disparity_range_px
        txt = where + f"disparity {d:7.2f} px   "
        if d >= hi - 1.0:
            return txt + "invalid: too near for the disparity range"
        xyz = triangulate(self._output.result.calibration, x, y, d)
        if xyz is None:
            return txt + "invalid: too far"
        z, how = xyz[2], ""
        fit = self.ctx.active_fit
        if fit is not None:
            lo_s, hi_s = fit.disparity_span
            if not lo_s <= d <= hi_s:
                return txt + f"invalid: outside the {fit.model} fit's disparity range"
            z, how = float(fit.predict(d)), f" ({fit.model} fit)"
        return txt + f"distance (Z) {format_distance(z)}{how}   valid"

    # ---- measuring ---------------------------------------------------------------------------
    def _double_clicked(self, key: str, x: float, y: float) -> None:
        if key not in MEASURABLE:
            self.ctx.show_status("Measure on the left image or a disparity view: the right "
                                 "image has other pixel coordinates.")
            return
        self.measure_at(x, y, key)

    def measure_at(self, x: float, y: float, key: str = "wls") -> int | None:
        """Measure at rectified-left pixel (x, y) on the frame now shown; returns the job id."""
        out = self._output
        if out is None:
            self.ctx.report_error("No frame to measure on yet.")
            return None
        from stereo_gui.core.measure import measure_point

        patch = int(self.ctx.settings.patch_size)
        fit = self.ctx.active_fit
        result = out.result
        job = self.ctx.jobs.submit(lambda: measure_point(result, x, y, patch=patch, fit=fit))
        self._pending[job] = (key, self.ruler_button.isChecked())
        return job

    def _job_finished(self, job_id: int, m) -> None:
        if self._snapshot_done(job_id, m) or self._export_done(job_id, m):
            return
        if job_id not in self._pending:
            return  # another tab's job
        _key, ruler = self._pending.pop(job_id)
        color = marker_color(m.valid)
        label = format_distance(m.Z_mm) if m.valid else f"✕ {m.reason or 'invalid'}"
        line_to, line_text = None, ""
        if ruler:
            if self._ruler_a is None or not self._ruler_a.valid:
                self._ruler_a = m
                label = "A: " + label
            else:
                a = self._ruler_a
                self._ruler_a = None
                if m.valid:
                    dist = math.dist((a.X_mm, a.Y_mm, a.Z_mm), (m.X_mm, m.Y_mm, m.Z_mm))
                    label = f"B: {label}"
                    line_text = f"A–B {format_distance(dist)}"
                    line_to = (a.x, a.y)
                    color = "#40c4ff"
                    self.last_ruler_mm = dist
        for key in MEASURABLE:
            self.panels[key].add_marker(m.x, m.y, label, color, line_to, line_text)
        self.ctx.add_measurement(self._record(m))
        self.ctx.show_status(self._status_text(m))
        self.measured.emit(m)

    def _job_failed(self, job_id: int, message: str) -> None:
        if self._pending.pop(job_id, None) is not None:
            self.ctx.report_error(f"Measurement failed: {message}")
        elif job_id in self._exports:
            what = self._exports.pop(job_id)
            self.ctx.report_error(f"Export of the {what} failed: {message}")
        elif job_id in getattr(self, "_snapshots", set()):
            self._snapshots.discard(job_id)
            self.ctx.report_error(f"Snapshot not saved: {message}")

    def _status_text(self, m) -> str:
        if not m.valid:
            return f"({m.x:.0f}, {m.y:.0f}): no distance: {m.reason}"
        return (f"({m.x:.0f}, {m.y:.0f}): Z {format_distance(m.Z_mm)}, range "
                f"{format_distance(m.range_mm)} ± {format_distance(m.expected_error_mm)}, "
                f"disparity {m.disparity_px:.2f} px, {m.valid_fraction:.0%} valid ({m.method})")

    def _record(self, m):
        from stereo_gui.files.spreadsheet import MeasurementRecord

        calib = self.ctx.calibration
        path = self.ctx.calibration_path
        return MeasurementRecord(
            time=_dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            x_px=float(m.x), y_px=float(m.y), disparity_px=float(m.disparity_px),
            X_mm=float(m.X_mm), Y_mm=float(m.Y_mm), Z_mm=float(m.Z_mm),
            range_mm=float(m.range_mm), valid=bool(m.valid), reason=m.reason or "",
            valid_fraction=float(m.valid_fraction), expected_error_mm=float(m.expected_error_mm),
            method=m.method,
            calibration_file=str(path) if path else self.ctx.calibration_note,
            calibration_rms_px=float(getattr(calib, "rms_stereo", float("nan"))),
        )

    def _ruler_toggled(self, on: bool) -> None:
        self._ruler_a = None
        if on:
            self.ctx.show_status("Ruler: double-click the first point, then the second.")

    def clear_markers(self) -> None:
        self._ruler_a = None
        for p in self.panels.values():
            p.clear_markers()

    def fit_views(self) -> None:
        for p in self.panels.values():
            p.fit()

    # ---- pause and snapshot ------------------------------------------------------------------
    def set_paused(self, paused: bool) -> None:
        if self.pause_button.isChecked() != paused:
            self.pause_button.setChecked(paused)  # re-enters through toggled
            return
        self.pause_button.setText("Resume" if paused else "Pause")
        if paused:
            self.ctx.frames.pause()
        else:
            self.ctx.frames.resume()

    def _snapshot_clicked(self) -> None:
        start = self.ctx.settings.last_export_dir or str(Path.home())
        folder = QFileDialog.getExistingDirectory(self, "Save snapshot into", start)
        if folder:
            self.snapshot(folder)
            self.ctx.update_settings(last_export_dir=folder)

    def snapshot(self, folder: str | Path) -> int | None:
        """Save the views shown as PNG files in `folder` (atomically, off the UI thread).

        Files are named snapshot-<time>-<view>.png. Returns the job id.
        """
        out = self._output
        if out is None:
            self.ctx.report_error("No frame to save yet.")
            return None
        folder = Path(folder)
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
        images = {k: out.images[k] for k in self.visible_views()}

        def write() -> list[Path]:
            from stereo_gui.files.atomic import write_bytes_atomic

            written = []
            for key, img in images.items():
                bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
                ok, buf = cv2.imencode(".png", bgr)
                if not ok:
                    raise StereoGuiError(f"could not encode the {key} view as PNG")
                written.append(write_bytes_atomic(folder / f"snapshot-{stamp}-{key}.png",
                                                  buf.tobytes()))
            return written

        job = self.ctx.jobs.submit(write)
        self._snapshots = getattr(self, "_snapshots", set()) | {job}
        return job

    def _snapshot_done(self, job_id: int, paths) -> bool:
        if job_id in getattr(self, "_snapshots", set()):
            self._snapshots.discard(job_id)
            self.ctx.show_status(f"Snapshot saved: {len(paths)} files in {Path(paths[0]).parent}"
                                 if paths else "Snapshot: no views shown")
            return True
        return False

    # ---- depth exports of the frame shown ----------------------------------------------------
    def _export_start_dir(self) -> str:
        return self.ctx.settings.last_export_dir or str(Path.home())

    def _export_clicked(self, kind: str) -> None:
        if self._output is None:
            self.ctx.report_error("No frame to export yet.")
            return
        text, suffix, _what = EXPORTS[kind]
        start = str(Path(self._export_start_dir()) / f"frame-{_stamp()}{suffix}")
        ext = Path(suffix).suffix
        path, _ = QFileDialog.getSaveFileName(self, text.rstrip("…"), start,
                                              f"{ext[1:].upper()} files (*{ext})")
        if path:
            if not path.lower().endswith(ext):
                path += ext
            self.export_frame(path, kinds=(kind,))
            self.ctx.update_settings(last_export_dir=str(Path(path).parent))

    def _export_all_clicked(self) -> None:
        if self._output is None:
            self.ctx.report_error("No frame to export yet.")
            return
        folder = QFileDialog.getExistingDirectory(self, "Export the frame's depth into",
                                                  self._export_start_dir())
        if folder:
            self.export_frame(folder)
            self.ctx.update_settings(last_export_dir=folder)

    def export_frame(self, target: str | Path, kinds=tuple(EXPORTS)) -> int | None:
        """Write the shown frame's depth off the UI thread; returns the job id.

        With one kind, `target` is the file; with several, a folder that receives
        frame-<time><suffix> for each (see EXPORTS). Every file is written atomically.
        """
        out = self._output
        if out is None:
            self.ctx.report_error("No frame to export yet.")
            return None
        kinds = tuple(kinds)
        target = Path(target)
        if len(kinds) == 1:
            paths = {kinds[0]: target}
        else:
            stamp = _stamp()
            paths = {k: target / f"frame-{stamp}{EXPORTS[k][1]}" for k in kinds}
        result = out.result
        disparity = result.final_px
        calib = result.calibration  # the one the frame was rectified with (scaled if it was)

        def write() -> list[tuple[str, Path, str]]:
            from stereo_gui.files import depth_export as dx

            done = []
            for kind, path in paths.items():
                if kind == "disparity_png":
                    dx.write_disparity_png16(path, disparity)
                    note = ""
                elif kind == "disparity_npy":
                    dx.write_disparity_npy(path, disparity)
                    note = ""
                elif kind == "depth_png":
                    dx.write_depth_png16(path, disparity, calib)
                    note = ""
                else:
                    n = dx.write_ply(path, disparity, result.rectified_left, calib)
                    note = f"{n} points"
                done.append((kind, Path(path), note))
            return done

        job = self.ctx.jobs.submit(write)
        self._exports[job] = ("frame's depth" if len(kinds) > 1 else EXPORTS[kinds[0]][2])
        return job

    def _export_done(self, job_id: int, done) -> bool:
        if job_id not in self._exports:
            return False
        del self._exports[job_id]
        self.last_export = [p for _k, p, _n in done]
        if len(done) == 1:
            kind, path, note = done[0]
            extra = f", {note}" if note else ""
            self.ctx.show_status(f"Exported the {EXPORTS[kind][2]} to {path}{extra}")
        else:
            self.ctx.show_status(f"Exported the frame's depth: {len(done)} files in "
                                 f"{done[0][1].parent} (disparity PNG and .npy, depth PNG, PLY)")
        return True

    # ---- recording -----------------------------------------------------------------------------
    def _update_record_tooltip(self) -> None:
        base = recordings_dir(self.ctx.settings)
        self.record_button.setToolTip(
            f"Record the raw stereo frames with their timestamps into a new folder in {base}; "
            "the arrow offers another folder")

    def _record_clicked(self, checked: bool) -> None:
        if checked:
            self.start_recording()
        else:
            self.ctx.recorder.stop_recording()
        self._sync_record_button()

    def _record_into_clicked(self) -> None:
        if self.ctx.recorder.is_recording:
            return
        folder = QFileDialog.getExistingDirectory(
            self, "Record into (an empty or new folder)", str(recordings_dir(self.ctx.settings)))
        if folder:
            self.start_recording(folder)

    def _choose_recordings_dir(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Folder for new recordings",
                                                  str(recordings_dir(self.ctx.settings)))
        if folder:
            self.ctx.update_settings(recordings_dir=folder)
            self._update_record_tooltip()

    def start_recording(self, folder: str | Path | None = None) -> Path | None:
        """Record the source's raw frames into `folder` (new or empty), or into a new folder in
        the recordings folder; returns the folder, or None (with a message) if it cannot."""
        src = self.ctx.frames.source()
        if src is None:
            self.ctx.report_error("Nothing to record: no source is open.")
            self._sync_record_button()
            return None
        if folder is None:
            folder = new_recording_folder(recordings_dir(self.ctx.settings))
        try:
            path = self.ctx.recorder.start(folder, source_name=getattr(src, "name", ""),
                                           fps=float(getattr(src, "nominal_fps", 30.0) or 30.0))
        except StereoGuiError as exc:
            self.ctx.report_error(f"Cannot start recording: {exc}")
            self._sync_record_button()
            return None
        return path

    def stop_recording(self) -> int | None:
        return self.ctx.recorder.stop_recording()

    def _sync_record_button(self) -> None:
        rec = self.ctx.recorder
        self.record_button.blockSignals(True)
        self.record_button.setChecked(rec.is_recording)
        self.record_button.blockSignals(False)
        self._update_record_button()

    def _update_record_button(self) -> None:
        rec = self.ctx.recorder
        if rec.is_recording:
            self.record_button.setText(f"■ Stop {format_elapsed(rec.elapsed_s)}")
            self.record_button.setToolTip(f"Recording into {rec.folder}: {rec.frames_written} "
                                          "frames written; click to stop")
        else:
            self.record_button.setText(RECORD_TEXT)

    def _recording_started(self, folder: str) -> None:
        self._record_timer.start()
        self._sync_record_button()
        self.ctx.show_status(f"Recording into {folder}")

    def _recording_stopped(self, result) -> None:
        self._record_timer.stop()
        self._sync_record_button()
        self._update_record_tooltip()
        text = describe_result(result)
        if result.error:
            self.ctx.report_error(text)
        else:
            self.ctx.show_status(text)

    def shutdown(self) -> None:
        """Called by the main window on close."""
        if self._processor is not None and self.ctx.frames.processor() is self._processor:
            self.ctx.frames.set_processor(None)
