"""The Calibration tab's warnings: what the calibration found doubtful, each with the remedy the
window offers in one click (Fix k3 and recalibrate, Swap the cameras and recalibrate)."""

from __future__ import annotations

from collections.abc import Sequence

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QGroupBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from stereo_gui.core.uncertainty import CalibrationWarning

ACTIONS = {"fix_k3": "Fix k3 and recalibrate", "swap": "Swap the cameras and recalibrate"}


class CalibrationWarnings(QGroupBox):
    """One row per core.uncertainty.CalibrationWarning; `actionRequested(proposal)` when the
    technician clicks a remedy ("fix_k3" or "swap")."""

    actionRequested = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Warnings", parent)
        self._layout = QVBoxLayout(self)
        self.buttons: dict[str, QPushButton] = {}
        self.labels: list[QLabel] = []
        self.setVisible(False)

    def show_warnings(self, warnings: Sequence[CalibrationWarning]) -> None:
        for i in reversed(range(self._layout.count())):
            item = self._layout.takeAt(i)
            w = item.widget() if item is not None else None
            lay = item.layout() if item is not None else None
            if w is not None:
                w.deleteLater()
            elif lay is not None:
                while lay.count():
                    taken = lay.takeAt(0)
                    sub = taken.widget() if taken is not None else None
                    if sub is not None:
                        sub.deleteLater()
        self.buttons = {}
        self.labels = []
        for warning in warnings:
            row = QHBoxLayout()
            lab = QLabel(warning.message)
            lab.setWordWrap(True)
            colour = "#b03a2e" if warning.code == "swapped" else "#9a5b00"
            lab.setStyleSheet(f"color: {colour}")
            lab.setToolTip(f"warning code: {warning.code}")
            row.addWidget(lab, 1)
            self.labels.append(lab)
            if warning.proposal in ACTIONS and warning.proposal not in self.buttons:
                b = QPushButton(ACTIONS[warning.proposal])
                b.clicked.connect(lambda _=False, p=warning.proposal: self.actionRequested.emit(p))
                row.addWidget(b)
                self.buttons[warning.proposal] = b
            self._layout.addLayout(row)
        self.setVisible(bool(warnings))

    def texts(self) -> list[str]:
        return [lab.text() for lab in self.labels]
