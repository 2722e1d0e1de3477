"""The Live tab: rectified pair, disparity views, the WLS colour view, parameters, click-to-measure.

Work is split by thread:
- the frame worker runs `stereo_gui.pipeline.live.LiveProcessor` on every frame: the pipeline
  (rectify, SGBM, closing, WLS, colour map) and the conversion of each view into a displayable
  uint8 image;
- the pointer's readout and double-click measurements (`live_readings.LiveReadings`) are
  `measure_point` jobs on the context's job thread;
- the 3D point cloud (`live_cloud.LiveCloud`) is made on a thread of its own;
- the watched region's figures (`live_region.LiveRegion`) come with each frame's output;
- the UI thread only hands arrays to pyqtgraph, writes the readout line and draws markers.

Snapshot and depth exports are `live_exports.LiveExports`; recording is the
`RecordButton` widget.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Collection, Iterable
from pathlib import Path

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QLabel,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSplitter,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.colouring import color_scale_caption
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.measure import Measurement
from stereo_gui.core.preset import COLORMAPS, Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.timing import ShownMeter, ShownStats
from stereo_gui.pipeline.cloud import CloudPoints
from stereo_gui.pipeline.live import NO_MATCH_RGB, NOT_SEEN_RGB, LiveOutput, LiveProcessor
from stereo_gui.pipeline.readout import PointerReading
from stereo_gui.qt.context import TRUE_CALIBRATION_NOTE, AppContext
from stereo_gui.qt.source_capabilities import simulated_rig
from stereo_gui.qt.tabs.live_cloud import LiveCloud
from stereo_gui.qt.tabs.live_exports import EXPORTS, LiveExports
from stereo_gui.qt.tabs.live_readings import HOVER_HINT, MEASURABLE, LiveReadings, ReadingScreen
from stereo_gui.qt.tabs.live_region import LiveRegion
from stereo_gui.qt.tabs.live_stream import LiveStream
from stereo_gui.qt.tabs.live_views import COLOR_VIEWS, VIEWS, ViewGrid
from stereo_gui.qt.widgets.calibration_health import CalibrationHealthPanel
from stereo_gui.qt.widgets.camera_controls import CameraControlsPanel
from stereo_gui.qt.widgets.cloud_view import CloudView
from stereo_gui.qt.widgets.flow_layout import FlowLayout
from stereo_gui.qt.widgets.no_calibration_page import NoCalibrationPage
from stereo_gui.qt.widgets.params_panel import MODIFIED, ParamsPanel, load_preset
from stereo_gui.qt.widgets.playback_bar import PlaybackBar
from stereo_gui.qt.widgets.record_button import RecordButton
from stereo_gui.sources.base import StereoFrame
from stereo_gui.sources.sim.rig import SimRig

log = logging.getLogger(__name__)

NO_WLS_TITLE = "No WLS filter in this preset: the depth view"
WLS_MEASURED_TITLE = "WLS filtered: this preset's depth (what a click reads)"


def _hex(rgb: Iterable[int]) -> str:
    return "#" + "".join(f"{int(v):02x}" for v in rgb)


# what the colours of pixels without depth mean, once under the views (not in every title); the
# grey views (Raw, Closed) and the colour maps use neither colour for depth
LEGEND = (f"<span style='color:{_hex(NO_MATCH_RGB)}'>■</span> dark red: no match &nbsp; "
          f"<span style='color:{_hex(NOT_SEEN_RGB)}'>■</span> magenta: not seen by the right "
          "camera")
REGION_VIEW = "depth"  # the view that carries the region box


def legend_text(caption: str = "") -> str:
    """The line under the views: the colours of pixels without depth, and what the depth
    colours are (`caption`: core.colouring.color_scale_caption of the frame shown)."""
    return f"{LEGEND} &nbsp;·&nbsp; {caption}" if caption else LEGEND


def wls_title(result: PipelineResult) -> str:
    """The WLS view's title for a frame: a picture, or the preset's depth itself."""
    if result.wls_px is None:
        return NO_WLS_TITLE
    if result.wls_px is result.final_px or not result.params.check_block_size:
        return WLS_MEASURED_TITLE
    return VIEWS["wls"]


MCAP_TEXT = "Record the depth as MCAP…"
MCAP_STOP_TEXT = "Stop the MCAP recording"


class LiveTab(QWidget):
    """The Live tab. `ctx` is the AppContext."""

    calibrateRequested = Signal()
    loadCalibrationRequested = Signal()
    measured = Signal(Measurement)  # after its marker was drawn
    frameShown = Signal(LiveOutput)  # the frame whose views were all just drawn
    hoverRead = Signal(PointerReading)  # after the readout line shows it
    cloudShown = Signal(CloudPoints)  # after the 3D view drew them

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._active = False
        self._processor: LiveProcessor | None = None
        self._output: LiveOutput | None = None
        self._scale_note = ""
        self.shown_frame: StereoFrame | None = None  # the raw frame of the result shown
        self.frames_shown = 0
        # frames drawn over the last seconds, and how late (see shown_stats)
        self._shown = ShownMeter()
        self._read_at = math.nan  # when the reader got the frame of the output being drawn
        self.last_latency_ms = math.nan  # of the frame drawn last (NaN: unknown)
        self._to_draw: list[str] = []  # views still to get the image of the frame shown
        self._draw_scheduled = False
        scroll = self._build_params()
        self._build_views()
        self._build_toolbar()
        views_page = self._build_views_page()
        self._build_layout(views_page, scroll)
        self._connect()
        self._calibration_changed(ctx.calibration)

    # ---- set-up ------------------------------------------------------------------------------
    def _build_params(self) -> QScrollArea:
        """The matcher parameters' panel, in the scroll area beside the views."""
        self.params_panel = ParamsPanel(self._initial_params())
        self.params_panel.paramsChanged.connect(self._params_changed)
        scroll = QScrollArea()
        scroll.setWidget(self.params_panel)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        scroll.setMinimumWidth(self.params_panel.sizeHint().width()
                               + scroll.verticalScrollBar().sizeHint().width() + 4)
        return scroll

    def _build_views(self) -> None:
        """The view grid, the pointer's readout and the readings (hover, double-click, ruler)."""
        ctx = self.ctx
        self.views = ViewGrid(ctx.settings.visible_views)
        self.panels, self.view_checks = self.views.panels, self.views.checks
        self.readout = QLabel(HOVER_HINT)
        self.readout.setTextFormat(Qt.TextFormat.PlainText)
        self.readout.setStyleSheet("font-family: monospace; padding: 2px 4px;")
        # a long reading must not make the window wider than a laptop screen
        self.readout.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.ruler_button = QPushButton("Ruler")
        self.ruler_button.setCheckable(True)
        self.ruler_button.setToolTip("Double-click two points to measure the 3D distance between them")
        # hover readout, double-clicks and the ruler
        self.readings = LiveReadings(ctx, ReadingScreen(
            output=lambda: self._output, frame=lambda: self.shown_frame, readout=self.readout,
            markers={k: self.panels[k] for k in MEASURABLE}, ruler_on=self.ruler_button.isChecked),
            self)
        self.readings.measured.connect(self.measured)
        self.readings.hoverRead.connect(self.hoverRead)
        for panel in self.panels.values():
            panel.hovered.connect(self.readings.hovered)
            panel.doubleClicked.connect(self.readings.double_clicked)

    def _build_toolbar(self) -> None:
        """The buttons above the views and the parts they drive (exports, region, stream, 3D
        view, recording), then the playback bar."""
        ctx = self.ctx
        self.pause_button = QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.pause_button.toggled.connect(self.set_paused)
        self.snapshot_button = QPushButton("Snapshot…")
        self.snapshot_button.setToolTip("Save the views shown as PNG files")
        self.exports = LiveExports(ctx, self, lambda: self._output, self.visible_views)
        self.snapshot_button.clicked.connect(self.exports.snapshot_clicked)
        self.ruler_button.toggled.connect(self.readings.ruler_toggled)
        self.clear_button = QPushButton("Clear")
        self.clear_button.setToolTip("Remove all distance markers (they are not kept when the "
                                     "window closes; the readings are, in the Measurements tab)")
        self.clear_button.clicked.connect(self.clear_markers)
        self.fit_button = QPushButton("Fit")
        self.fit_button.setToolTip("Show the whole image in every view again (after zooming with "
                                   "the mouse wheel or panning)")
        self.fit_button.clicked.connect(self.fit_views)
        self.export_button = self.exports.make_export_button()
        self.record_button = RecordButton(ctx)
        self.region = LiveRegion(ctx, self, self.panels[REGION_VIEW],
                                 self.view_checks[REGION_VIEW], lambda: self._processor,
                                 lambda: self._output)
        self.region_button, self.alarm_spin = self.region.button, self.region.alarm_spin
        self.stream = LiveStream(ctx, self, lambda: self._processor)
        self.stream_button = self.stream.button
        # beside the raw recording: the depth stream's topics as MCAP (File > Record MCAP… too)
        self.record_button.menu().addSeparator()
        self.mcap_action = self.record_button.menu().addAction(
            MCAP_TEXT, lambda: self.stream.toggle_recording(self))
        self.stream.recordingChanged.connect(lambda path: self.mcap_action.setText(
            MCAP_STOP_TEXT if path is not None else MCAP_TEXT))
        self.readings.logged.connect(self.stream.publish_record)
        self.cloud_button = QPushButton("3D view")
        self.cloud_button.setToolTip("The point cloud of the frame shown, in a window of its own "
                                     "(drag to rotate, wheel to zoom), updated a few times a "
                                     "second")
        self.cloud_button.clicked.connect(self.show_cloud)
        self.cloud = LiveCloud(ctx, self, lambda: self._output)
        self.cloud.shown.connect(self.cloudShown)
        self.params_button = QPushButton("Parameters")
        self.params_button.setCheckable(True)
        self.params_button.setChecked(True)
        self.params_button.setToolTip("Show or hide the matcher parameters beside the views")
        # the toolbar wraps onto a second row on a narrow window instead of being cut off
        self.toolbar = QWidget()
        tools = FlowLayout(self.toolbar)
        tools.addWidget(QLabel("Show:"))
        for c in self.view_checks.values():
            tools.addWidget(c)
        tools.add_stretch()
        for b in (self.ruler_button, self.region_button, self.alarm_spin, self.clear_button,
                  self.fit_button, self.pause_button, self.snapshot_button, self.export_button,
                  self.record_button, self.stream_button, self.cloud_button,
                  self.params_button):
            tools.addWidget(b)
        self.playback = PlaybackBar(ctx)
        self.playback.used.connect(lambda: self.set_paused(False))

    def _build_views_page(self) -> QWidget:
        """The page shown with a calibration: toolbar, notes, the views and the lines under them."""
        ctx = self.ctx
        self.legend = QLabel(LEGEND)
        self._caption = ""  # the depth colours' caption the legend shows
        self.legend.setStyleSheet("padding: 0px 4px;")
        self.region_label = self.region.label
        self.calib_note = QLabel()
        self.calib_note.setStyleSheet("background: #ffd54f; color: #3e2700; padding: 2px 6px;")
        self.calib_note.hide()
        self.scale_label = QLabel()
        self.scale_label.setStyleSheet("background: #b3e5fc; color: #01304a; padding: 2px 6px;")
        self.scale_label.hide()

        views_page = QWidget()
        vcol = QVBoxLayout(views_page)
        vcol.setContentsMargins(4, 4, 4, 4)
        vcol.addWidget(self.toolbar)
        vcol.addWidget(self.playback)
        self.camera_controls = CameraControlsPanel(ctx, "live")
        vcol.addWidget(self.camera_controls)
        vcol.addWidget(self.calib_note)
        vcol.addWidget(self.scale_label)
        vcol.addWidget(self.views, 1)
        vcol.addWidget(self.legend)
        vcol.addWidget(self.region_label)
        vcol.addWidget(self.stream.label)
        vcol.addWidget(self.readout)
        self.health = CalibrationHealthPanel(ctx)  # drift figure and refinement
        vcol.addWidget(self.health)
        return views_page

    def _build_layout(self, views_page: QWidget, scroll: QScrollArea) -> None:
        """The no-calibration page or the views, beside the parameters."""
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
        self.params_scroll = scroll
        self.params_button.toggled.connect(scroll.setVisible)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(splitter)

    def _connect(self) -> None:
        """The views laid out, the region and stream restored, and the context's signals."""
        ctx = self.ctx
        self.views.changed.connect(self._views_changed)
        self.views.lay_out()
        self.region.restore()
        self.stream.restore()
        ctx.calibration_model.changed.connect(self._calibration_changed)
        ctx.frames.frameReady.connect(self._frame_ready)
        ctx.frames.sourceChanged.connect(self._source_changed)

    def _initial_params(self) -> Preset:
        name = self.ctx.settings.preset or "live"
        failed = []
        for candidate in dict.fromkeys((name, "live", "seed")):
            try:
                params = load_preset(candidate).replace(name=candidate)
            except StereoGuiError as exc:
                failed.append(str(exc))
                continue
            break
        else:
            params = Preset(name="seed")
        if failed:  # said in the window: the preset chosen last is not what runs now
            self.ctx.report_error(f"The preset {name!r} chosen last could not be used "
                                  f"({'; '.join(failed)}); the {params.name!r} preset is used")
        return params

    def _views_changed(self, keys: list[str]) -> None:
        self.ctx.settings_model.update(visible_views=tuple(keys)) if self.ctx.settings else None
        if self._processor is not None:
            self._processor.set_views(self._processed_views())

    def visible_views(self) -> list[str]:
        return self.views.visible()

    def _processed_views(self) -> list[str]:
        """The views the processor makes images of: those shown (the snapshot saves those)."""
        return self.visible_views()

    def set_visible_views(self, keys: Collection[str]) -> None:
        self.views.set_visible(keys)

    # ---- activation, calibration, parameters -------------------------------------------------
    def set_active(self, active: bool) -> None:
        """Called by the main window: the shown tab owns the frame worker's processor."""
        self._active = active
        self._shown.reset()  # (frames drawn before it was hidden are no rate now)
        if active:
            self._install_processor()
            if self.pause_button.isChecked():  # paused before another tab was shown: still is
                self.ctx.frames.pause()
            self._frame_ready()
        elif self.pause_button.isChecked():
            # other tabs need frames; the Live view stays paused until the person resumes it
            self.ctx.frames.resume()

    def _install_processor(self) -> None:
        if self._active:
            p = self._processor
            self.ctx.frames.set_processor(p, lanes=p.lanes if p is not None else 1)

    def _retire(self, processor: LiveProcessor | None) -> None:
        """Off the frame worker (if still on it) and closed: its pipelines and health thread
        (a frame in work ends first; the UI thread does not wait for it)."""
        if processor is not None:
            if self.ctx.frames.processor() is processor:
                self.ctx.frames.set_processor(None)
            processor.close(wait=False)

    def _calibration_changed(self, calib: StereoCalibration | None) -> None:
        self.params_panel.set_calibration(calib)
        replaced = self._processor
        self._processor = (LiveProcessor(calib, self.params_panel.params())
                           if calib is not None else None)
        if self._processor is not None:
            self._processor.set_views(self._processed_views())
        self._output = None  # (of the calibration before: the region is not read on it)
        self.region.apply()
        self.stream.apply()
        self._to_draw = []  # (a view still to be drawn of the frame before must not be)
        self.clear_markers()
        self._install_processor()
        self._retire(replaced)
        note = self.ctx.calibration_note
        self.calib_note.setVisible(calib is not None and note == TRUE_CALIBRATION_NOTE)
        self.calib_note.setText("Using the simulated rig's TRUE calibration (the one it was "
                                "built with), not one you calibrated.")
        self.stack.setCurrentIndex(0 if calib is None else 1)
        self._update_no_calib_page()

    def _source_changed(self, _name: str = "") -> None:
        """A new source: the markers (and a ruler's first point) were of the old one's frames;
        during playback the playback bar's Play/Pause is the one pause button."""
        self.clear_markers()
        self._shown.reset()
        self._update_no_calib_page()
        if (self._sim_rig() is not None and self.ctx.settings.sim_true_calibration
                and self.ctx.calibration_note != TRUE_CALIBRATION_NOTE):
            self.use_true_calibration()  # the calibration chosen last, on the rig it belongs to
        playing_back = self.playback.source() is not None
        if playing_back and self.pause_button.isChecked():
            self.set_paused(False)
        self.pause_button.setVisible(not playing_back)

    def _update_no_calib_page(self) -> None:
        self.no_calib.use_true.setVisible(self._sim_rig() is not None)

    def _sim_rig(self) -> SimRig | None:
        return simulated_rig(self.ctx.frames.source())

    def use_true_calibration(self) -> bool:
        """On the simulated rig: use the calibration it was built with (clearly labelled)."""
        rig = self._sim_rig()
        if rig is None:
            self.ctx.report_error("The true calibration exists only for the simulated rig.")
            return False
        self.ctx.calibration_model.set(rig.true_calibration(), None, note=TRUE_CALIBRATION_NOTE)
        return True

    def _params_changed(self, params: Preset) -> None:
        if self._processor is not None:
            self._processor.set_params(params)
            self._install_processor()  # (how many frames it may take at once may change)
        if not params.name.endswith(MODIFIED):
            self.ctx.settings_model.update(preset=params.name)

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
        self.show_output(pf.output, pf.read_at)

    def show_output(self, out: LiveOutput, read_at: float = math.nan) -> None:
        """Draw one processed frame (UI thread: array hand-over only). The views get their
        images one event-loop turn apart, so that each is painted on its own and the window
        answers in between (four views painted in one go would hold it up for a visible
        moment on a busy machine); frameShown follows the last one. `read_at` is when the
        frame worker's reader got the frame (`time.monotonic()`; NaN: unknown), the start of
        its latency (shown_stats)."""
        self._output = out
        self._read_at = read_at
        # (a view ticked after this frame was made is left out: the next frame has it)
        self._to_draw = [k for k in self.visible_views() if k in out.images]
        self._update_color_bars(out)
        self.panels["wls"].set_title(wls_title(out.result))
        self.readings.frame_shown()
        self.region.show(out.region)
        if out.scale_note != self._scale_note:
            self._scale_note = out.scale_note
            self.scale_label.setText(out.scale_note)
            self.scale_label.setVisible(bool(out.scale_note))
            if out.scale_note:
                self.ctx.show_status(out.scale_note)
        if out.result.calibration is not self.params_panel.calibration:
            # the panel shows the range and scale of the calibration that runs: scaled to the
            # source's frames
            self.params_panel.set_calibration(out.result.calibration)
        self.health.show_output(out, self.shown_frame)
        if not self._draw_scheduled:  # (else the turn already scheduled goes on with this frame)
            self._draw_next()

    def _draw_next(self) -> None:
        """Hand the next view its image; the one after it comes once this one is painted."""
        self._draw_scheduled = False
        if self._output is None:  # the views were cleared meanwhile (a new calibration)
            self._to_draw = []
            return
        if not self._to_draw:  # no view shown
            self._frame_drawn()
            return
        key = self._to_draw.pop(0)
        self.panels[key].set_image(self._output.images[key])
        if self._to_draw:
            self._draw_scheduled = True
            QTimer.singleShot(0, self, self._draw_next)  # (dropped if the tab is deleted)
        else:
            self._frame_drawn()

    def _frame_drawn(self) -> None:
        """The last view shown got its image: the frame counts as shown, and its latency ends
        here (its paint follows in the same event-loop turn)."""
        now = time.monotonic()
        self._shown.add(now, self._read_at)
        self.last_latency_ms = ((now - self._read_at) * 1000.0 if math.isfinite(self._read_at)
                                else math.nan)
        self.frames_shown += 1
        self.frameShown.emit(self._output)

    def shown_stats(self, now: float | None = None) -> ShownStats:
        """The frames drawn over the last two seconds: their rate, and their latency from the
        moment the frame worker's reader got each frame from the source to the moment the last
        view shown was handed its image (ms; its paint follows in the same event-loop turn, so
        the paint of the other views is counted, that one's not). Nothing when the tab is hidden
        or drew nothing for a second. UI thread; cheap (the status bar asks twice a second)."""
        return self._shown.stats(now)

    def _update_color_bars(self, out: LiveOutput) -> None:
        scale = out.result.color_scale
        if scale is None or out.result.calibration is None:
            return
        caption = color_scale_caption(scale)
        if caption != self._caption:  # (the same text on most frames: no relayout)
            self._caption = caption
            self.legend.setText(legend_text(caption))
        shown = self.visible_views()
        for key in COLOR_VIEWS:
            bar = self.panels[key].color_bar
            if bar is not None and key in shown:
                bar.set_scale(COLORMAPS[out.result.preset.display.colormap], scale)

    # ---- the 3D point cloud -----------------------------------------------------------------
    def show_cloud(self) -> QWidget:
        """Open (or raise) the 3D view of the frame shown."""
        return self.cloud.show()

    @property
    def cloud_view(self) -> CloudView | None:
        return self.cloud.view

    # ---- the watched region (see LiveRegion) ------------------------------------------------
    def set_region(self, box: tuple[int, int, int, int] | None,
                   alarm_m: float | None = None) -> None:
        """Watch the box (x0, y0, x1, y1) px of the colour view (None: stop), with an alarm
        below `alarm_m` metres (None or 0: none)."""
        self.region.set_region(box, alarm_m)

    # ---- readings (see LiveReadings) ---------------------------------------------------------
    def measure_at(self, x: float, y: float, key: str = "depth") -> int | None:
        """Measure at rectified-left pixel (x, y) on the frame now shown; returns the job id."""
        return self.readings.measure_at(x, y, key)

    @property
    def last_reading(self) -> PointerReading | None:
        return self.readings.last_reading

    @property
    def last_ruler_mm(self) -> float | None:
        return self.readings.last_ruler_mm

    @property
    def hover_jobs_submitted(self) -> int:
        return self.readings.hover_jobs_submitted

    def clear_markers(self) -> None:
        self.readings.forget_ruler_point()
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
        self._shown.reset()
        if not self._active:
            return  # the frames belong to the tab shown; set_active applies the pause
        if paused:
            self.ctx.frames.pause()
        else:
            self.ctx.frames.resume()

    def toggle_pause(self) -> None:
        """Pause or resume what the tab shows: the playback when a recording plays, else the
        live view."""
        if self.playback.source() is not None:
            self.playback.toggle_play()
        else:
            self.set_paused(not self.pause_button.isChecked())

    def show_parameters(self, shown: bool) -> None:
        """Show or hide the matcher parameters beside the views (narrow screens hide them)."""
        self.params_button.setChecked(shown)

    def snapshot(self, folder: str | Path) -> int | None:
        """Save the views shown as PNG files in `folder` (see LiveExports.snapshot)."""
        return self.exports.snapshot(folder)

    # ---- depth exports of the frame shown ----------------------------------------------------
    def export_frame(self, target: str | Path, kinds: Iterable[str] = tuple(EXPORTS)
                     ) -> int | None:
        """Write the shown frame's depth off the UI thread (see LiveExports.export_frame)."""
        return self.exports.export_frame(target, kinds)

    @property
    def last_export(self) -> list[Path]:
        """Files written by the last finished export."""
        return self.exports.last_export

    def unfinished_work(self) -> list[str]:
        """Exports and snapshots closing now would cut short (see LiveExports)."""
        return self.exports.unfinished_work()

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        return self.exports.cancel_unfinished_work(timeout_ms)

    # ---- recording -----------------------------------------------------------------------------
    def start_recording(self, folder: str | Path | None = None) -> Path | None:
        """Record the source's raw frames (see RecordButton.start_recording)."""
        return self.record_button.start_recording(folder)

    def stop_recording(self) -> int | None:
        return self.record_button.stop_recording()

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Called by the main window on close: the tab's helpers are stopped (the cloud's jobs
        are joined by the context, where they are registered)."""
        self.cloud.shutdown()
        self.health.shutdown()
        self.stream.shutdown()
        self._retire(self._processor)
        return True
