"""The application context: the single owner of app-wide state, shared by every tab.

Widgets get the context in their constructor, read its attributes and subscribe to its signals;
they change state only through its methods, so every change is announced exactly once.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.settings import Settings
from stereo_gui.qt.workers.frame_worker import FrameWorker
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.recorder import Recorder

log = logging.getLogger(__name__)

LOG_SAVE_DELAY_MS = 300  # changes to the measurement log within this time are saved together


# the note of the simulated rig's true calibration (the status bar and the Live tab show it)
TRUE_CALIBRATION_NOTE = "simulated rig's TRUE calibration"


class AppContext(QObject):
    """App-wide state: settings, calibration, measurement log, active fit, frame worker.

    `settings` is a frozen `stereo_gui.files.settings.Settings`; replace it with
    `update_settings(**changes)`. `measurements` is a list of
    `stereo_gui.files.spreadsheet.MeasurementRecord`, oldest first; `cleared_measurements`
    the readings of the last Clear log, until the next reading (`undo_clear` brings them back).
    With `keep_log(path)` the log, the cleared readings and the active fit are restored from
    `path` and saved there (atomically) whenever they change.
    """

    calibrationChanged = Signal(object)  # StereoCalibration | None
    measurementsChanged = Signal()
    activeFitChanged = Signal(object)  # FitResult | None
    settingsChanged = Signal(object)  # Settings
    statusMessage = Signal(str)
    errorOccurred = Signal(str)
    # the tab now shown: "capture", "calibration", "live" or "measurements". The shown tab owns
    # the frame worker's processor: a tab sets `frames.set_processor(...)` when it is shown
    # (tabs may also define `set_active(bool)`, which the main window calls).
    currentTabChanged = Signal(str)

    def __init__(self, settings=None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.settings = settings if settings is not None else Settings()
        self.calibration = None
        self.calibration_path: Path | None = None
        self.calibration_note = ""
        self.measurements: list = []
        self.cleared_measurements: list = []
        self.active_fit = None
        self.log_path: Path | None = None  # where the log is kept (keep_log), None: nowhere
        self._log_timer = QTimer(self)
        self._log_timer.setSingleShot(True)
        self._log_timer.setInterval(LOG_SAVE_DELAY_MS)
        self._log_timer.timeout.connect(self.save_log)
        self.source_fell_back_to_sim = False  # True when auto found no cameras
        self.current_tab = ""
        self.frames = FrameWorker(self)
        self.jobs = JobRunner("measure-jobs", self)  # occasional work off the UI thread
        self.recorder = Recorder(self.frames, self)  # records the raw frames the worker reads
        self._workers: list = []  # more workers (calibration, files) registered by tabs
        self.frames.errorOccurred.connect(self.report_error)

    # ---- state changes -----------------------------------------------------------------------
    def set_calibration(self, calib, path: str | Path | None = None, note: str = "",
                        remember: bool = True) -> None:
        """Use `calib` (or None) from now on; `path` is the file it came from, if any.

        `note` says where an unsaved calibration came from (e.g. TRUE_CALIBRATION_NOTE); the
        status bar shows it instead of a file name. Whether it is the simulated rig's true
        calibration is remembered for the next start (`Settings.sim_true_calibration`) unless
        `remember` is False (the start itself restoring the last one).
        """
        self.calibration = calib
        self.calibration_path = Path(path) if path is not None else None
        self.calibration_note = note
        true = calib is not None and note == TRUE_CALIBRATION_NOTE
        if remember and self.settings.sim_true_calibration != true:
            self.update_settings(sim_true_calibration=true)
        self.calibrationChanged.emit(calib)

    def open_calibration_file(self, path: str | Path) -> bool:
        """Load the calibration file `path` (ours, OpenCV's, ROS's or Middlebury's: see
        files.any_calibration), use it and remember it for the next start; False (after
        reporting why) when it cannot be read. A file without an image size takes the size of
        the frames shown."""
        from stereo_gui.files.any_calibration import load_any_calibration

        try:
            loaded = load_any_calibration(path, self.frame_size)
        except (StereoGuiError, OSError) as exc:
            self.report_error(f"Cannot load calibration {path}: {exc}")
            return False
        self._use_calibration_file(loaded.calibration, path)
        extra = "" if loaded.kind == "stereo-gui" else f" ({loaded.description})"
        self.show_status(f"Loaded calibration {path}{extra}")
        return True

    def frame_size(self) -> tuple[int, int]:
        """(width, height) px of the frames shown, or those the source was asked for."""
        latest = self.frames.latest()
        if latest is not None:
            return int(latest.frame.left.shape[1]), int(latest.frame.left.shape[0])
        return tuple(self.settings.resolution)

    def save_calibration_file(self, calib, path: str | Path) -> bool:
        """Write `calib` to `path`, use it from there and remember it for the next start; False
        (after reporting why) when it cannot be written."""
        from stereo_gui.files.calibration_file import save_calibration

        try:
            save_calibration(calib, path)
        except (StereoGuiError, OSError) as exc:
            self.report_error(f"Cannot save calibration {path}: {exc}")
            return False
        self._use_calibration_file(calib, path)
        self.show_status(f"Saved calibration {path}")
        return True

    def _use_calibration_file(self, calib, path: str | Path) -> None:
        self.set_calibration(calib, path)
        self.settings = self.settings.with_recent(str(path)).with_updates(
            last_calibration=str(Path(path).resolve()))
        self.settingsChanged.emit(self.settings)

    def add_measurement(self, record) -> int:
        """Append a record to the log; return its index. A Clear log can no longer be undone."""
        self.measurements.append(record)
        self.cleared_measurements = []
        self._log_changed()
        return len(self.measurements) - 1

    def add_measurements(self, records, replace: bool = False) -> None:
        """Append `records` (an imported log) to the log, or replace the log with them."""
        if replace:
            self.measurements = list(records)
        else:
            self.measurements.extend(records)
        self._log_changed()

    def update_measurement(self, index: int, record) -> None:
        self.measurements[index] = record
        self._log_changed()

    def remove_measurement(self, index: int) -> None:
        del self.measurements[index]
        self._log_changed()

    def clear_measurements(self) -> None:
        """Empty the log; `undo_clear` brings the readings back until the next reading."""
        if self.measurements:
            self.cleared_measurements = list(self.measurements)
        self.measurements = []
        self._log_changed()

    @property
    def can_undo_clear(self) -> bool:
        return bool(self.cleared_measurements)

    def undo_clear(self) -> bool:
        """Put the readings of the last Clear log back in front of the log; False if none."""
        if not self.cleared_measurements:
            return False
        self.measurements = self.cleared_measurements + self.measurements
        self.cleared_measurements = []
        self._log_changed()
        return True

    def set_active_fit(self, fit) -> None:
        """Make live readings use `fit` (a FitResult) instead of triangulation; None to undo."""
        self.active_fit = fit
        self.activeFitChanged.emit(fit)
        self._schedule_log_save()

    # ---- the log kept between runs -----------------------------------------------------------
    def keep_log(self, path: str | Path) -> list[str]:
        """Restore the log, the cleared readings and the active fit from `path` and save them
        there from now on; returns warnings about what could not be restored."""
        from stereo_gui.files.measurement_log import load_log

        kept, warnings = load_log(path)
        self.log_path = None  # restoring is no change to save
        self.measurements = list(kept.records)
        self.cleared_measurements = list(kept.cleared)
        self.measurementsChanged.emit()
        if kept.active_fit is not None:
            self.set_active_fit(kept.active_fit)
        self.log_path = Path(path)
        return warnings

    def _log_changed(self) -> None:
        self.measurementsChanged.emit()
        self._schedule_log_save()

    def _schedule_log_save(self) -> None:
        if self.log_path is not None:
            self._log_timer.start()  # a burst of changes is written once

    def save_log(self) -> bool:
        """Write the kept log now (no-op without `keep_log`); False (reported) on failure."""
        self._log_timer.stop()
        if self.log_path is None:
            return True
        from stereo_gui.files.measurement_log import KeptLog, save_log

        try:
            save_log(KeptLog(tuple(self.measurements), tuple(self.cleared_measurements),
                             self.active_fit), self.log_path)
        except (StereoGuiError, OSError) as exc:
            self.report_error(f"The measurement log could not be saved: {exc}")
            return False
        return True

    def update_settings(self, **changes) -> None:
        """Replace settings fields (unknown names raise TypeError, as dataclasses.replace does)."""
        self.settings = self.settings.with_updates(**changes)
        self.settingsChanged.emit(self.settings)

    def set_current_tab(self, name: str) -> None:
        """Called by the main window when the user switches tabs."""
        if name != self.current_tab:
            self.current_tab = name
            self.currentTabChanged.emit(name)

    def report_error(self, text: str) -> None:
        """Show `text` to the user (the main window listens) and log it."""
        log.warning("%s", text)
        self.errorOccurred.emit(str(text))

    def show_status(self, text: str) -> None:
        self.statusMessage.emit(str(text))

    # ---- workers -----------------------------------------------------------------------------
    def register_worker(self, worker) -> None:
        """Have `shutdown()` stop `worker` too (anything with `stop(timeout_ms=...)`)."""
        if worker not in self._workers:
            self._workers.append(worker)

    def unregister_worker(self, worker) -> None:
        if worker in self._workers:
            self._workers.remove(worker)

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Save the kept log if a change is pending, then stop and join every worker within
        `timeout_ms` in total; True if all ended.

        Every worker is asked to stop, each waiting only for what is left of the time: a
        blocked one never makes closing take longer than `timeout_ms` (it is left to end on
        its own; see workers/threads.py).
        """
        if self._log_timer.isActive():
            self.save_log()
        ok = True
        deadline = time.monotonic() + timeout_ms / 1000.0
        for w in [self.recorder, self.frames, self.jobs, *self._workers]:
            left_ms = max(1, int((deadline - time.monotonic()) * 1000))
            try:
                ok = bool(_stop(w, left_ms)) and ok
            except Exception:  # noqa: BLE001 - one broken worker must not keep others running
                log.warning("stopping %r failed", w, exc_info=True)
                ok = False
        return ok


def _stop(worker, timeout_ms: int):
    try:
        return worker.stop(timeout_ms=timeout_ms)
    except TypeError:
        result = worker.stop()
        return True if result is None else result
