"""The Live tab: rectified pair, disparity views, the WLS colour view, parameters, click-to-measure.

Work is split by thread:
- the frame worker runs `stereo_gui.pipeline.live.LiveProcessor` on every frame: the pipeline
  (rectify, SGBM, closing, WLS, colour map) and the conversion of each view into a displayable
  uint8 image;
- a double-click becomes a `measure_point` job on the context's job thread, run on the result
  that was on screen when the user clicked;
- the UI thread only hands arrays to pyqtgraph, reads one pixel for the hover readout
  (`stereo_gui.pipeline.readout`), and draws markers.

Snapshot and depth exports are `live_exports.LiveExports`; recording is the
`RecordButton` widget.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSplitter,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.matching import COLORMAPS, MatcherParams
from stereo_gui.pipeline.live import LiveOutput, LiveProcessor
from stereo_gui.qt.widgets.calibration_health import CalibrationHealthPanel
from stereo_gui.pipeline.readout import format_distance, pointer_readout
from stereo_gui.qt.tabs.live_exports import EXPORTS, LiveExports
from stereo_gui.qt.widgets.image_view import ImagePanel, marker_color
from stereo_gui.qt.widgets.no_calibration_page import NoCalibrationPage
from stereo_gui.qt.widgets.params_panel import ParamsPanel, load_preset
from stereo_gui.qt.widgets.playback_bar import PlaybackBar
from stereo_gui.qt.widgets.record_button import RecordButton
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

# view key -> title; all views are in rectified-left pixel coordinates except "right"
VIEWS: dict[str, str] = {
    "left": "Rectified left",
    "right": "Rectified right",
    "raw": "Raw disparity (SGBM), bright = near, dark red = no match, grey = not seen by the "
           "right camera",
    "closed": "After the closing filter, dark red = no match, grey = not seen",
    "wls": "WLS filtered (confident pixels), colour = distance, dark red = no match, "
           "grey = not seen",
}
SHORT_NAMES = {"left": "Left", "right": "Right", "raw": "Raw", "closed": "Closed", "wls": "WLS"}
DEFAULT_VIEWS = ("left", "raw", "closed", "wls")
MEASURABLE = ("left", "raw", "closed", "wls")  # views sharing the left image's pixel frame
TRUE_CALIBRATION_NOTE = "simulated rig's TRUE calibration"
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
        self.shown_frame: StereoFrame | None = None  # the raw frame of the result shown
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
        self.exports = LiveExports(ctx, self, lambda: self._output, self.visible_views)
        self.snapshot_button.clicked.connect(self.exports.snapshot_clicked)
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
        self.export_button = self.exports.make_export_button()
        self.record_button = RecordButton(ctx)
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
        self.health = CalibrationHealthPanel(ctx)  # issue 10: drift figure and refinement
        vcol.addWidget(self.health)

        self.no_calib = NoCalibrationPage()
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
                                     "dark red = no match, grey = not seen")
        if self._hover is not None:
            self._show_readout(*self._hover)
        if out.scale_note != self._scale_note:
            self._scale_note = out.scale_note
            self.scale_label.setText(out.scale_note)
            self.scale_label.setVisible(bool(out.scale_note))
            if out.scale_note:
                self.ctx.show_status(out.scale_note)
        self.health.show_output(out, self.shown_frame)
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
        result = self._output.result if self._output is not None else None
        return pointer_readout(result, key, x, y, self.ctx.active_fit)

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

    def snapshot(self, folder: str | Path) -> int | None:
        """Save the views shown as PNG files in `folder` (see LiveExports.snapshot)."""
        return self.exports.snapshot(folder)

    # ---- depth exports of the frame shown ----------------------------------------------------
    def export_frame(self, target: str | Path, kinds=tuple(EXPORTS)) -> int | None:
        """Write the shown frame's depth off the UI thread (see LiveExports.export_frame)."""
        return self.exports.export_frame(target, kinds)

    @property
    def last_export(self) -> list[Path]:
        """Files written by the last finished export."""
        return self.exports.last_export

    # ---- recording -----------------------------------------------------------------------------
    def start_recording(self, folder: str | Path | None = None) -> Path | None:
        """Record the source's raw frames (see RecordButton.start_recording)."""
        return self.record_button.start_recording(folder)

    def stop_recording(self) -> int | None:
        return self.record_button.stop_recording()

    def shutdown(self) -> None:
        """Called by the main window on close."""
        self.health.shutdown()
        if self._processor is not None and self.ctx.frames.processor() is self._processor:
            self.ctx.frames.set_processor(None)
