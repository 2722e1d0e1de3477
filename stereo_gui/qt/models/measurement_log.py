"""The measurement log: the readings taken, the undo of Clear, the active fit, kept on disk."""

from __future__ import annotations

import logging
from collections.abc import Iterable
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.regression import FitResult
from stereo_gui.files.measurement_log import KeptLog, load_log, save_log
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.qt.models.calibration import Reporter

log = logging.getLogger(__name__)

SAVE_DELAY_MS = 300  # changes to the log within this time are saved together


class MeasurementLog(QObject):
    """The readings, oldest first (`records`), the readings of the last Clear log until the next
    reading (`cleared`, brought back by `undo_clear`) and the fit live readings use instead of
    triangulation (`active_fit`, None for none).

    Changed only through its methods: `changed` announces a change of the readings,
    `activeFitChanged` one of the fit. With `keep(path)` all three are restored from `path` and
    saved there (atomically, a burst of changes once) whenever they change.
    """

    changed = Signal()
    activeFitChanged = Signal(object)  # FitResult | None (object: None is emitted too)

    def __init__(self, report: Reporter, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._report = report
        self._records: list[MeasurementRecord] = []
        self._snapshot: tuple[MeasurementRecord, ...] | None = None  # `records` until a change
        self._cleared: list[MeasurementRecord] = []
        self._active_fit: FitResult | None = None
        self._path: Path | None = None  # where the log is kept, None: nowhere
        self._save_timer = QTimer(self)
        self._save_timer.setSingleShot(True)
        self._save_timer.setInterval(SAVE_DELAY_MS)
        self._save_timer.timeout.connect(self.save)

    # ---- reading ------------------------------------------------------------------------------
    @property
    def records(self) -> tuple[MeasurementRecord, ...]:
        """The readings, oldest first (the same tuple until the log changes: a table may
        index it for every cell it paints)."""
        if self._snapshot is None:
            self._snapshot = tuple(self._records)
        return self._snapshot

    @property
    def cleared(self) -> tuple[MeasurementRecord, ...]:
        return tuple(self._cleared)

    @property
    def active_fit(self) -> FitResult | None:
        return self._active_fit

    @property
    def can_undo_clear(self) -> bool:
        return bool(self._cleared)

    @property
    def path(self) -> Path | None:
        """Where the log is kept (see `keep`), None when nowhere."""
        return self._path

    @property
    def save_pending(self) -> bool:
        """Whether a change waits to be written."""
        return self._save_timer.isActive()

    # ---- changes ------------------------------------------------------------------------------
    def add(self, record: MeasurementRecord) -> int:
        """Append a record; return its index. A Clear log can no longer be undone."""
        self._records.append(record)
        self._cleared = []
        self._changed()
        return len(self._records) - 1

    def add_many(self, records: Iterable[MeasurementRecord], replace: bool = False) -> None:
        """Append `records` (an imported log), or replace the log with them."""
        if replace:
            self._records = list(records)
        else:
            self._records.extend(records)
        self._changed()

    def update(self, index: int, record: MeasurementRecord) -> None:
        self._records[index] = record
        self._changed()

    def remove(self, index: int) -> None:
        del self._records[index]
        self._changed()

    def clear(self) -> None:
        """Empty the log; `undo_clear` brings the readings back until the next reading."""
        if self._records:
            self._cleared = list(self._records)
        self._records = []
        self._changed()

    def undo_clear(self) -> bool:
        """Put the readings of the last Clear log back in front of the log; False if none."""
        if not self._cleared:
            return False
        self._records = self._cleared + self._records
        self._cleared = []
        self._changed()
        return True

    def set_active_fit(self, fit: FitResult | None) -> None:
        """Make live readings use `fit` instead of triangulation; None to undo."""
        self._active_fit = fit
        self.activeFitChanged.emit(fit)
        self._schedule_save()

    # ---- kept between runs --------------------------------------------------------------------
    def keep(self, path: str | Path) -> list[str]:
        """Restore the log, the cleared readings and the active fit from `path` and save them
        there from now on; returns warnings about what could not be restored."""
        kept, warnings = load_log(path)
        self._path = None  # restoring is no change to save
        self._records = list(kept.records)
        self._cleared = list(kept.cleared)
        self._snapshot = None
        self.changed.emit()
        if kept.active_fit is not None:
            self.set_active_fit(kept.active_fit)
        self._path = Path(path)
        return warnings

    def save(self) -> bool:
        """Write the kept log now (no-op unless kept); False (reported) on failure."""
        self._save_timer.stop()
        if self._path is None:
            return True
        try:
            save_log(KeptLog(tuple(self._records), tuple(self._cleared), self._active_fit),
                     self._path)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"The measurement log could not be saved: {exc}")
            return False
        return True

    def _changed(self) -> None:
        self._snapshot = None
        self.changed.emit()
        self._schedule_save()

    def _schedule_save(self) -> None:
        if self._path is not None:
            self._save_timer.start()
