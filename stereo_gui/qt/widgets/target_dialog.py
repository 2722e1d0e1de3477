"""Print a target...: the Capture tab's target as a PDF, SVG or PNG to print at true scale.

(A dialog among the widgets because the Capture tab opens it, and tabs do not import dialogs.)

The dialog shows the sheet as it will print (core.target_sheet lays it out), says so when the
target does not fit the chosen paper, and writes the file chosen (files.target_sheet)."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.target_sheet import PAGES_MM, TargetSheet, describe, layout
from stereo_gui.files.target_sheet import png_image, write_target
from stereo_gui.qt.widgets import folder_dialog

_PREVIEW_DPI = 42.0


class TargetDialog(QDialog):
    """Preview the target on a page and write it; `written(path)` after each file written."""

    written = Signal(str)

    def __init__(self, board: BoardSpec, folder: Path, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Print a target")
        self.board = board
        self.folder = Path(folder)
        self.sheet: TargetSheet | None = None
        lay = QVBoxLayout(self)
        self.what_label = QLabel(describe(board))
        self.what_label.setWordWrap(True)
        lay.addWidget(self.what_label)
        row = QHBoxLayout()
        row.addWidget(QLabel("Paper:"))
        self.page_combo = QComboBox()
        for key, (w, h) in PAGES_MM.items():
            self.page_combo.addItem(f"{key.upper() if key.startswith('a') else key.capitalize()} "
                                    f"({w:g} x {h:g} mm)", key)
        self.page_combo.currentIndexChanged.connect(self._update)
        row.addWidget(self.page_combo)
        row.addStretch(1)
        lay.addLayout(row)
        self.preview = QLabel()
        self.preview.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.preview.setMinimumSize(320, 320)
        self.preview.setStyleSheet("background: #777")
        lay.addWidget(self.preview, 1)
        self.status_label = QLabel("")
        self.status_label.setWordWrap(True)
        lay.addWidget(self.status_label)
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        self.save_button = QPushButton("Save as…")
        self.save_button.setDefault(True)
        self.save_button.clicked.connect(self._choose_file)
        close = QPushButton("Close")
        close.clicked.connect(self.reject)
        buttons.addWidget(self.save_button)
        buttons.addWidget(close)
        lay.addLayout(buttons)
        self._update()

    def _update(self) -> None:
        try:
            sheet = layout(self.board, self.page_combo.currentData())
        except StereoGuiError as exc:
            self.sheet = None
            self.preview.clear()
            self.status_label.setText(f"<b>Does not fit:</b> {exc}")
            self.status_label.setStyleSheet("color: #b03a2e")
            self.save_button.setEnabled(False)
            return
        self.sheet = sheet
        img = png_image(sheet, _PREVIEW_DPI)
        qimg = QImage(img.data, img.shape[1], img.shape[0], img.strides[0],
                      QImage.Format.Format_Grayscale8).copy()
        self.preview.setPixmap(QPixmap.fromImage(qimg))
        w, h = sheet.page_mm
        self.status_label.setStyleSheet("")
        self.status_label.setText(
            f"On {sheet.page_name} {'landscape' if w > h else 'portrait'}. Print at 100 % "
            "(no 'fit to page') and check the 100 mm bar with a ruler; glue the sheet flat.")
        self.save_button.setEnabled(True)

    def _choose_file(self) -> None:
        name = f"target-{self.board.target}-{self.board.cols}x{self.board.rows}.pdf"
        path, _ = folder_dialog.save_file_name(
            self, "Save the target", str(self.folder / name),
            "PDF (*.pdf);;SVG (*.svg);;PNG at 300 dpi (*.png)")
        if path:
            self.save(path)

    def save(self, path: str | Path) -> bool:
        """Write the sheet to `path` (format by its suffix); False (and the reason shown) if not."""
        if self.sheet is None:
            return False
        try:
            out = write_target(self.sheet, Path(path))
        except (StereoGuiError, OSError) as exc:
            self.status_label.setText(f"Could not write the target: {exc}")
            self.status_label.setStyleSheet("color: #b03a2e")
            return False
        self.status_label.setStyleSheet("")
        self.status_label.setText(f"Wrote {out}. Print it at 100 %.")
        self.written.emit(str(out))
        return True
