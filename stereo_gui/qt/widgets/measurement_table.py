"""The measurement log as a Qt table model over `ctx.measurement_log` (MeasurementRecord); the
true-distance column is editable and makes a reading a regression sample, the note column says
what was measured."""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable
from dataclasses import replace
from typing import TYPE_CHECKING

from PySide6.QtCore import QAbstractTableModel, QModelIndex, QObject, QPersistentModelIndex, Qt
from PySide6.QtGui import QBrush, QColor

from stereo_gui.core.stereo_calibration import StereoCalibration, triangulate
from stereo_gui.files.measurement_record import RULER_METHOD, MeasurementRecord, record_error

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext


ModelIndex = QModelIndex | QPersistentModelIndex


def _num(v: float | None, digits: int = 1) -> str:
    if v is None:
        return ""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return f"{f:.{digits}f}" if math.isfinite(f) else "—"


def _short_time(iso: str) -> str:
    try:
        t = _dt.datetime.fromisoformat(iso)
    except (TypeError, ValueError):
        return iso
    return t.astimezone().strftime("%H:%M:%S") if t.tzinfo else t.strftime("%H:%M:%S")


def _is_ruler(r: MeasurementRecord) -> bool:
    return r.method.startswith(RULER_METHOD)


def _xyz(v: float, r: MeasurementRecord) -> str:
    """X, Y or Z of a reading; of a ruler distance they are the components of B - A."""
    return f"Δ {_num(v)}" if _is_ruler(r) else _num(v)


# (header, how to show a record, tooltip); the true distance sits next to what it is compared with
COLUMNS = (
    ("Time", lambda r: _short_time(r.time), "time of the reading"),
    ("x, y (px)", lambda r: f"{_num(r.x_px, 0)}, {_num(r.y_px, 0)}",
     "pixel of the rectified left image"),
    ("Disparity (px)", lambda r: _num(r.disparity_px, 3), "median disparity of the patch"),
    ("True distance (mm)", lambda r: _num(r.true_mm) if r.true_mm is not None else "",
     "double-click to enter the measured true distance: it makes the reading a regression sample"),
    ("Note", lambda r: r.note, "double-click to say what was measured (kept and exported)"),
    ("Z (mm)", lambda r: _xyz(r.Z_mm, r), "depth along the optical axis (Δ: a ruler's B − A)"),
    ("Error (mm)", lambda r: _num(record_error(r)[0]),
     "Z − true distance, mm (empty until a true distance is entered)"),
    ("Error (%)", lambda r: _num(record_error(r)[1], 2),
     "(Z − true distance) / true distance, %"),
    ("Range (mm)", lambda r: _num(r.range_mm),
     "distance from the left camera; of a ruler distance, the length A–B"),
    ("± (mm)", lambda r: _num(r.expected_error_mm),
     "95 % bound of the depth error: the true distance lies within Z ± this in 19 of 20 "
     "readings"),
    ("Valid", lambda r: "yes" if r.valid else f"no: {r.reason}" if r.reason else "no",
     "whether the reading is usable, and why not"),
    ("X (mm)", lambda r: _xyz(r.X_mm, r), "left rectified camera frame"),
    ("Y (mm)", lambda r: _xyz(r.Y_mm, r), "left rectified camera frame"),
    ("Method", lambda r: r.method, "triangulation or the fit used"),
)
TRUE_COL = 3
NOTE_COL = 4
VALID_COL = 10
_LEFT_ALIGNED = (0, NOTE_COL, VALID_COL, len(COLUMNS) - 1)
NOTE_MAX_CHARS = 500  # a note is a few words; longer text is cut there


