"""The Capture tab's board row: the chessboard's inner corners and square size, and the switch
for automatic capture."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QDoubleSpinBox, QHBoxLayout, QLabel, QSpinBox, QWidget

from stereo_gui.core.board import BoardSpec
from stereo_gui.qt.widgets.flow_layout import FlowLayout


class BoardRow(QWidget):
    """Board columns x rows (inner corners), square size (mm), automatic capture.

    `edited()` follows a change of the board by the user (not by `show_board`); the automatic
    capture check box is `auto_check`. `auto_tooltip` explains what automatic capture waits for.
    """

    edited = Signal()

    def __init__(self, auto_tooltip: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        # three groups that wrap onto a second row on a narrow window (a laptop screen)
        board = FlowLayout(self, spacing=18)
        self.cols_spin = QSpinBox()
        self.cols_spin.setRange(2, 40)
        self.rows_spin = QSpinBox()
        self.rows_spin.setRange(2, 40)
        self.square_spin = QDoubleSpinBox()
        self.square_spin.setRange(0.5, 500.0)
        self.square_spin.setDecimals(2)
        self.square_spin.setSuffix(" mm")
        self.auto_check = QCheckBox("Automatic capture (steady board, new pose)")
        self.auto_check.setToolTip(auto_tooltip)
        for group in ((QLabel("Board inner corners:"), self.cols_spin, QLabel("×"),
                       self.rows_spin),
                      (QLabel("Square size:"), self.square_spin), (self.auto_check,)):
            box = QWidget()
            row = QHBoxLayout(box)
            row.setContentsMargins(0, 0, 0, 0)
            for w in group:
                row.addWidget(w)
            board.addWidget(box)
        for w in (self.cols_spin, self.rows_spin):
            w.valueChanged.connect(self.edited)
        self.square_spin.valueChanged.connect(self.edited)

    @property
    def board(self) -> BoardSpec:
        return BoardSpec(self.cols_spin.value(), self.rows_spin.value(), self.square_spin.value())

    def show_board(self, board: BoardSpec) -> None:
        """Show `board` without emitting `edited`."""
        for w, v in ((self.cols_spin, board.cols), (self.rows_spin, board.rows),
                     (self.square_spin, board.square_mm)):
            w.blockSignals(True)
            w.setValue(v)
            w.blockSignals(False)

    def show_auto(self, on: bool) -> None:
        """Check or uncheck automatic capture without emitting `toggled`."""
        self.auto_check.blockSignals(True)
        self.auto_check.setChecked(on)
        self.auto_check.blockSignals(False)
