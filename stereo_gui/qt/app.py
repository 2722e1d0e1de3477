"""The application shell: QApplication, settings, start-up calibration and source, auto-quit.

`STEREO_GUI_QUIT_AFTER=SECONDS` in the environment makes the application close its window and
exit with status 0 after that many seconds (smoke tests of installed or bundled builds).
"""

from __future__ import annotations

import gc
import logging
import os
import signal
import sys
from collections.abc import Callable
from types import FrameType, TracebackType

import pyqtgraph as pg
from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QApplication

from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.measurement_log import default_log_path
from stereo_gui.files.settings import load_settings
from stereo_gui.pipeline.concurrency import use_opencv_threads_beside_lanes
from stereo_gui.qt.context import AppContext
from stereo_gui.qt.dialogs.about import application_icon
from stereo_gui.qt.dialogs.source_dialog import SourceChoice
from stereo_gui.qt.main_window import MainWindow
from stereo_gui.sources.open import expected_frame_size, parse_source_spec

log = logging.getLogger(__name__)

QUIT_AFTER_ENV = "STEREO_GUI_QUIT_AFTER"
QUIT_AFTER_MAX_S = 86_400  # a day: the switch is for smoke tests of a build


def quit_after_seconds() -> float | None:
    """The auto-quit delay from the environment, seconds (None when unset); InputError if bad."""
    raw = os.environ.get(QUIT_AFTER_ENV, "").strip()
    if not raw:
        return None
    try:
        value = float(raw)
    except ValueError:
        raise InputError(f"{QUIT_AFTER_ENV} must be a number of seconds, not {raw!r}") from None
    if not 0 <= value <= QUIT_AFTER_MAX_S:  # Qt's timers take at most 2**31 - 1 ms
        raise InputError(f"{QUIT_AFTER_ENV} must be from 0 to {QUIT_AFTER_MAX_S} seconds, "
                         f"not {raw!r}")
    return value


def freeze_startup_objects() -> int:
    """Move every object alive now (modules, Qt wrappers, the window's widgets) out of the
    garbage collector's reach; return how many. They live until the process ends, yet every
    full collection would walk them all again, a pause on the UI thread each time while live.
    Objects made later are collected as usual."""
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def free_garbage_on_ui_thread() -> int:
    """Collect the garbage there is now (a closed window's widgets, in reference cycles) on the
    UI thread, before a window is built; return how many objects were freed. Left to the
    automatic collection, it may run in a worker thread: a Qt object freed there is destroyed
    there, its destructor holding Qt's connection lock while it waits for the GIL, which the UI
    thread holds while it waits for that lock to connect the new window's signals. Both then wait
    for ever (seen when the calibration-health worker's allocation collected the first window's
    widgets while a second one was built).

    Collection stays automatic otherwise: collecting only on a UI timer (pyqtgraph's
    GarbageCollector) cost the live window a tenth of its frames (`bench --window 15`, three
    alternating pairs: 20.3-25.3 against 22.1-29.3 fps)."""
    return gc.collect()


def check_source_spec(spec: str) -> None:
    """Raise InputError for a --source value that names no source (nothing is opened)."""
    parse_source_spec(spec)


def configure_pyqtgraph() -> None:
    """Row-major images (numpy's own order) and no antialiasing cost on live images."""
    pg.setConfigOptions(imageAxisOrder="row-major", antialias=False,
                        background="#202020", foreground="#dddddd")


def _install_excepthook(ctx: AppContext) -> None:
    """An unexpected exception in a slot becomes a message in the window, not a lost traceback."""
    previous = sys.excepthook

    def hook(exc_type: type[BaseException], exc: BaseException,
             tb: TracebackType | None) -> None:
        if issubclass(exc_type, KeyboardInterrupt):
            previous(exc_type, exc, tb)
            return
        log.error("unexpected error", exc_info=(exc_type, exc, tb))
        try:
            ctx.report_error(f"Unexpected error: {exc_type.__name__}: {exc}")
        except RuntimeError:  # the context is already deleted at exit
            pass

    sys.excepthook = hook


