"""The window's error bar: the newest problem in a red bar, and every problem not yet dismissed
in a list the person can open.

A start can meet several problems at once (a log set aside, settings that could not be read, a
preset that is broken, a source that cannot be opened): each is kept, none replaces another.
The bar shows the newest; "All N problems" opens the list of all of them, oldest first; the
close button dismisses them all.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QLabel, QListWidget, QToolButton, QVBoxLayout, QWidget

MAX_KEPT = 50  # a flapping device reports again and again: older problems drop off the list
STYLE = "background: #c62828; color: white;"


class ErrorBar(QWidget):
    """A red bar with the newest message, a button that opens the list of all, and Dismiss."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setAutoFillBackground(True)
        self.setStyleSheet(STYLE)
        self._messages: list[str] = []
        self.label = QLabel()  # the newest message
        self.label.setWordWrap(True)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.all_button = QToolButton()
        self.all_button.setCheckable(True)
        self.all_button.setAutoRaise(True)
        self.all_button.setToolTip("Show every problem not yet dismissed")
        self.all_button.toggled.connect(self._show_list)
        close = QToolButton()
        close.setText("✕")
        close.setToolTip("Dismiss all")
        close.setAutoRaise(True)
        close.clicked.connect(self.clear)
        self.list = QListWidget()  # every message, oldest first
        self.list.setWordWrap(True)
        self.list.setStyleSheet("background: #8e0000; color: white;")
        self.list.setMaximumHeight(160)
        self.list.hide()
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.label, 1)
        row.addWidget(self.all_button)
        row.addWidget(close)
        col = QVBoxLayout(self)
        col.setContentsMargins(10, 4, 6, 4)
        col.addLayout(row)
        col.addWidget(self.list)
        self.hide()

    def messages(self) -> list[str]:
        """Every message not yet dismissed, oldest first."""
        return list(self._messages)

    def show_text(self, text: str) -> None:
        """Add `text` (the same text again moves to the end rather than showing twice)."""
        text = str(text)
        if text in self._messages:
            self._messages.remove(text)
        self._messages.append(text)
        del self._messages[:-MAX_KEPT]
        self._update()

    def remove(self, text: str) -> None:
        """Take `text` off (a problem that ended, such as a camera back); hide when none is left."""
        if text in self._messages:
            self._messages.remove(text)
            self._update()

    def clear(self) -> None:
        """Dismiss every message."""
        self._messages.clear()
        self._update()

    def _show_list(self, on: bool) -> None:
        self.list.setVisible(on and len(self._messages) > 1)

    def _update(self) -> None:
        if not self._messages:
            self.all_button.setChecked(False)
            self.hide()
            return
        n = len(self._messages)
        self.label.setText(self._messages[-1])
        self.all_button.setText(f"All {n} problems" if n > 1 else "")
        self.all_button.setVisible(n > 1)
        self.list.clear()
        self.list.addItems(self._messages)
        self._show_list(self.all_button.isChecked())
        self.show()
