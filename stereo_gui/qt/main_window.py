"""The main window: four tabs, the source chooser, the status bar, file menu, and clean shutdown.

The window owns no state of its own: it shows the AppContext's and forwards the user's choices
to it. It is the one place where errors reported anywhere (`ctx.errorOccurred`) become a message
the user sees (a red bar above the tabs, also written to the status bar).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum
from pathlib import Path

from PySide6.QtCore import QByteArray, QRect, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QCloseEvent, QGuiApplication, QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMenu,
    QMessageBox,
    QTabWidget,
    QToolButton,
    QWidget,
)

from stereo_gui.core.states import Transitions
from stereo_gui.core.timing import CPU_WINDOW_S, SHOWN_WINDOW_S, CpuMeter, ShownStats
from stereo_gui.files.recording import is_recording
from stereo_gui.files.session import MANIFEST
from stereo_gui.files.settings import Settings
from stereo_gui.qt.context import AppContext
from stereo_gui.qt.dialogs.about import show_about
from stereo_gui.qt.dialogs.closing import CloseWaiter, ask_unsaved_calibration, tell_cancelled
from stereo_gui.qt.dialogs.help import add_help_actions
from stereo_gui.qt.dialogs.source_dialog import SourceChoice, SourceDialog, describe_spec
from stereo_gui.qt.models.calibration import order_left_right
from stereo_gui.qt.source_capabilities import playback_of, simulated_rig
from stereo_gui.qt.tabs.calibration import CalibrationTab
from stereo_gui.qt.tabs.capture import CaptureTab
from stereo_gui.qt.tabs.live import LiveTab
from stereo_gui.qt.tabs.measurements import MeasurementsTab
from stereo_gui.qt.tabs.tab import WindowTab
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.widgets.error_bar import ErrorBar
from stereo_gui.qt.widgets.helpers import pane
from stereo_gui.qt.workers.frame_worker import StreamState, StreamStatus
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.recorder import RecordingResult, format_elapsed
from stereo_gui.sources.base import FrameSource
from stereo_gui.sources.open import OpenedSource, open_source
from stereo_gui.sources.playback import VIDEO_EXTENSIONS

log = logging.getLogger(__name__)

DEFAULT_SIZE = (1366, 860)  # px, when the screen has room for it
_FRAME_PX = 32  # room left for the window manager's title bar, px
NARROW_SCREEN_PX = 1200  # below this width the Live tab starts with its parameters hidden


def default_window_size(available: QRect | None) -> tuple[int, int]:
    """(width, height) px of a new window: DEFAULT_SIZE, within `available` (a QRect of the
    screen's usable area, None when unknown) less room for the title bar."""
    w, h = DEFAULT_SIZE
    if available is None:
        return w, h
    return min(w, available.width()), min(h, available.height() - _FRAME_PX)


CLOSE_TIMEOUT_MS = 2000  # closing waits at most this long for the workers, all together
TAB_NAMES = ("capture", "calibration", "live", "measurements")
CALIB_FILTER = "Calibration files (*.yaml *.yml *.xml *.json *.txt);;All files (*)"
SIM_BANNER = ("Running on the SIMULATED stereo rig: {why}. Distances are of the rendered scene, "
              "not of the real world. Choose a source in File > Choose source… once cameras "
              "are connected.")


def _close_source(source: FrameSource) -> None:
    try:
        source.close()
    except Exception:
        log.warning("closing an unused source failed", exc_info=True)


def _close_opened(opened: object) -> None:
    """The source opener's `dispose`: a source opened after the window closed is closed."""
    if isinstance(opened, OpenedSource):
        _close_source(opened.source)


SOURCE_SHORTCUT = "Ctrl+Shift+O"  # File > Choose source…


def recent_entry(path: str) -> tuple[str, str, str]:
    """(kind, path, menu text) of a recent file: kind is calibration, session, recording,
    folder, video or missing."""
    p = Path(path)
    if not p.exists():
        return "missing", path, f"{p.name} (missing)"
    if p.is_dir():
        if (p / MANIFEST).is_file():
            return "session", path, f"Session: {p.name}   ({p.parent})"
        if is_recording(p):
            return "recording", path, f"Recording: {p.name}   ({p.parent})"
        return "folder", path, f"Folder of pairs: {p.name}   ({p.parent})"
    if p.suffix.lower() in VIDEO_EXTENSIONS:
        return "video", path, f"Video: {p.name}   ({p.parent})"
    return "calibration", path, f"Calibration: {p.name}   ({p.parent})"


def shown_tooltip(stats: ShownStats | None, cores: int) -> str:
    """What the status bar's 'Shown' figures mean, with the 95th percentile of the latency
    (`stats`: the Live tab's, None when it shows nothing)."""
    p95 = stats.latency.p95_ms if stats is not None and stats.showing else math.nan
    spread = (f" (95th percentile {p95:.0f} ms)" if math.isfinite(p95) else "")
    return (f"Frames drawn in the Live tab per second, over the last {SHOWN_WINDOW_S:g} s.\n"
            f"Latency, median{spread}: from the source's delivery of a frame to the Live "
            "tab's views getting its image.\n"
            f"CPU: this program's CPU time (all its threads) as a share of all {cores} "
            f"core{'s' if cores != 1 else ''} it may use (100 % = all of them busy), over the "
            f"last {CPU_WINDOW_S:g} s.")


def _quietly(fn: Callable[[], bool], default: bool = False) -> bool:
    """fn() or `default` when it raises (a property of a source closed meanwhile)."""
    try:
        return fn()
    except Exception:  # noqa: BLE001
        return default


def is_simulated(source: FrameSource) -> bool:
    """Whether `source` renders the simulated rig (its frames are of no real scene)."""
    return simulated_rig(source) is not None


def _format_rms(value: float) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "?"
    return "?" if v != v else f"{v:.3f} px"


class ClosePhase(Enum):
    """Where the window is on its way to closing."""

    OPEN = "open"  # not closing, or closing was called off
    WAITING = "waiting"  # the CloseWaiter waits for running work to end
    CLOSING = "closing"  # the tabs and workers are being stopped; the window goes


# waiting only for work the open window has; the waiter ends once (done, cancelled, Don't
# close), back to OPEN, from where the window closes; nothing follows CLOSING
CLOSE_MOVES: Transitions[ClosePhase] = Transitions("closing", {
    ClosePhase.OPEN: {ClosePhase.WAITING, ClosePhase.CLOSING},
    ClosePhase.WAITING: {ClosePhase.OPEN},
    ClosePhase.CLOSING: set(),
})


@dataclass
class CloseState:
    """Where closing the window stands. The answers hold for one attempt to close: keeping
    the window open (Don't close) forgets them."""

    phase: ClosePhase = ClosePhase.OPEN
    waiter: CloseWaiter | None = None  # shown while WAITING
    calibration_discarded: bool = False  # "Discard" was answered for the unsaved calibration
    work_settled: bool = False  # the running work ended or was cancelled: do not wait again

    def move(self, to: ClosePhase, waiter: CloseWaiter | None = None) -> None:
        """Go to phase `to` (CLOSE_MOVES refuses an impossible move: TransitionError) with
        `waiter` shown (WAITING) or none."""
        self.phase = CLOSE_MOVES.check(self.phase, to)
        self.waiter = waiter

    def start_over(self, calibration_discarded: bool = False,
                   work_settled: bool = False) -> None:
        """A new attempt to close, OPEN: the answers of the last one forgotten (or given)."""
        if self.phase is not ClosePhase.OPEN:
            self.move(ClosePhase.OPEN)
        self.waiter = None
        self.calibration_discarded = calibration_discarded
        self.work_settled = work_settled


class _MessageBar(QWidget):
    """A coloured bar with a message and an optional close button (the banner)."""

    def __init__(self, style: str, closable: bool, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setAutoFillBackground(True)
        self.setStyleSheet(style)
        self.label = QLabel()
        self.label.setWordWrap(True)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        row = QHBoxLayout(self)
        row.setContentsMargins(10, 4, 6, 4)
        row.addWidget(self.label, 1)
        if closable:
            close = QToolButton()
            close.setText("✕")
            close.setToolTip("Dismiss")
            close.setAutoRaise(True)
            close.clicked.connect(self.hide)
            row.addWidget(close)
        self.hide()

    def show_text(self, text: str) -> None:
        self.label.setText(text)
        self.show()


class MainWindow(QMainWindow):
    """The application window. `ctx` is the AppContext it shows."""

    sourceOpened = Signal(str)  # the source spec now in use

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        # errors reported before the error bar exists (a remembered session that cannot be
        # opened, bad settings) are shown once it does
        early_errors: list[str] = []
        collect = early_errors.append
        ctx.errorOccurred.connect(collect)
        self._build_source_opener()
        self.setWindowTitle("Stereo GUI")
        self.resize(*default_window_size(self._available_geometry()))
        self._build_central()
        self._last_session_seen = ctx.settings.last_session
        self._build_menus()
        self._build_status_bar()
        ctx.settings_model.changed.connect(self._settings_changed)

        ctx.errorOccurred.disconnect(collect)
        ctx.errorOccurred.connect(self.show_error)
        for text in early_errors:
            self.show_error(text)
        self._connect_context()
        self._update_calibration_label()
        self._fps_timer = QTimer(self)
        self._fps_timer.setInterval(500)
        self._fps_timer.timeout.connect(self._update_fps)
        self._fps_timer.start()
        self._restore_geometry()
        self.show_tab("live")
        self._tab_changed(self.tabs.currentIndex())

    # ---- construction ------------------------------------------------------------------------
    def _build_source_opener(self) -> None:
        """The remembered source, the closing state, and the thread that opens sources."""
        self.source_choice = self._choice_from_settings()
        self._close = CloseState()
        self._opening: tuple[SourceChoice, bool] = (self.source_choice, False)
        self._opening_id = 0
        # a source opened after the window closed is closed, not leaked
        self._opener = JobRunner("source-opener", self, dispose=_close_opened)
        self._opener.finished.connect(self._source_opened)
        self._opener.failed.connect(self._source_failed)
        self.ctx.workers.register(self._opener)

    def _build_central(self) -> None:
        """The simulated rig's banner and the error bar above the four tabs."""
        self.banner = _MessageBar(
            "background: #ffd54f; color: #3e2700; font-weight: bold;", closable=False)
        self.error_bar = ErrorBar()  # every problem kept, the newest shown
        self._build_tabs()
        central, col = pane()
        col.setSpacing(0)
        col.addWidget(self.banner)
        col.addWidget(self.error_bar)
        col.addWidget(self.tabs, 1)
        self.setCentralWidget(central)

    def _build_tabs(self) -> None:
        ctx = self.ctx
        self.tabs = QTabWidget()
        self.tabs.setDocumentMode(True)
        self.capture_tab = CaptureTab(ctx)
        self.calibration_tab = CalibrationTab(ctx)
        self.live_tab = LiveTab(ctx)
        self.measurements_tab = MeasurementsTab(ctx)
        self._pages: tuple[WindowTab, ...] = (self.capture_tab, self.calibration_tab,
                                              self.live_tab, self.measurements_tab)
        for name, tab in zip(TAB_NAMES, self._pages, strict=True):
            self.tabs.addTab(tab, name.capitalize())
        self.tabs.currentChanged.connect(self._tab_changed)
        self.live_tab.calibrateRequested.connect(lambda: self.show_tab("calibration"))
        self.live_tab.loadCalibrationRequested.connect(self.open_calibration)

    def _connect_context(self) -> None:
        """The status bar, the calibration, source and stream labels, and the recorder's."""
        ctx = self.ctx
        ctx.statusMessage.connect(lambda text: self.statusBar().showMessage(text, 8000))
        ctx.calibration_model.changed.connect(self._update_calibration_label)
        ctx.frames.sourceChanged.connect(self._update_source_label)
        ctx.frames.streamStatus.connect(self._stream_status)
        self._stream_error = ""  # the error bar's text about the stream, while it is wrong
        ctx.recorder.started.connect(lambda _f: self._update_recording_label())
        ctx.recorder.stopped.connect(lambda _r: self._update_recording_label())
        ctx.recorder.stopped.connect(self._recording_stopped)

    def _build_menus(self) -> None:
        file_menu = self.menuBar().addMenu("&File")
        self.act_source = QAction("Choose &source…", self)
        self.act_source.setShortcut(QKeySequence(SOURCE_SHORTCUT))
        self.act_source.triggered.connect(self.choose_source)
        self.recent_menu = QMenu("Open &recent", self)
        self.recent_menu.aboutToShow.connect(self._fill_recent_menu)
        self.act_open = QAction("&Open calibration…", self)
        self.act_open.setShortcut(QKeySequence.StandardKey.Open)
        self.act_open.triggered.connect(lambda: self.open_calibration())
        self.act_save = QAction("&Save calibration as…", self)
        self.act_save.setShortcut(QKeySequence.StandardKey.SaveAs)
        self.act_save.triggered.connect(lambda: self.save_calibration())
        self.act_export_ros = QAction("&Export ROS camera_info…", self)
        self.act_export_ros.setToolTip("Write left.yaml and right.yaml (ROS camera_info) into "
                                       "a folder")
        self.act_export_ros.triggered.connect(lambda: self.export_ros())
        self.act_export_kalibr = QAction("Export &Kalibr camchain…", self)
        self.act_export_kalibr.setToolTip("Write the calibration as a Kalibr camchain.yaml "
                                          "(cam0, cam1; pinhole radtan or equidistant lenses)")
        self.act_export_kalibr.triggered.connect(lambda: self.export_kalibr())
        self.act_import_ros = QAction("&Import ROS camera_info…", self)
        self.act_import_ros.setToolTip("Use a calibration from a ROS left.yaml + right.yaml pair")
        self.act_import_ros.triggered.connect(lambda: self.import_ros())
        self.act_stream = QAction("S&tream the depth (Foxglove)", self)
        self.act_stream.setCheckable(True)
        self.act_stream.setToolTip("Serve the live depth to robots' programs and Foxglove on "
                                   "this machine, as the Live tab's Stream button")
        self.act_stream.toggled.connect(self.live_tab.stream.set_on)
        self.live_tab.stream.changed.connect(self.act_stream.setChecked)
        self.act_stream.setChecked(self.live_tab.stream.button.isChecked())
        self.act_mcap = QAction("Record &MCAP…", self)
        self.act_mcap.setToolTip("Record the depth stream's topics to an MCAP file (Foxglove, "
                                 "ROS 2 tools)")
        self.act_mcap.triggered.connect(lambda: self.toggle_mcap())
        self.live_tab.stream.recordingChanged.connect(self._mcap_changed)
        quit_act = QAction("&Quit", self)
        quit_act.setShortcut(QKeySequence.StandardKey.Quit)
        quit_act.triggered.connect(self.close)
        for a in (self.act_source, None, self.act_open, self.recent_menu, self.act_save, None,
                  self.act_import_ros, self.act_export_ros, self.act_export_kalibr, None,
                  self.act_stream,
                  self.act_mcap, None, quit_act):
            if a is None:
                file_menu.addSeparator()
            elif isinstance(a, QMenu):
                file_menu.addMenu(a)
            else:
                file_menu.addAction(a)
        self._build_shortcuts()
        help_menu = self.menuBar().addMenu("&Help")
        self.help_actions = add_help_actions(self, help_menu, self.ctx)
        about = QAction("&About Stereo GUI", self)
        about.triggered.connect(self.show_about)
        help_menu.addAction(about)

    def _build_shortcuts(self) -> None:
        """Ctrl+1..4 switch tabs; Space pauses the Live view (or the playback) while Live is
        shown, and only then, so that Space keeps its meaning elsewhere."""
        self.tab_shortcuts = []
        for i, name in enumerate(TAB_NAMES):
            sc = QShortcut(QKeySequence(f"Ctrl+{i + 1}"), self)
            sc.activated.connect(lambda n=name: self.show_tab(n))
            self.tab_shortcuts.append(sc)
        self.pause_shortcut = QShortcut(QKeySequence(Qt.Key.Key_Space), self)
        self.pause_shortcut.activated.connect(self.toggle_live_pause)
        self.pause_shortcut.setEnabled(False)

    def toggle_live_pause(self) -> None:
        """Pause or resume what the Live tab shows: the playback when a recording plays, else
        the live view."""
        self.live_tab.toggle_pause()

    # ---- recent files ----------------------------------------------------------------------
    def remember_recent(self, path: str | Path) -> None:
        """Put `path` (a calibration, session, recording or video) first in File > Open recent."""
        self.ctx.settings_model.remember_recent(str(Path(path).expanduser().resolve()))

    def _recording_stopped(self, result: RecordingResult) -> None:
        """A recording just made is in File > Open recent at once, not only once played."""
        if result.frames and result.recording is not None:
            self.remember_recent(result.folder)

    def _settings_changed(self, settings: Settings) -> None:
        session = settings.last_session
        if session and session != self._last_session_seen:
            self._last_session_seen = session
            self.remember_recent(session)

    def _fill_recent_menu(self) -> None:
        self.recent_menu.clear()
        entries = [recent_entry(p) for p in self.ctx.settings.recent_files]
        if not entries:
            none = self.recent_menu.addAction("(nothing yet)")
            none.setEnabled(False)
            return
        for kind, path, label in entries:
            act = self.recent_menu.addAction(label)
            act.setToolTip(path)
            act.setEnabled(kind != "missing")
            act.triggered.connect(lambda _c=False, p=path: self.open_recent(p))

    def open_recent(self, path: str) -> bool:
        """Open a recent file as what it is: a calibration is loaded, a capture session opened
        in the Capture tab, a recording, folder or video played as the source."""
        kind, path, _label = recent_entry(path)
        if kind == "missing":
            self.ctx.report_error(f"{path} is no longer there.")
            return False
        if kind == "calibration":
            return self.open_calibration(path)
        if kind == "session":
            self.show_tab("capture")
            self.capture_tab.open_session(path)
            return True
        c = self.source_choice
        w, h = c.size
        self.open_source(SourceChoice(path, (w, h), bool(c.swap)))
        self.show_tab("live")
        return True

    def _build_status_bar(self) -> None:
        sb = self.statusBar()
        self.source_label = QLabel("Source: none")
        self.camera_fps_label = QLabel("Camera: – fps")
        self.processing_fps_label = QLabel("Processing: – fps")
        self.shown_label = QLabel("Shown: –")
        self._cpu = CpuMeter()  # the process's CPU share, read by the status bar's timer
        self.calibration_label = QLabel("No calibration")
        self.recording_label = QLabel()
        self.recording_label.setStyleSheet("color: #ff5252; font-weight: bold;")
        for w in (self.recording_label, self.source_label, self.camera_fps_label,
                  self.processing_fps_label, self.shown_label, self.calibration_label):
            w.setContentsMargins(6, 0, 6, 0)
            sb.addPermanentWidget(w)
        self.recording_label.hide()

    def _choice_from_settings(self) -> SourceChoice:
        s = self.ctx.settings
        w, h = s.resolution
        return SourceChoice(s.source or "auto", (w, h), bool(s.swap_lr))

    # ---- tabs --------------------------------------------------------------------------------
    def show_tab(self, name: str) -> None:
        self.tabs.setCurrentIndex(TAB_NAMES.index(name))

    def current_tab_name(self) -> str:
        i = self.tabs.currentIndex()
        return TAB_NAMES[i] if 0 <= i < len(TAB_NAMES) else ""

    def _tab_changed(self, index: int) -> None:
        # the hidden ones first: the shown one owns the frame worker's processor
        for i, page in enumerate(self._pages):
            if i != index:
                page.set_active(False)
        if 0 <= index < len(self._pages):
            self._pages[index].set_active(True)
        self.pause_shortcut.setEnabled(self.current_tab_name() == "live")

    # ---- source ------------------------------------------------------------------------------
    def choose_source(self) -> None:
        dlg = SourceDialog(self.source_choice, parent=self)
        if dlg.exec():
            self.open_source(dlg.choice())

    def open_source(self, choice: SourceChoice, fallback_to_auto: bool = False) -> int:
        """Open the chosen source off the UI thread (opening a device or building the simulated
        rig takes seconds), then hand it to the frame worker; failures become a message.

        With `fallback_to_auto`, a source that fails is replaced by automatic selection (used
        for the remembered source at start-up). Returns the request id.
        """
        w, h = choice.size
        spec, size, swap = choice.spec, (w, h), bool(choice.swap)
        # the remembered cameras are found again by name and USB ids if their indices changed
        s = self.ctx.settings
        known = tuple(s.cameras) if spec == s.source else ()
        self.source_label.setText(f"Source: opening {describe_spec(spec)}…")
        self.statusBar().showMessage(f"Opening {describe_spec(spec)}…")
        self._opening = (choice, fallback_to_auto)
        self._opening_id = self._opener.submit(
            lambda _control: open_source(spec, size=size, swap=swap,
                                         remembered_cameras=known)).id
        return self._opening_id

    def is_opening_source(self) -> bool:
        return self._opener.is_busy()

    def _source_opened(self, job_id: int, opened: OpenedSource) -> None:
        if job_id != self._opening_id or self._close.phase is ClosePhase.CLOSING:
            _close_source(opened.source)  # a newer request or the window closed meanwhile
            return
        self.statusBar().clearMessage()
        choice = self._opening[0]
        if opened.spec:  # absolute paths; cameras where they were found
            choice = replace(choice, spec=opened.spec)
        for text in opened.warnings:  # a recording not closed cleanly, frames left out, ...
            self.ctx.report_error(text)
        self.use_source(opened.source, choice, opened.fell_back_to_sim, opened.message,
                        cameras=opened.cameras)

    def _source_failed(self, job_id: int, message: str) -> None:
        if job_id != self._opening_id or self._close.phase is ClosePhase.CLOSING:
            return
        choice, fallback = self._opening
        self.ctx.report_error(f"Cannot open the source {describe_spec(choice.spec)}: {message}")
        self._update_source_label(self.ctx.frames.status().source_name)
        if fallback and choice.spec != "auto":
            self.open_source(SourceChoice("auto", choice.size, choice.swap))

    def use_source(self, source: FrameSource, choice: SourceChoice, fell_back_to_sim: bool = False,
                   message: str = "", cameras: tuple[str, ...] = ()) -> None:
        """Use an already opened source (remembered in the settings, with the identities of its
        cameras)."""
        self.source_choice = choice
        if fell_back_to_sim:
            why = (message or "no cameras were found").split(";")[0].strip()
            self.banner.show_text(SIM_BANNER.format(why=why))
        elif is_simulated(source):  # chosen (--source sim, the source dialog): said all the same
            self.banner.show_text(SIM_BANNER.format(why="it was chosen as the source"))
            if message:
                self.statusBar().showMessage(message, 8000)
        else:
            self.banner.hide()
            if message:
                self.statusBar().showMessage(message, 8000)
        self.ctx.settings_model.update(source=choice.spec, resolution=tuple(choice.size),
                                       swap_lr=bool(choice.swap), cameras=tuple(cameras))
        if Path(choice.spec).expanduser().exists():  # a recording, a folder or a video
            self.remember_recent(choice.spec)
        self.ctx.frames.set_source(source)
        self.sourceOpened.emit(choice.spec)

    def _update_source_label(self, name: str) -> None:
        self.source_label.setText(f"Source: {name or 'none'}")

    def _stream_status(self, status: StreamStatus) -> None:
        """The frame worker's StreamStatus: the source label says a camera is being
        reconnected or the source stopped; once frames come again the error bar about the
        stream goes (a newer error stays) and the status bar says the frames are back."""
        if status.state is StreamState.OK:
            if self._stream_error:
                self.error_bar.remove(self._stream_error)
            self._stream_error = ""
            self._update_source_label(status.source_name)
            if status.message:
                self.statusBar().showMessage(status.message, 8000)
            return
        self._stream_error = status.message
        if status.state is StreamState.RECONNECTING:
            self.source_label.setText(f"Source: {status.source_name} (reconnecting…)")
        elif status.state is StreamState.STALLED:
            self.source_label.setText(f"Source: {status.source_name} (not answering)")
        elif status.state is StreamState.FAILED:
            self.source_label.setText(f"Source: none ({status.source_name} stopped)")

    def _update_recording_label(self) -> None:
        rec = self.ctx.recorder
        if rec.is_recording:
            self.recording_label.setText(f"● REC {format_elapsed(rec.elapsed_s)}, "
                                         f"{rec.frames_written} frames")
            self.recording_label.setToolTip(str(rec.folder))
        self.recording_label.setVisible(rec.is_recording)

    def _update_fps(self) -> None:
        self._update_recording_label()
        s = self.ctx.frames.status()
        self._update_shown(s.paused)
        if s.paused:
            self.camera_fps_label.setText("Camera: paused")
            self.processing_fps_label.setText("Processing: paused")
            return
        playback = playback_of(self.ctx.frames.source())
        if playback is not None and _quietly(lambda: bool(playback.paused)):
            # the reader re-delivers the paused frame: its rate is no camera's
            self.camera_fps_label.setText("Playback: paused")
            self.processing_fps_label.setText(f"Processing: {s.processing_fps:.1f} fps")
            return
        skipped = s.skipped_frames
        self.camera_fps_label.setText(f"Camera: {s.camera_fps:.1f} fps" + (
            f", {skipped} bad frame{'s' if skipped != 1 else ''} skipped" if skipped else ""))
        self.camera_fps_label.setToolTip("Frames that could not be decoded are left out"
                                         if skipped else "")
        self.processing_fps_label.setText(f"Processing: {s.processing_fps:.1f} fps")

    def _update_shown(self, paused: bool) -> None:
        """'Shown: 29.8 fps, 41 ms, CPU 47 %': the Live tab's frames drawn per second, their
        median latency from the source's delivery, and the process's CPU share of all cores;
        'Shown: –' (with the CPU) while the Live tab is hidden or draws nothing."""
        cpu = self._cpu.sample()
        cpu_text = f"CPU {cpu:.0f} %" if math.isfinite(cpu) else "CPU –"
        live = self.current_tab_name() == "live" and not paused
        stats = self.live_tab.shown_stats() if live else None
        if paused:
            text = f"Shown: paused, {cpu_text}"
        elif stats is not None and stats.showing:
            ms = stats.latency.median_ms
            latency = f"{ms:.0f} ms" if math.isfinite(ms) else "– ms"
            text = f"Shown: {stats.fps:.1f} fps, {latency}, {cpu_text}"
        else:
            text = f"Shown: –, {cpu_text}"
        self.shown_label.setText(text)
        tip = shown_tooltip(stats, self._cpu.cores)
        if tip != self.shown_label.toolTip():
            self.shown_label.setToolTip(tip)

    # ---- calibration files -------------------------------------------------------------------
    def _update_calibration_label(self, *_args: object) -> None:
        c = self.ctx.calibration
        if c is None:
            self.calibration_label.setText("No calibration")
            self.calibration_label.setToolTip("")
            return
        path = self.ctx.calibration_path
        name = path.name if path is not None else (self.ctx.calibration_note or "not saved")
        self.calibration_label.setText(f"Calibration: {name}, RMS {_format_rms(c.rms_stereo)}")
        self.calibration_label.setToolTip(str(path) if path else "")

    def _start_dir(self) -> str:
        s = self.ctx.settings
        if self.ctx.calibration_path is not None:
            return str(self.ctx.calibration_path.parent)
        if s.last_calibration:
            return str(Path(s.last_calibration).parent)
        return str(Path.home())

    def open_calibration(self, path: str | None = None) -> bool:
        """Load a calibration file (asks for one without `path`); True when loaded."""
        if not path:
            path, _ = QFileDialog.getOpenFileName(self, "Open calibration", self._start_dir(),
                                                  CALIB_FILTER)
            if not path:
                return False
        return self.ctx.calibration_model.open_file(path)

    def save_calibration(self, path: str | None = None) -> bool:
        """Save the current calibration (asks where without `path`); True when written."""
        calib = self.ctx.calibration
        if calib is None:
            self.ctx.report_error("There is no calibration to save: calibrate or open one first.")
            return False
        if not path:
            start = str(Path(self._start_dir()) / "calibration.yaml")
            path, _ = folder_dialog.save_file_name(self, "Save calibration", start, CALIB_FILTER)
            if not path:
                return False
        return self.ctx.calibration_model.save_file(calib, path)

    def toggle_mcap(self, path: str | None = None) -> Path | None:
        """Start an MCAP recording of the depth stream (asks for the file without `path`), or
        stop the one running; the file being recorded, None when none."""
        return self.live_tab.stream.toggle_recording(self, path)

    def _mcap_changed(self, path: Path | None) -> None:
        self.act_mcap.setText("Stop &MCAP recording" if path is not None else "Record &MCAP…")

    def export_ros(self, folder: str | None = None) -> tuple[Path, Path] | None:
        """Write the calibration as ROS camera_info left.yaml and right.yaml into `folder`
        (asks for it without); returns both paths, or None (with a message)."""
        if self.ctx.calibration is None:
            self.ctx.report_error("There is no calibration to export: calibrate or open one first.")
            return None
        if not folder:
            folder = QFileDialog.getExistingDirectory(
                self, "Export ROS camera_info (left.yaml, right.yaml) into", self._start_dir())
            if not folder:
                return None
        return self.ctx.calibration_model.export_ros(folder)

    def export_kalibr(self, path: str | None = None) -> Path | None:
        """Write the calibration as a Kalibr camchain.yaml (asks where without `path`); its
        path, or None (with a message)."""
        if self.ctx.calibration is None:
            self.ctx.report_error("There is no calibration to export: calibrate or open one first.")
            return None
        if not path:
            path, _ = folder_dialog.save_file_name(
                self, "Export Kalibr camchain", str(Path(self._start_dir()) / "camchain.yaml"),
                "Kalibr camchain (*.yaml)")
            if not path:
                return None
        return self.ctx.calibration_model.export_kalibr(path)

    def import_ros(self, left: str | None = None, right: str | None = None) -> bool:
        """Use the calibration of a ROS camera_info pair (asks for the two files without them);
        True when loaded. Chosen together, the file whose name says "right" is the right one."""
        if not left or not right:
            files, _ = QFileDialog.getOpenFileNames(
                self, "Import ROS camera_info: choose the left and the right file",
                self._start_dir(), "ROS camera_info (*.yaml *.yml);;All files (*)")
            if not files:
                return False
            if len(files) != 2:
                self.ctx.report_error(f"Choose exactly two ROS camera_info files (left and right), "
                                      f"not {len(files)}.")
                return False
            left, right = order_left_right(files)
        return self.ctx.calibration_model.import_ros(left, right)

    # ---- messages ----------------------------------------------------------------------------
    def show_error(self, text: str) -> None:
        self.error_bar.show_text(text)
        self.statusBar().showMessage(text, 10000)

    def show_about(self) -> None:
        show_about(self)

    # ---- geometry and shutdown ---------------------------------------------------------------
    def _available_geometry(self) -> QRect | None:
        """The part of the screen a window may use (without panels and docks), or None."""
        screen = self.screen() or QGuiApplication.primaryScreen()
        return screen.availableGeometry() if screen is not None else None

    def _restore_geometry(self) -> None:
        s = self.ctx.settings
        if s.window_geometry:
            self.restoreGeometry(QByteArray.fromBase64(s.window_geometry.encode("ascii")))
        if s.window_state:
            self.restoreState(QByteArray.fromBase64(s.window_state.encode("ascii")))
        avail = self._available_geometry()
        if avail is not None:
            # a window remembered from a larger screen starts within this one
            g = self.geometry()
            w, h = min(g.width(), avail.width()), min(g.height(), avail.height() - _FRAME_PX)
            if (w, h) != (g.width(), g.height()):
                self.resize(w, h)
            if not avail.intersects(self.frameGeometry()):
                self.move(avail.topLeft())
            if avail.width() < NARROW_SCREEN_PX:
                self.live_tab.show_parameters(False)  # the views need the width

    def save_settings(self) -> None:
        """Store geometry (and whatever the tabs changed) in the settings file."""
        geometry = bytes(self.saveGeometry().toBase64().data()).decode("ascii")
        state = bytes(self.saveState().toBase64().data()).decode("ascii")
        self.ctx.settings_model.update(window_geometry=geometry, window_state=state)
        self.ctx.settings_model.save()

    # ---- closing without losing work ---------------------------------------------------------
    def unfinished_work(self) -> list[str]:
        """What closing now would cut short (the tabs' running exports), for a person."""
        return [line for page in self._pages for line in page.unfinished_work()]

    def close_waiter(self) -> CloseWaiter | None:
        """The dialog shown while closing waits for running work, else None."""
        return self._close.waiter

    def close_without_asking(self) -> None:
        """Close now: an unsaved calibration is discarded and running work cancelled."""
        if self._close.phase is not ClosePhase.CLOSING:
            if self._close.waiter is not None:
                self._close.waiter.dismiss()
            self._close.start_over(calibration_discarded=True, work_settled=True)
        self.close()

    def _keep_or_save_calibration(self) -> bool:
        """Ask Save / Discard / Cancel for a computed calibration not saved; False to stay open
        (Cancel, or Save that was not done)."""
        what = self.calibration_tab.unsaved_calibration()
        if not what or self._close.calibration_discarded:
            return True
        answer = ask_unsaved_calibration(self, what)
        if answer == QMessageBox.StandardButton.Save:
            return self.save_calibration()
        if answer == QMessageBox.StandardButton.Discard:
            self._close.calibration_discarded = True
            log.info("closing: the unsaved calibration (%s) was discarded", what)
            return True
        return False

    def _wait_for_work(self) -> bool:
        """With exports still running: show the CloseWaiter and close when they are done (or
        cancel them, see `_cancel_work_and_close`); False when nothing runs."""
        if self._close.work_settled or not self.unfinished_work():
            return False
        waiter = CloseWaiter(self, self.unfinished_work)
        waiter.workDone.connect(self._work_done_close)
        waiter.cancelRequested.connect(self._cancel_work_and_close)
        waiter.aborted.connect(self._close_aborted)
        self._close.move(ClosePhase.WAITING, waiter)
        self.statusBar().showMessage("Closing as soon as the export is written…")
        waiter.open()
        return True

    def _work_done_close(self) -> None:
        self._close.move(ClosePhase.OPEN)
        self._close.work_settled = True
        self.close()

    def _close_aborted(self) -> None:
        self._close.start_over()
        self.statusBar().showMessage("Not closed: the export goes on", 8000)

    def _cancel_work_and_close(self, timed_out: bool) -> None:
        waiter = self._close.waiter
        waited_s = waiter.wait_s if waiter is not None and timed_out else None
        self._close.move(ClosePhase.OPEN)
        deadline = time.monotonic() + CLOSE_TIMEOUT_MS / 1000.0
        said: list[str] = []
        for page in self._pages:
            left = max(1, int((deadline - time.monotonic()) * 1000))
            said.extend(page.cancel_unfinished_work(timeout_ms=left))
        for line in said:
            log.warning("closing: %s", line)
        self._close.work_settled = True
        tell_cancelled(self, said, waited_s)
        self.close()

    def closeEvent(self, event: QCloseEvent) -> None:
        if self._close.phase is ClosePhase.WAITING:
            # closed again while waiting: the user insists. After this event, since a close()
            # from within closeEvent would be refused
            event.ignore()
            waiter = self._close.waiter
            assert waiter is not None  # (CloseState.move shows one while WAITING)
            QTimer.singleShot(0, waiter.insist)
            return
        if self._close.phase is ClosePhase.OPEN:
            # a true distance still being typed belongs in the log that is kept
            self.measurements_tab.commit_edits()
            if not self._keep_or_save_calibration() or self._wait_for_work():
                event.ignore()
                return
            self._stop_everything()
        super().closeEvent(event)

    def _stop_everything(self) -> None:
        """Stop the tabs and every worker within one deadline, and save the settings: a blocked
        worker never makes closing take longer than CLOSE_TIMEOUT_MS."""
        self._close.move(ClosePhase.CLOSING)
        self._fps_timer.stop()
        deadline = time.monotonic() + CLOSE_TIMEOUT_MS / 1000.0

        def left_ms() -> int:
            return max(1, int((deadline - time.monotonic()) * 1000))

        for page in self._pages:
            try:
                page.shutdown(timeout_ms=left_ms())
            except Exception:
                log.warning("shutting down a tab failed", exc_info=True)
        self.save_settings()
        if not self.ctx.shutdown(left_ms()):
            log.warning("some workers did not stop within %d ms", CLOSE_TIMEOUT_MS)
