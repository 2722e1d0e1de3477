"""The Capture tab's board row: the target (chessboard, circle grids, ChArUco), its size, square
and marker sizes and ArUco dictionary, Print a target..., and the switch for automatic capture."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QLabel,
    QPushButton,
    QSpinBox,
    QWidget,
)

from stereo_gui.core.board import DICTIONARIES, TARGET_NAMES, TARGETS, BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.qt.widgets.flow_layout import FlowLayout

_COUNT_LABEL = {"chessboard": "Inner corners:", "circles": "Circles:", "acircles": "Circles:",
                "charuco": "Squares:"}
_SQUARE_LABEL = {"chessboard": "Square:", "circles": "Spacing:", "acircles": "Spacing:",
                 "charuco": "Square:"}
_MARKER_LABEL = {"circles": "Circle:", "acircles": "Circle:", "charuco": "Marker:"}


class BoardRow(QWidget):
    """Target, columns x rows, square (or spacing) and marker (or circle) size in mm, the ArUco
    dictionary, Print a target..., automatic capture.

    `edited()` follows a change of the board by the user (not by `show_board`); `board` is
    always a valid BoardSpec (the last valid one while the fields describe none, and
    `error_label` says why); `printRequested()` asks for the target dialog; the automatic
    capture check box is `auto_check`. `auto_tooltip` explains what automatic capture waits for.
    """

    edited = Signal()
    printRequested = Signal()

    def __init__(self, auto_tooltip: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._board = BoardSpec()
        # groups that wrap onto further rows on a narrow window (a laptop screen)
        flow = FlowLayout(self, spacing=14)

        group = flow.add_group

        self.target_combo = QComboBox()
        for t in TARGETS:
            self.target_combo.addItem(TARGET_NAMES[t].capitalize().replace("Charuco", "ChArUco"), t)
        self.target_combo.setToolTip("The calibration target. A ChArUco board also counts when "
                                     "only part of it is in view, so it can reach the image corners")
        group(QLabel("Target:"), self.target_combo)
        self.count_label = QLabel(_COUNT_LABEL["chessboard"])
        self.cols_spin = QSpinBox()
        self.cols_spin.setRange(2, 40)
        self.rows_spin = QSpinBox()
        self.rows_spin.setRange(2, 40)
        group(self.count_label, self.cols_spin, QLabel("×"), self.rows_spin)
        self.square_label = QLabel(_SQUARE_LABEL["chessboard"])
        self.square_spin = QDoubleSpinBox()
        self.square_spin.setRange(0.5, 500.0)
        self.square_spin.setDecimals(2)
        self.square_spin.setSuffix(" mm")
        group(self.square_label, self.square_spin)
        self.marker_label = QLabel("Marker:")
        self.marker_spin = QDoubleSpinBox()
        self.marker_spin.setRange(0.0, 500.0)
        self.marker_spin.setDecimals(2)
        self.marker_spin.setSuffix(" mm")
        self.marker_spin.setSpecialValueText("default")
        self.marker_spin.setToolTip("ChArUco: the side of the markers; circle grids: the circle "
                                    "diameter (not needed to find them). 0: the usual default")
        self.dict_combo = QComboBox()
        for d in DICTIONARIES:
            self.dict_combo.addItem(d.replace("DICT_", ""), d)
        self.dict_combo.setToolTip("The ArUco dictionary the ChArUco board was printed with")
        group(self.marker_label, self.marker_spin, self.dict_combo)
        self.print_button = QPushButton("Print a target…")
        self.print_button.setToolTip("Write this target as a PDF, SVG or PNG to print at true scale")
        self.print_button.clicked.connect(self.printRequested)
        self.auto_check = QCheckBox("Automatic capture (steady board, new pose or a region "
                                    "not yet covered)")
        self.auto_check.setToolTip(auto_tooltip)
        group(self.print_button, self.auto_check)
        self.error_label = QLabel("")
        self.error_label.setStyleSheet("color: #b03a2e")
        flow.addWidget(self.error_label)
        self.target_combo.currentIndexChanged.connect(self._fields_edited)
        self.dict_combo.currentIndexChanged.connect(self._fields_edited)
        for w in (self.cols_spin, self.rows_spin):
            w.valueChanged.connect(self._fields_edited)
        for box in (self.square_spin, self.marker_spin):
            box.valueChanged.connect(self._fields_edited)
        self.show_board(self._board)

    @property
    def board(self) -> BoardSpec:
        return self._board

    def _from_fields(self) -> BoardSpec:
        return BoardSpec(self.cols_spin.value(), self.rows_spin.value(), self.square_spin.value(),
                         self.target_combo.currentData(), self.marker_spin.value(),
                         self.dict_combo.currentData())

    def _fields_edited(self) -> None:
        self._show_target_fields()
        try:
            board = self._from_fields()
        except InputError as exc:
            self.error_label.setText(str(exc))
            return
        self.error_label.setText("")
        if board != self._board:
            self._board = board
            self.edited.emit()

    def _show_target_fields(self) -> None:
        t = self.target_combo.currentData()
        self.count_label.setText(_COUNT_LABEL[t])
        self.square_label.setText(_SQUARE_LABEL[t])
        self.marker_label.setText(_MARKER_LABEL.get(t, "Marker:"))
        self.marker_label.setVisible(t != "chessboard")
        self.marker_spin.setVisible(t != "chessboard")
        self.dict_combo.setVisible(t == "charuco")

    def show_board(self, board: BoardSpec) -> None:
        """Show `board` without emitting `edited`."""
        widgets = (self.target_combo, self.cols_spin, self.rows_spin, self.square_spin,
                   self.marker_spin, self.dict_combo)
        for w in widgets:
            w.blockSignals(True)
        self.target_combo.setCurrentIndex(max(0, self.target_combo.findData(board.target)))
        self.cols_spin.setValue(board.cols)
        self.rows_spin.setValue(board.rows)
        self.square_spin.setValue(board.square_mm)
        self.marker_spin.setValue(board.marker_mm)
        self.dict_combo.setCurrentIndex(max(0, self.dict_combo.findData(board.dictionary)))
        for w in widgets:
            w.blockSignals(False)
        self._board = board
        self.error_label.setText("")
        self._show_target_fields()

    def show_auto(self, on: bool) -> None:
        """Check or uncheck automatic capture without emitting `toggled`."""
        self.auto_check.blockSignals(True)
        self.auto_check.setChecked(on)
        self.auto_check.blockSignals(False)
