"""Small widget helpers the tabs share."""

from __future__ import annotations

from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget


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