class MeasurementModel(QAbstractTableModel):
    """A table over ctx.measurement_log.records; the true-distance column is editable."""

    def __init__(self, ctx: AppContext, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._rows = len(ctx.measurement_log.records)
        ctx.measurement_log.changed.connect(self._reset)

    def _reset(self) -> None:
        n = len(self.ctx.measurement_log.records)
        if n == self._rows:
            # a reading changed (a true distance was entered): a reset would destroy the cell
            # editor committing it and lose the current cell, so Down no longer led to the next
            if n:
                self.dataChanged.emit(self.index(0, 0), self.index(n - 1, len(COLUMNS) - 1))
            return
        self.beginResetModel()
        self._rows = n
        self.endResetModel()

    def rowCount(self, parent: ModelIndex = QModelIndex()) -> int:  # noqa: N802 - Qt API
        return 0 if parent.isValid() else len(self.ctx.measurement_log.records)

    def columnCount(self, parent: ModelIndex = QModelIndex()) -> int:  # noqa: N802 - Qt API
        return 0 if parent.isValid() else len(COLUMNS)

    def headerData(self, section: int, orientation: Qt.Orientation,  # noqa: N802
                   role: int = Qt.ItemDataRole.DisplayRole) -> object:
        if orientation == Qt.Orientation.Horizontal:
            if role == Qt.ItemDataRole.DisplayRole:
                return COLUMNS[section][0]
            if role == Qt.ItemDataRole.ToolTipRole:
                return COLUMNS[section][2]
        elif role == Qt.ItemDataRole.DisplayRole:
            return str(section + 1)
        return None

    def data(self, index: ModelIndex, role: int = Qt.ItemDataRole.DisplayRole) -> object:
        if not index.isValid():
            return None
        rec = self.ctx.measurement_log.records[index.row()]
        col = index.column()
        if role == Qt.ItemDataRole.DisplayRole:
            return COLUMNS[col][1](rec)
        if role == Qt.ItemDataRole.EditRole and col == TRUE_COL:
            return "" if rec.true_mm is None else f"{rec.true_mm:g}"
        if role == Qt.ItemDataRole.EditRole and col == NOTE_COL:
            return rec.note
        if role == Qt.ItemDataRole.ToolTipRole and col == NOTE_COL and rec.note:
            return rec.note
        if role == Qt.ItemDataRole.ForegroundRole and not rec.valid:
            return QBrush(QColor("#a93226"))
        if role == Qt.ItemDataRole.BackgroundRole and col == TRUE_COL:
            return QBrush(QColor("#fdf6d8"))
        if role == Qt.ItemDataRole.TextAlignmentRole and col not in _LEFT_ALIGNED:
            return int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if role == Qt.ItemDataRole.ToolTipRole and col == VALID_COL and not rec.valid:
            return rec.reason
        return None

    def flags(self, index: ModelIndex) -> Qt.ItemFlag:
        f = super().flags(index)
        if index.isValid() and index.column() in (TRUE_COL, NOTE_COL):
            f |= Qt.ItemFlag.ItemIsEditable
        return f

    def setData(self, index: ModelIndex, value: object,  # noqa: N802
                role: int = Qt.ItemDataRole.EditRole) -> bool:
        if role != Qt.ItemDataRole.EditRole or index.column() not in (TRUE_COL, NOTE_COL):
            return False
        if index.column() == NOTE_COL:
            # one line of text: a line break or tab would split the row of a CSV export reader
            note = " ".join(str(value or "").split())[:NOTE_MAX_CHARS]
            rec = self.ctx.measurement_log.records[index.row()]
            if note != rec.note:
                self.ctx.measurement_log.update(index.row(), replace(rec, note=note))
            return True
        text = str(value).strip().replace(",", ".")
        if text == "":
            true_mm = None
        else:
            try:
                true_mm = float(text)
            except ValueError:
                self.ctx.report_error(f"true distance {value!r} is not a number of millimetres")
                return False
            if not math.isfinite(true_mm) or true_mm <= 0:
                self.ctx.report_error(f"true distance must be a positive number of mm, not {value}")
                return False
        rec = self.ctx.measurement_log.records[index.row()]
        self.ctx.measurement_log.update(index.row(), replace(rec, true_mm=true_mm))
        return True


def samples_from(records: Iterable[MeasurementRecord]) -> list[tuple[float, float]]:
    """(disparity px, true distance mm) of the valid readings that have a true distance."""
    out = []
    for r in records:
        if r.true_mm is not None and r.valid and math.isfinite(r.disparity_px):
            out.append((float(r.disparity_px), float(r.true_mm)))
    return out


def triangulation_errors_mm(records: Iterable[MeasurementRecord],
                            calibration: StereoCalibration | None = None) -> list[float]:
    """Z - true distance (mm) of triangulation for the valid readings with a true distance: the
    logged Z where triangulation made it, else triangulated again through `calibration` (a
    metric StereoCalibration) from the logged pixel and disparity; readings that cannot be
    triangulated are left out."""
    out = []
    for r in records:
        if r.true_mm is None or not r.valid or not math.isfinite(r.disparity_px):
            continue
        if r.method == "triangulation":
            z = r.Z_mm
        elif calibration is not None and calibration.metric:
            xyz = triangulate(calibration, r.x_px, r.y_px, r.disparity_px)
            z = float("nan") if xyz is None else xyz[2]
        else:
            continue
        if math.isfinite(z):
            out.append(float(z) - float(r.true_mm))
    return out
