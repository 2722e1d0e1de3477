"""The application context: one typed object that holds the models every tab is handed.

The state lives in small models (`stereo_gui.qt.models`), each changed only through its own
methods and announcing its changes by its own signals:

- `settings_model`: the frozen `Settings`, replaced by `update`, saved by `save`;
- `calibration_model`: the calibration in use, its file or note, and calibration files;
- `measurement_log`: the readings, the undo of Clear, the active fit, kept on disk;
- `workers`: the frame worker, the job thread, the recorder and every registered worker.

The context itself is the error bus (`report_error`, `show_status`; the main window shows what
they announce) and offers read-only shortcuts to what widgets read most (`settings`,
`calibration`, `active_fit`, `frames`, ...). Nothing is assigned from outside.
"""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.settings import Settings
from stereo_gui.qt.models import (
    TRUE_CALIBRATION_NOTE,
    CalibrationModel,
    MeasurementLog,
    SettingsModel,
    StoppableWorker,
    WorkerRegistry,
)
from stereo_gui.qt.workers.frame_worker import FrameWorker
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.qt.workers.recorder import Recorder

log = logging.getLogger(__name__)

__all__ = ["TRUE_CALIBRATION_NOTE", "AppContext"]


class AppContext(QObject):
    """The models of one application window, and the bus its errors and status lines take."""

    errorOccurred = Signal(str)
    statusMessage = Signal(str)

    def __init__(self, settings: Settings | None = None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.settings_model = SettingsModel(settings, self)
        self.workers = WorkerRegistry(self)
        self.calibration_model = CalibrationModel(self.settings_model, self, self.frame_size,
                                                  self)
        self.measurement_log = MeasurementLog(self, self)
        self.workers.frames.errorOccurred.connect(self.report_error)

    # ---- the error bus -----------------------------------------------------------------------
    def report_error(self, text: str) -> None:
        """Show `text` to the user (the main window listens) and log it."""
        log.warning("%s", text)
        self.errorOccurred.emit(str(text))

    def show_status(self, text: str) -> None:
        """Show `text` in the status bar for a while."""
        self.statusMessage.emit(str(text))

    # ---- read-only shortcuts -----------------------------------------------------------------
    @property
    def settings(self) -> Settings:
        """The settings now (`settings_model.current`)."""
        return self.settings_model.current

    @property
    def calibration(self) -> StereoCalibration | None:
        return self.calibration_model.calibration

    @property
    def calibration_path(self) -> Path | None:
        return self.calibration_model.path

    @property
    def calibration_note(self) -> str:
        return self.calibration_model.note

    @property
    def active_fit(self) -> FitResult | None:
        return self.measurement_log.active_fit

    @property
    def frames(self) -> FrameWorker:
        return self.workers.frames

    @property
    def jobs(self) -> JobRunner:
        """The job thread for occasional work off the UI thread (readings, small files)."""
        return self.workers.jobs

    @property
    def recorder(self) -> Recorder:
        """Records the raw frames the frame worker reads."""
        return self.workers.recorder

    def frame_size(self) -> tuple[int, int]:
        """(width, height) px of the frames shown, or those the source was asked for."""
        latest = self.frames.latest()
        if latest is not None:
            return int(latest.frame.left.shape[1]), int(latest.frame.left.shape[0])
        w, h = self.settings.resolution
        return w, h

    # ---- one-line forwards to the models -----------------------------------------------------
    def update_settings(self, **changes: object) -> None:
        """`settings_model.update(**changes)`."""
        self.settings_model.update(**changes)

    def add_measurement(self, record: MeasurementRecord) -> int:
        """`measurement_log.add(record)`."""
        return self.measurement_log.add(record)

    def register_worker(self, worker: StoppableWorker) -> None:
        """`workers.register(worker)`: `shutdown()` stops it too."""
        self.workers.register(worker)

    def unregister_worker(self, worker: StoppableWorker) -> None:
        self.workers.unregister(worker)

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Save the kept log if a change is pending, then stop and join every worker within
        `timeout_ms` in total; True if all ended."""
        if self.measurement_log.save_pending:
            self.measurement_log.save()
        return self.workers.shutdown(timeout_ms)