def build_window(source: str | None = None, calib: str | None = None
                 ) -> tuple[AppContext, MainWindow]:
    """Create the context and main window, load the calibration and open the source.

    Explicit arguments that cannot be used raise StereoGuiError (the command line turns that into
    one line and exit 2); a remembered calibration or source that fails is reported in the window.
    Returns (ctx, window). A QApplication must exist.
    """
    configure_pyqtgraph()
    free_garbage_on_ui_thread()
    settings, warnings = load_settings()
    ctx = AppContext(settings)
    w, h = settings.resolution
    size = (w, h)
    if source:
        check_source_spec(source)  # a bad --source is a user mistake: exit 2 before the window
    spec = source or settings.source or "auto"

    def frame_size() -> tuple[int, int] | None:  # for a file without an image size (OpenCV's sample writes none)
        return expected_frame_size(spec, size)

    loaded, calib_error = None, ""
    if calib:
        loaded = load_any_calibration(calib, frame_size)  # raises for a bad --calib
    elif settings.last_calibration:
        try:
            loaded = load_any_calibration(settings.last_calibration, frame_size)
        except Exception as exc:  # noqa: BLE001 - a remembered file never blocks the start
            calib_error = f"The last calibration could not be loaded: {exc}"
            log.warning("%s", calib_error, exc_info=not isinstance(exc, StereoGuiError))

    window = MainWindow(ctx)
    _install_excepthook(ctx)
    if loaded is not None and loaded.path is not None:
        ctx.calibration_model.set(loaded.calibration, loaded.path.resolve(), remember=False)
        ctx.settings_model.update(last_calibration=str(loaded.path.resolve()))
    elif loaded is not None:  # rectified:F,B[,DOFFS] is remembered as written
        ctx.calibration_model.set(loaded.calibration, None, note=loaded.description,
                                  remember=False)
        ctx.settings_model.update(last_calibration=calib or settings.last_calibration)
    # opening takes seconds (devices, the simulated rig's ray maps): done off the UI thread
    window.open_source(SourceChoice(spec, size, settings.swap_lr), fallback_to_auto=not source)
    # the log, the readings of the last Clear log and the active fit of the last run
    warnings = [*warnings, *ctx.measurement_log.keep(default_log_path())]
    problems = [w for w in warnings] + ([calib_error] if calib_error else [])
    for text in problems:  # each kept in the error bar's list, beside what the tabs reported
        window.show_error(text)
    return ctx, window


SIGNAL_POLL_MS = 200  # how often Python gets to run a signal's handler while Qt waits


def on_signals(owner: QObject, fn: Callable[[], object]) -> Callable[[], None]:
    """Ctrl+C in the terminal (SIGINT) and SIGTERM call `fn` in Qt's event loop. (Python runs a
    signal's handler only between its own instructions, so a timer of `owner`'s gives it a
    moment now and then while Qt's loop waits.) Returns what puts the handlers before back."""
    def handle(signum: int, _frame: FrameType | None) -> None:
        log.info("signal %d", signum)
        QTimer.singleShot(0, owner, fn)

    before = {s: signal.signal(s, handle) for s in (signal.SIGINT, signal.SIGTERM)}
    poll = QTimer(owner)
    poll.setInterval(SIGNAL_POLL_MS)
    poll.timeout.connect(lambda: None)
    poll.start()

    def restore() -> None:
        poll.stop()
        for s, handler in before.items():
            signal.signal(s, handler)

    return restore


def close_on_signals(window: MainWindow) -> Callable[[], None]:
    """Ctrl+C and SIGTERM close the window as Ctrl+Q does: the log saved, a recording closed,
    the workers stopped (`on_signals`). Returns what puts the handlers before back."""
    return on_signals(window, window.close)


def run_app(source: str | None = None, calib: str | None = None) -> int:
    """Run the GUI until its window closes; return the exit status."""
    use_opencv_threads_beside_lanes()  # our threads (the frame lanes first) share the cores
    quit_after = quit_after_seconds()
    existing = QApplication.instance()
    app = existing if isinstance(existing, QApplication) else QApplication(sys.argv[:1])
    app.setApplicationName("Stereo GUI")
    app.setOrganizationName("stereo-gui")
    app.setDesktopFileName("stereo-gui")  # matches resources/stereo-gui.desktop
    app.setWindowIcon(application_icon())
    ctx, window = build_window(source, calib)
    window.show()
    log.debug("%d start-up objects frozen for the garbage collector", freeze_startup_objects())
    if quit_after is not None:
        log.info("quitting after %.1f s (%s)", quit_after, QUIT_AFTER_ENV)
        QTimer.singleShot(int(quit_after * 1000), window.close)
    restore_signals = close_on_signals(window)
    try:
        status = int(app.exec())
    finally:
        restore_signals()
    # the window normally stopped every worker already; make sure nothing outlives exec
    if not ctx.shutdown(2000):
        # a thread is stuck in a device or OpenCV call that cannot be interrupted; letting the
        # interpreter tear down around it can abort the process, so leave at once (settings
        # were saved when the window closed)
        log.warning("a worker is still busy at exit; leaving without waiting for it")
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status
