"""A layout that places its widgets in a row and wraps them onto further rows when the row is
too narrow (a toolbar that stays whole on a laptop screen instead of being cut off). Give it a
widget of its own (`FlowLayout(widget)`): that widget then asks for the height its rows need."""

from __future__ import annotations

from PySide6.QtCore import QMargins, QPoint, QRect, QSize, Qt
from PySide6.QtWidgets import QHBoxLayout, QLayout, QLayoutItem, QWidget


class FlowLayout(QLayout):
    """Left-to-right rows of widgets, wrapped at the layout's width. `add_stretch()` marks a
    place where a row may leave its free space (items after it are pushed to the right end of
    the row when they fit on it)."""

    def __init__(self, parent: QWidget | None = None, spacing: int = 6) -> None:
        super().__init__(parent)
        self._items: list[QLayoutItem] = []
        self._stretch_at: int | None = None
        self._spacing = spacing
        self.setContentsMargins(QMargins(0, 0, 0, 0))

    # ---- QLayout API ---------------------------------------------------------------------------
    def addItem(self, item: QLayoutItem) -> None:  # noqa: N802 - Qt API
        self._items.append(item)

    def add_group(self, *widgets: QWidget) -> QWidget:
        """Add `widgets` side by side as one item (a label and its field never wrap apart)."""
        box = QWidget()
        row = QHBoxLayout(box)
        row.setContentsMargins(0, 0, 0, 0)
        for w in widgets:
            row.addWidget(w)
        self.addWidget(box)
        return box

    def add_stretch(self) -> None:
        """Items added from now on sit at the right end of their row when it has room."""
        self._stretch_at = len(self._items)

    def count(self) -> int:
        return len(self._items)

    def itemAt(self, index: int) -> QLayoutItem | None:  # noqa: N802 - Qt API
        return self._items[index] if 0 <= index < len(self._items) else None

    def takeAt(self, index: int) -> QLayoutItem | None:  # noqa: N802 - Qt API
        if 0 <= index < len(self._items):
            if self._stretch_at is not None and index < self._stretch_at:
                self._stretch_at -= 1
            return self._items.pop(index)
        return None

    def expandingDirections(self) -> Qt.Orientation:  # noqa: N802 - Qt API
        return Qt.Orientation(0)

    def hasHeightForWidth(self) -> bool:  # noqa: N802 - Qt API
        return True

    def heightForWidth(self, width: int) -> int:  # noqa: N802 - Qt API
        return self._do_layout(QRect(0, 0, width, 0), apply=False)

    def setGeometry(self, rect: QRect) -> None:  # noqa: N802 - Qt API
        super().setGeometry(rect)
        height = self._do_layout(rect, apply=True)
        # the widget that holds the layout asks for the rows it needs at this width (a parent
        # box layout does not ask a nested layout's heightForWidth, so the rows would overlap
        # what is below them when the window is short)
        host = self.parentWidget()
        if host is not None and host.layout() is self and host.minimumHeight() != height:
            host.setMinimumHeight(height)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt API
        """One row of everything (the width it would like)."""
        w = h = 0
        for item in self._visible():
            s = item.sizeHint()
            w += s.width() + (self._spacing if w else 0)
            h = max(h, s.height())
        m = self.contentsMargins()
        return QSize(w + m.left() + m.right(), h + m.top() + m.bottom())

    def minimumSize(self) -> QSize:  # noqa: N802 - Qt API
        """As wide as the widest item: everything else wraps."""
        size = QSize()
        for item in self._visible():
            size = size.expandedTo(item.minimumSize())
        m = self.contentsMargins()
        return size + QSize(m.left() + m.right(), m.top() + m.bottom())

    # ---- placement ------------------------------------------------------------------------------
    def _visible(self) -> list[QLayoutItem]:
        return [it for it in self._items
                if not ((w := it.widget()) is not None and w.isHidden())]

    def _rows(self, width: int) -> list[list[QLayoutItem]]:
        rows: list[list[QLayoutItem]] = [[]]
        used = 0
        for item in self._visible():
            w = item.sizeHint().width()
            if rows[-1] and used + self._spacing + w > width:
                rows.append([])
                used = 0
            used += (self._spacing if rows[-1] else 0) + w
            rows[-1].append(item)
        return rows

    def _do_layout(self, rect: QRect, apply: bool) -> int:
        m = self.contentsMargins()
        area = rect.adjusted(m.left(), m.top(), -m.right(), -m.bottom())
        y = area.y()
        pushed = set(map(id, self._items[self._stretch_at:])) if self._stretch_at is not None \
            else set()
        for row in self._rows(area.width()):
            if not row:
                continue
            height = max(it.sizeHint().height() for it in row)
            widths = [min(it.sizeHint().width(), area.width()) for it in row]
            total = sum(widths) + self._spacing * (len(widths) - 1)
            free = max(0, area.width() - total)
            x = area.x()
            for item, w in zip(row, widths, strict=True):
                if id(item) in pushed and free:
                    x += free  # the stretch: the rest of the row goes to the right end
                    free = 0
                if apply:  # one height a row: buttons of different kinds line up
                    item.setGeometry(QRect(QPoint(x, y), QSize(w, height)))
                x += w + self._spacing
            y += height + self._spacing
        return y - self._spacing - rect.y() + m.bottom()
