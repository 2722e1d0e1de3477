"""The Capture tab's side pane: coverage guidance above the saved pairs (thumbnails; click one,
or move to it with the keyboard, to review it) and Delete pair (Del), which deletes the pair
shown: the pair on screen and the pair selected in the list are one."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from PySide6.QtCore import QEvent, QObject, QSize, Qt, Signal
from PySide6.QtGui import QIcon, QImage, QKeyEvent, QPixmap
from PySide6.QtWidgets import (
    QFrame,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.detect import PairDetection
from stereo_gui.qt.widgets.coverage import CoverageWidget
from stereo_gui.qt.widgets.helpers import VerticalScroll, pane

THUMB_SIZE = QSize(128, 48)  # a saved pair's thumbnail: both images side by side


def pair_thumbnail(left_bgr: np.ndarray, right_bgr: np.ndarray) -> QIcon:
    """Both images of a pair side by side, THUMB_SIZE, as an icon."""
    h = THUMB_SIZE.height()
    w = THUMB_SIZE.width() // 2 - 2
    parts = [cv2.resize(im, (w, h), interpolation=cv2.INTER_AREA) for im in (left_bgr, right_bgr)]
    gap = np.full((h, 4, 3), 40, np.uint8)
    both = np.ascontiguousarray(np.hstack([parts[0], gap, parts[1]])[:, :, ::-1])
    qimg = QImage(both.data, both.shape[1], both.shape[0], both.strides[0],
                  QImage.Format.Format_RGB888).copy()
    return QIcon(QPixmap.fromImage(qimg))


@dataclass(frozen=True, eq=False)
class SavedPairInfo:
    """A saved pair as the tab shows it: its detection (for coverage) and a thumbnail."""

    name: str
    detection: PairDetection | None
    icon: QIcon | None


class SavedPairsPanel(QWidget):
    """Coverage of the saved pairs, their list and Delete pair.

    `pairClicked(name)` when the technician makes a pair the current one, by mouse or keyboard
    (not when the tab does it with `select`, `clear_selection` or by filling the list).
    """

    pairClicked = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        sl = QVBoxLayout(self)
        sl.setContentsMargins(0, 0, 0, 0)
        self.coverage = CoverageWidget()
        # the guidance scrolls and the line between it and the list can be dragged: at 1280x720
        # its words took the height and the list showed one pair
        coverage_scroll = VerticalScroll()
        coverage_scroll.setWidgetResizable(True)
        coverage_scroll.setFrameShape(QFrame.Shape.NoFrame)
        coverage_scroll.setWidget(self.coverage)
        pairs, pl = pane()
        self.pairs_label = QLabel("Saved pairs")
        pl.addWidget(self.pairs_label)
        self.pair_list = QListWidget()
        self.pair_list.setIconSize(THUMB_SIZE)
        self.pair_list.setUniformItemSizes(True)
        self._quiet = 0  # > 0 while the list is changed by the program, not by the user
        self.pair_list.currentItemChanged.connect(self._current_changed)
        pl.addWidget(self.pair_list, 1)
        self.splitter = QSplitter(Qt.Orientation.Vertical)
        self.splitter.addWidget(coverage_scroll)
        self.splitter.addWidget(pairs)
        self.splitter.setChildrenCollapsible(False)
        self.splitter.setStretchFactor(0, 3)
        self.splitter.setStretchFactor(1, 2)
        self.splitter.setSizes([330, 220])  # the list: four pairs or more at 1280x720
        sl.addWidget(self.splitter, 1)
        pb = QHBoxLayout()
        self.delete_button = QPushButton("Delete pair (Del)")
        self.delete_button.setToolTip("Delete the saved pair shown (its two image files)")
        self.pair_list.installEventFilter(self)  # the Del key in the list: Delete pair
        pb.addWidget(self.delete_button)
        pb.addStretch(1)
        sl.addLayout(pb)

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        if (obj is self.pair_list and event.type() == QEvent.Type.KeyPress
                and isinstance(event, QKeyEvent) and event.key() == Qt.Key.Key_Delete and self.delete_button.isEnabled()):
            self.delete_button.click()
            return True
        return super().eventFilter(obj, event)

    def add_item(self, info: SavedPairInfo, excluded: bool) -> None:
        """Append a saved pair to the list (with its thumbnail and what is wrong with it)."""
        text = info.name
        if info.detection is not None and not info.detection.found:
            text += "  (board not found in both)"
        if excluded:
            text += "  (excluded)"
        item = QListWidgetItem(text)
        if info.icon is not None:
            item.setIcon(info.icon)
        item.setData(Qt.ItemDataRole.UserRole, info.name)
        self._quiet += 1
        try:
            self.pair_list.addItem(item)
        finally:
            self._quiet -= 1
        self.update_label()

    def show_newest(self) -> None:
        """Scroll the list to its last pair (the one just saved)."""
        n = self.pair_list.count()
        if n:
            self.pair_list.scrollToItem(self.pair_list.item(n - 1))

    def clear(self) -> None:
        """Empty the list (no pairClicked)."""
        self._quiet += 1
        try:
            self.pair_list.clear()
        finally:
            self._quiet -= 1

    def _current_changed(self, item: QListWidgetItem | None,
                         _previous: QListWidgetItem | None) -> None:
        if self._quiet or item is None:
            return
        self.pairClicked.emit(item.data(Qt.ItemDataRole.UserRole))

    def update_label(self) -> None:
        n = self.pair_list.count()
        self.pairs_label.setText(f"Saved pairs ({n}): click one (or \u2191 \u2193) to review it")

    def names(self) -> list[str]:
        """The pair names listed, in order."""
        return [self.pair_list.item(i).data(Qt.ItemDataRole.UserRole)
                for i in range(self.pair_list.count())]

    def current_name(self) -> str | None:
        item = self.pair_list.currentItem()
        name: str | None = item.data(Qt.ItemDataRole.UserRole) if item is not None else None
        return name

    def select(self, name: str) -> None:
        """Make pair `name` the current one, scrolled into view (no pairClicked)."""
        for i in range(self.pair_list.count()):
            item = self.pair_list.item(i)
            if item.data(Qt.ItemDataRole.UserRole) == name:
                self._quiet += 1
                try:
                    self.pair_list.setCurrentItem(item)
                finally:
                    self._quiet -= 1
                self.pair_list.scrollToItem(item)
                return

    def clear_selection(self) -> None:
        """No current pair (none is shown; no pairClicked)."""
        self._quiet += 1
        try:
            self.pair_list.setCurrentRow(-1)
            self.pair_list.clearSelection()
        finally:
            self._quiet -= 1
