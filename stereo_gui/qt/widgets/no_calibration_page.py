"""The page the Live tab shows instead of its views while there is no calibration."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget


class NoCalibrationPage(QWidget):
    """Shown instead of the views while there is no calibration."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        title = QLabel("<h2>No calibration loaded</h2>")
        text = QLabel("The live depth view needs a calibration of the stereo camera. "
                      "Calibrate it from chessboard pairs, or load a calibration file.")
        text.setWordWrap(True)
        self.calibrate = QPushButton("Calibrate…")
        self.load = QPushButton("Load a calibration file…")
        self.use_true = QPushButton("Use the simulated rig's true calibration")
        self.use_true.setToolTip("Only for the simulated rig: the calibration it was built with. "
                                 "It is labelled as such in the status bar.")
        col = QVBoxLayout(self)
        col.addStretch(1)
        for w in (title, text):
            w.setAlignment(Qt.AlignmentFlag.AlignCenter)
            col.addWidget(w)
        row = QHBoxLayout()
        row.addStretch(1)
        for b in (self.calibrate, self.load, self.use_true):
            row.addWidget(b)
        row.addStretch(1)
        col.addLayout(row)
        col.addStretch(2)
