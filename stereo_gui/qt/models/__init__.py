"""The application's state as small evented models, Qt-aware but free of widgets.

Each model owns one piece of state, changes it only through its own methods and announces every
change by its own signals; widgets are handed the models (through `qt.context.AppContext`) and
connect to those signals. None of them draws anything, so they run and are tested without a
window.
"""

from stereo_gui.qt.models.calibration import TRUE_CALIBRATION_NOTE, CalibrationModel, Reporter
from stereo_gui.qt.models.measurement_log import MeasurementLog
from stereo_gui.qt.models.settings import SettingsModel
from stereo_gui.qt.models.workers import StoppableWorker, WorkerRegistry

__all__ = ["TRUE_CALIBRATION_NOTE", "CalibrationModel", "MeasurementLog", "Reporter",
           "SettingsModel", "StoppableWorker", "WorkerRegistry"]
