"""Small widget helpers the tabs share."""

from __future__ import annotations

from PySide6.QtCore import QSize, Qt
from PySide6.QtWidgets import QLabel, QScrollArea, QVBoxLayout, QWidget


def pane() -> tuple[QWidget, QVBoxLayout]:
    """A widget with a margin-less vertical layout, e.g. one side of a splitter."""
    widget = QWidget()
    layout = QVBoxLayout(widget)
    layout.setContentsMargins(0, 0, 0, 0)
    return widget, layout


def wrapping_label(text: str = "") -> QLabel:
    """A label whose text wraps at the label's width."""
    label = QLabel(text)
    label.setWordWrap(True)
    return label


class VerticalScroll(QScrollArea):
    """Scrolls up and down only: as wide as its widget needs, as low as one likes."""

    def __init__(self) -> None:
        super().__init__()
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)

    def minimumSizeHint(self) -> QSize:  # noqa: N802 - Qt API
        w = self.widget()
        hint = super().minimumSizeHint()
        if w is not None:
            hint.setWidth(w.minimumSizeHint().width() + self.verticalScrollBar().sizeHint().width())
        return hint
