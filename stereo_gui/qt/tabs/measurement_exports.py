"""The Measurements tab's exports: the log and its regression to .xlsx (in a worker: the
window stays usable, closing asks about an export still running) and the log to CSV.

`MeasurementExports` is owned by `measurements.MeasurementsTab` and is handed what it uses: the
log, the calibration, the fits to write, the xlsx button it disables while an export runs, and
the folder exports start in (`ExportFolder`, which the tab's other file dialogs share).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Generator
from pathlib import Path

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QPushButton, QWidget

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.jobs import JobControl, JobState, Progress
from stereo_gui.core.regression import FitResult
from stereo_gui.core.util import how_many
from stereo_gui.files import spreadsheet
from stereo_gui.qt.models.calibration import CalibrationModel, Reporter
from stereo_gui.qt.models.measurement_log import MeasurementLog
from stereo_gui.qt.models.settings import SettingsModel
from stereo_gui.qt.models.workers import WorkerRegistry
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.workers.job_worker import JobWorker


class ExportFolder:
    """The folder the Measurements tab's file dialogs start in: the one last exported to (or
    read from), kept in the settings."""

    def __init__(self, settings: SettingsModel) -> None:
        self._settings = settings

    def start(self) -> str:
        return self._settings.current.last_export_dir or str(Path.home())

    def remember(self, path: str | Path) -> None:
        """The next dialog starts in the folder of `path`."""
        self._settings.update(last_export_dir=str(Path(path).parent))


class MeasurementExports(QObject):
    """Export buttons' actions, and what closing would cut short (see module docstring)."""

    finished = Signal(str)  # path written by an xlsx export

    def __init__(self, log: MeasurementLog, calibration: CalibrationModel,
                 fits: Callable[[], list[FitResult]], folder: ExportFolder, report: Reporter,
                 workers: WorkerRegistry, xlsx_button: QPushButton, dialogs: QWidget) -> None:
        super().__init__(dialogs)
        self._log = log
        self._calibration = calibration
        self._fits = fits  # the fits to write beside the log, in the order of the sheets
        self._folder = folder
        self._report = report
        self._workers = workers
        self._xlsx_button = xlsx_button
        self._dialogs = dialogs  # the parent of the file dialogs
        self._export: JobWorker | None = None  # the xlsx export running
        self._export_path: Path | None = None
        self._export_progress = ""  # "12,000 of 20,000 rows"

    def choose_xlsx(self) -> None:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M")
        path, _ = folder_dialog.save_file_name(self._dialogs, "Export measurements",
                                              str(Path(self._folder.start())
                                                  / f"measurements-{stamp}.xlsx"),
                                              "Excel workbook (*.xlsx)")
        if path:
            if not path.lower().endswith(".xlsx"):
                path += ".xlsx"
            self.export_xlsx(path)

    def export_xlsx(self, path: str | Path) -> bool:
        """Write the log, the regression and the calibration to `path` in a worker."""
        if self._export is not None:
            self._report.report_error("an export is still running")
            return False
        records = list(self._log.records)
        fits = self._fits()
        calib, calib_path = self._calibration.calibration, self._calibration.path
        target = Path(path)

        def job(control: JobControl) -> Generator[Progress, None, Path]:
            yield Progress(0, 1, f"writing {target.name}")
            return spreadsheet.write_workbook(target, records, fits, calib, calib_path,
                                              cancel=control, progress=control.report)

        w = JobWorker(job, "export")
        w.finished_ok.connect(lambda p: self._export_done(str(p)))
        w.failed.connect(
            lambda msg: self._report.report_error(f"export to {target} failed: {msg}"))
        w.cancelled.connect(lambda: self._report.show_status(
            f"Export to {target} cancelled: nothing was written"))
        w.progress.connect(self._export_progressed)
        w.done.connect(self._export_ended)
        self._workers.register(w)
        self._export = w
        self._export_path = target
        self._export_progress = how_many(len(records), "row")
        self._xlsx_button.setEnabled(False)
        self._report.show_status(f"Exporting {how_many(len(records), 'reading')} to {target}…")
        w.start()
        self._folder.remember(target)
        return True

    def _export_progressed(self, p: Progress) -> None:
        if p.total > 1:
            self._export_progress = p.text

    def _export_done(self, path: str) -> None:
        self._report.show_status(f"Exported to {path}")
        self.finished.emit(path)

    def _export_ended(self) -> None:
        w, self._export = self._export, None
        self._export_path = None
        if w is not None:
            self._workers.unregister(w)
            w.wait(2000)
            w.deleteLater()
        self._xlsx_button.setEnabled(True)

    def choose_csv(self) -> None:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M")
        path, _ = folder_dialog.save_file_name(self._dialogs, "Export measurements as CSV",
                                              str(Path(self._folder.start())
                                                  / f"measurements-{stamp}.csv"),
                                              "CSV (*.csv)")
        if path:
            self.export_csv(path)

    def export_csv(self, path: str | Path) -> bool:
        try:
            spreadsheet.write_csv(path, list(self._log.records))
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not write {path}: {exc}")
            return False
        self._folder.remember(path)
        n = len(self._log.records)
        self._report.show_status(f"Exported {how_many(n, 'reading')} to {path}")
        return True

    def unfinished_work(self) -> list[str]:
        """What closing now would cut short: the xlsx export running, if any."""
        w = self._export
        if w is None or w.outcome is not None or not w.isRunning() or self._export_path is None:
            return []  # none, or settled (written, failed or cancelled) and only ending
        return [f"the export of the measurement log to {self._export_path.name} "
                f"({self._export_progress})"]

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        """Cancel the running export and wait for it at most `timeout_ms`; says what became of
        it ("" entries left out)."""
        w, path = self._export, self._export_path
        if w is None or path is None:
            return []
        w.cancel()
        if not w.wait(timeout_ms):
            return [f"The export to {path} was still being cancelled when the window closed: "
                    f"it is written whole or not at all."]
        if w.outcome is JobState.FINISHED:
            return [f"The export to {path} finished before it could be cancelled."]
        if w.outcome is JobState.CANCELLED:
            return [f"The export to {path} was cancelled: nothing was written"
                    + (f" ({path.name} was left as it was)." if path.exists() else ".")]
        return [f"The export to {path} failed."]

    def stop(self, timeout_ms: int = 2000) -> bool:
        """Stop a running export and join its thread (True when none is left running)."""
        if self._export is not None:
            return self._export.stop(timeout_ms)
        return True
