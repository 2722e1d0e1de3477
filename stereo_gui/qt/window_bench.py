"""`stereo-gui bench --window SECONDS`: the application's own window, timed.

The window is built as `run_app` builds it (`app.build_window`, the frame lanes' OpenCV threads,
the start-up objects frozen for the garbage collector), on settings written to a temporary
folder for the run (`STEREO_GUI_CONFIG_DIR` and `STEREO_GUI_DATA_DIR` point there meanwhile), so
that the user's settings, presets and measurement log are never read or touched. The settings
give the source, the frame size, the preset and the Live tab's views; on the simulated rig
without --calib the Live tab uses the rig's true calibration, as its button does.

Once the Live tab has drawn its first frame, WARMUP_S pass; then for `seconds` the frames the
Live tab draws are counted with each one's latency (`LiveTab.last_latency_ms`: from the frame
worker's reader getting the frame to the last view's image), and the frames processed and read
(`FrameWorker.status()`) and the process's CPU time are read at both ends. What the options
mean and the line printed are `commands.bench_window`'s.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from enum import Enum
from pathlib import Path

from PySide6.QtCore import (
    QEventLoop,
    QMessageLogContext,
    QObject,
    Qt,
    QTimer,
    QtMsgType,
    qInstallMessageHandler,
)
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QApplication

from stereo_gui.commands.bench_window import WindowBench, WindowBenchResult
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.states import Transitions
from stereo_gui.core.timing import cpu_percent, intervals, latency_stats, usable_cores
from stereo_gui.files.presets import BUILTIN, save_user_preset
from stereo_gui.files.settings import Settings, save_settings
from stereo_gui.pipeline.concurrency import use_opencv_threads_beside_lanes
from stereo_gui.pipeline.live import LiveOutput
from stereo_gui.qt.app import build_window, freeze_startup_objects, on_signals
from stereo_gui.qt.context import AppContext
from stereo_gui.qt.main_window import MainWindow
from stereo_gui.qt.source_capabilities import simulated_rig

log = logging.getLogger(__name__)

START_TIMEOUT_S = 120.0  # the source open and a first frame drawn within this (the rig: ~10 s)
WINDOW_PX = (1366, 736)  # the window on a 1366x768 laptop screen, less its title bar
CLOSE_TIMEOUT_MS = 2000
SETTINGS_DIRS = (("STEREO_GUI_CONFIG_DIR", "config"), ("STEREO_GUI_DATA_DIR", "data"))


@contextlib.contextmanager
def temporary_settings_dirs() -> Iterator[Path]:
    """Point the settings and data folders at a new temporary folder (removed afterwards) while
    the block runs; the environment is put back as it was."""
    before = {name: os.environ.get(name) for name, _ in SETTINGS_DIRS}
    with tempfile.TemporaryDirectory(prefix="stereo-gui-bench-") as tmp:
        try:
            for name, sub in SETTINGS_DIRS:
                folder = Path(tmp) / sub
                folder.mkdir()
                os.environ[name] = str(folder)
            yield Path(tmp)
        finally:
            for name, value in before.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value


def _preset_setting(request: WindowBench) -> str:
    """What Settings.preset must hold for the Live tab to start with the preset asked for: a
    built-in's name, a preset file's full path, or the name of the user's preset copied into
    the temporary settings folder (the user's own is not read from there)."""
    name = request.preset
    if name in BUILTIN:
        return name
    if name.endswith(".json") and Path(name).is_file():
        return str(Path(name).resolve())
    save_user_preset(request.params, name)
    return name


def run_window_bench(request: WindowBench) -> WindowBenchResult:
    """Build the window on temporary settings, time it as the module doc says, close it."""
    with temporary_settings_dirs():
        save_settings(Settings(source=request.source, resolution=request.size or (640, 480),
                               preset=_preset_setting(request), visible_views=request.views))
        use_opencv_threads_beside_lanes()  # as run_app: the frame lanes share the cores
        existing = QApplication.instance()
        app = existing if isinstance(existing, QApplication) else QApplication(sys.argv[:1])
        app.setApplicationName("Stereo GUI")
        ctx, window = build_window(request.source, request.calib)
        previous_handler = qInstallMessageHandler(_qt_message)
        try:
            window.resize(*WINDOW_PX)
            window.show()
            if existing is None:  # (as run_app; never in a process that was running before)
                freeze_startup_objects()
            return _Timing(ctx, window, request).run()
        finally:
            window.close()  # the tabs and every worker stopped, the settings saved (there)
            if not ctx.shutdown(CLOSE_TIMEOUT_MS):
                log.warning("a worker did not stop within %d ms after the bench",
                            CLOSE_TIMEOUT_MS)
            window.deleteLater()
            qInstallMessageHandler(previous_handler)


def _qt_message(kind: QtMsgType, _context: QMessageLogContext, text: str) -> None:
    """Qt's own messages during the bench go to the log (-v shows them), not between the
    command's output: the offscreen platform's "does not support propagateSizeHints()" is no
    news about the window's speed."""
    level = logging.WARNING if kind in (QtMsgType.QtCriticalMsg, QtMsgType.QtFatalMsg) \
        else logging.DEBUG
    log.log(level, "Qt: %s", text)


class BenchPhase(Enum):
    """Where a window bench stands."""

    STARTING = "starting"  # the source opening, no frame drawn yet
    WARMING = "warming"  # the first frame drawn, WARMUP_S passing
    COUNTING = "counting"  # the frames drawn, with their latency, counted
    DONE = "done"  # counted, failed or interrupted: the event loop ends


# any phase may end (a failure, Ctrl+C); counting follows warming follows the first frame
BENCH_MOVES: Transitions[BenchPhase] = Transitions("window bench", {
    BenchPhase.STARTING: {BenchPhase.WARMING, BenchPhase.DONE},
    BenchPhase.WARMING: {BenchPhase.COUNTING, BenchPhase.DONE},
    BenchPhase.COUNTING: {BenchPhase.DONE},
    BenchPhase.DONE: {BenchPhase.DONE},  # (a late failure or signal after the end: no news)
})


class _Timing(QObject):
    """Waits for the first frame drawn, warms up, counts; the event loop runs meanwhile."""

    def __init__(self, ctx: AppContext, window: MainWindow, request: WindowBench) -> None:
        super().__init__(window)
        self.ctx, self.window, self.request = ctx, window, request
        self.live = window.live_tab
        self.loop = QEventLoop(self)
        self.phase = BenchPhase.STARTING
        self.failure: StereoGuiError | None = None
        self.interrupted = False  # Ctrl+C or SIGTERM (the window is closed all the same)
        self.latencies_ms: list[float] = []
        self._start: tuple[float, float, int, int, int, float] | None = None
        self._end: tuple[float, float, int, int, int, float] | None = None
        window.sourceOpened.connect(self._source_opened)
        ctx.errorOccurred.connect(self._error)
        self.live.frameShown.connect(self._frame_shown)

    def run(self) -> WindowBenchResult:
        QTimer.singleShot(int(START_TIMEOUT_S * 1000), self, self._start_timed_out)
        with _signals_stop(self):
            self.loop.exec()
        if self.interrupted:
            raise KeyboardInterrupt
        if self.failure is not None:
            raise self.failure
        return self._result()

    # ---- the phases ------------------------------------------------------------------------
    def _move(self, to: BenchPhase) -> None:
        self.phase = BENCH_MOVES.check(self.phase, to)

    def _source_opened(self, _spec: str) -> None:
        """The source is in use: the Live tab shown, its views, the calibration it needs."""
        self.window.show_tab("live")
        self.live.set_visible_views(self.request.views)
        if self.ctx.calibration is None:
            if simulated_rig(self.ctx.frames.source()) is None:
                self._fail(f"no calibration for {self.request.source}: give --calib FILE")
                return
            self.live.use_true_calibration()  # as the Live tab's button does

    def _frame_shown(self, _out: LiveOutput) -> None:
        if self.phase is BenchPhase.STARTING:
            self._move(BenchPhase.WARMING)
            log.info("first frame drawn; warming up for %.1f s", self.request.warmup_s)
            _precisely_after(self.request.warmup_s, self, self._start_counting)
        elif self.phase is BenchPhase.COUNTING:
            self.latencies_ms.append(self.live.last_latency_ms)

    def _start_counting(self) -> None:
        if self.phase is not BenchPhase.WARMING:
            return
        self._move(BenchPhase.COUNTING)
        self._start = self._readings()
        _precisely_after(self.request.seconds, self, self._stop_counting)

    def _stop_counting(self) -> None:
        if self.phase is not BenchPhase.COUNTING:
            return
        self._end = self._readings()
        self._move(BenchPhase.DONE)
        self.loop.quit()

    def _readings(self) -> tuple[float, float, int, int, int, float]:
        """(wall s, process CPU s, frames shown, processed, read, the source's CPU s) now."""
        status = self.ctx.frames.status()
        return (time.monotonic(), time.process_time(), self.live.frames_shown,
                status.frames_processed, status.frames_read, status.source_cpu_s)

    # ---- what stops it ---------------------------------------------------------------------
    def _error(self, text: str) -> None:
        log.warning("the window said: %s", text)
        if self.phase is BenchPhase.STARTING and self.ctx.frames.source() is None:
            self._fail(text)  # the source could not be opened: no frame will come

    def _start_timed_out(self) -> None:
        if self.phase is BenchPhase.STARTING:
            said = "; ".join(self.window.error_bar.messages())
            self._fail(f"the window drew no frame within {START_TIMEOUT_S:.0f} s"
                       + (f" ({said})" if said else ""))

    def _fail(self, text: str) -> None:
        self.failure = StereoGuiError(f"bench --window: {text}")
        self._move(BenchPhase.DONE)
        self.loop.quit()

    def interrupt(self) -> None:
        self.interrupted = True
        self._move(BenchPhase.DONE)
        self.loop.quit()

    # ---- the result ------------------------------------------------------------------------
    def _result(self) -> WindowBenchResult:
        assert self._start is not None and self._end is not None  # (the loop ends counted)
        t0, cpu0, shown0, processed0, read0, source0 = self._start
        t1, cpu1, shown1, processed1, read1, source1 = self._end
        wall = max(t1 - t0, 1e-9)
        camera_fps = (read1 - read0) / wall
        latency = latency_stats(self.latencies_ms)
        cores = usable_cores()
        size = self.live.shown_frame.size if self.live.shown_frame is not None else (0, 0)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        return WindowBenchResult(
            shown_fps=(shown1 - shown0) / wall,
            processing_fps=(processed1 - processed0) / wall,
            camera_fps=camera_fps,
            cpu_percent=cpu_percent(cpu1 - cpu0, wall, cores),
            cores=cores,
            latency_median_ms=latency.median_ms,
            latency_p95_ms=latency.p95_ms,
            latency_intervals=intervals(latency.median_ms, camera_fps),
            latency_p95_intervals=intervals(latency.p95_ms, camera_fps),
            frames_shown=shown1 - shown0,
            frames_processed=processed1 - processed0,
            frames_read=read1 - read0,
            seconds=wall,
            warmup_s=self.request.warmup_s,
            source=self.request.source,
            size=size,
            preset=self.request.preset,
            views=tuple(self.live.visible_views()),
            window_px=(self.window.width(), self.window.height()),
            platform=QGuiApplication.platformName(),
            load_average=load,
            errors=tuple(self.window.error_bar.messages()),
            source_cpu_percent=cpu_percent(source1 - source0, wall, cores),
        )


def _precisely_after(seconds: float, owner: QObject, fn: Callable[[], None]) -> None:
    """Call `fn` once after `seconds` (a precise timer: a coarse one may end 5 % early)."""
    timer = QTimer(owner)
    timer.setSingleShot(True)
    timer.setTimerType(Qt.TimerType.PreciseTimer)
    timer.timeout.connect(fn)
    timer.start(int(round(seconds * 1000)))


@contextlib.contextmanager
def _signals_stop(timing: _Timing) -> Iterator[None]:
    """Ctrl+C and SIGTERM end the bench (the window is closed as usual: `app.on_signals`).
    Only in the main thread, where Python allows handlers."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    restore = on_signals(timing, timing.interrupt)
    try:
        yield
    finally:
        restore()
