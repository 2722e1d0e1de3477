"""The Calibration tab's warnings: what the calibration found doubtful, each with the remedy the
window offers in one click (Fix k3 and recalibrate, Swap the cameras and recalibrate)."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QGroupBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

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

    def show_warnings(self, warnings) -> None:
        for i in reversed(range(self._layout.count())):
            item = self._layout.takeAt(i)
            w = item.widget() if item is not None else None
            if w is not None:
                w.deleteLater()
            elif item is not None and item.layout() is not None:
                lay = item.layout()
                while lay.count():
                    sub = lay.takeAt(0).widget()
                    if sub is not None:
                        sub.deleteLater()
        self.buttons = {}
        self.labels = []
        for w in warnings:
            row = QHBoxLayout()
            lab = QLabel(w.message)
            lab.setWordWrap(True)
            colour = "#b03a2e" if w.code == "swapped" else "#9a5b00"
            lab.setStyleSheet(f"color: {colour}")
            lab.setToolTip(f"warning code: {w.code}")
            row.addWidget(lab, 1)
            self.labels.append(lab)
            if w.proposal in ACTIONS and w.proposal not in self.buttons:
                b = QPushButton(ACTIONS[w.proposal])
                b.clicked.connect(lambda _=False, p=w.proposal: self.actionRequested.emit(p))
                row.addWidget(b)
                self.buttons[w.proposal] = b
            self._layout.addLayout(row)
        self.setVisible(bool(warnings))

    def texts(self) -> list[str]:
        return [lab.text() for lab in self.labels]
