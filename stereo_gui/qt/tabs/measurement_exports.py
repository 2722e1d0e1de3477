"""The Measurements tab's exports: the log and its regression to .xlsx (in a worker: the
window stays usable, closing asks about an export still running) and the log to CSV.

A mixin of `measurements.MeasurementsTab`, which owns the state used here (`fits`, the xlsx
button, the `exportFinished` signal, the folder last used)."""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.jobs import JobState, Progress
from stereo_gui.core.util import how_many
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.widgets.regression_plot import MODELS
from stereo_gui.qt.workers.job_worker import JobWorker


class MeasurementExports:
    """Export buttons' actions, and what closing would cut short (see module docstring)."""

    def _choose_xlsx(self) -> None:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M")
        path, _ = folder_dialog.save_file_name(self, "Export measurements",
                                              str(Path(self._start_dir())
                                                  / f"measurements-{stamp}.xlsx"),
                                              "Excel workbook (*.xlsx)")
        if path:
            if not path.lower().endswith(".xlsx"):
                path += ".xlsx"
            self.export_xlsx(path)

    def export_xlsx(self, path) -> bool:
        """Write the log, the regression and the calibration to `path` in a worker."""
        if self._export is not None:
            self.ctx.report_error("an export is still running")
            return False
        from stereo_gui.files.spreadsheet import write_workbook

        records = list(self.ctx.measurement_log.records)
        fits = [self.fits[m] for m in MODELS if m in self.fits]
        calib, calib_path = self.ctx.calibration, self.ctx.calibration_path
        path = Path(path)

        def job(control):
            yield Progress(0, 1, f"writing {path.name}")
            return write_workbook(path, records, fits, calib, calib_path, cancel=control,
                                  progress=control.report)

        w = JobWorker(job, "export")
        w.finished_ok.connect(lambda p: self._export_done(str(p)))
        w.failed.connect(lambda msg: self.ctx.report_error(f"export to {path} failed: {msg}"))
        w.cancelled.connect(lambda: self.ctx.show_status(
            f"Export to {path} cancelled: nothing was written"))
        w.progress.connect(self._export_progressed)
        w.done.connect(self._export_ended)
        self.ctx.workers.register(w)
        self._export = w
        self._export_path = path
        self._export_progress = how_many(len(records), "row")
        self.xlsx_button.setEnabled(False)
        self.ctx.show_status(f"Exporting {how_many(len(records), 'reading')} to {path}…")
        w.start()
        self._remember_dir(path)
        return True

    def _export_progressed(self, p: Progress) -> None:
        if p.total > 1:
            self._export_progress = p.text

    def _export_done(self, path: str) -> None:
        self.ctx.show_status(f"Exported to {path}")
        self.exportFinished.emit(path)

    def _export_ended(self) -> None:
        w, self._export = self._export, None
        self._export_path = None
        if w is not None:
            self.ctx.workers.unregister(w)
            w.wait(2000)
            w.deleteLater()
        self.xlsx_button.setEnabled(True)

    def _choose_csv(self) -> None:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M")
        path, _ = folder_dialog.save_file_name(self, "Export measurements as CSV",
                                              str(Path(self._start_dir())
                                                  / f"measurements-{stamp}.csv"),
                                              "CSV (*.csv)")
        if path:
            self.export_csv(path)

    def export_csv(self, path) -> bool:
        from stereo_gui.files.spreadsheet import write_csv

        try:
            write_csv(path, list(self.ctx.measurement_log.records))
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not write {path}: {exc}")
            return False
        self._remember_dir(path)
        n = len(self.ctx.measurement_log.records)
        self.ctx.show_status(f"Exported {how_many(n, 'reading')} to {path}")
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
