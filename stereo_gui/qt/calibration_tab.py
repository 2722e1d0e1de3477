"""The Calibration tab of the main window (being built; see issue 4)."""

from __future__ import annotations

from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget


class CalibrationTab(QWidget):
    """The calibration tab. `ctx` is the application's AppContext (the owner of app-wide state)."""

    def __init__(self, ctx, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        layout = QVBoxLayout(self)
        layout.addWidget(QLabel("Calibration: not built yet"))
