"""The Live tab's views: one image panel per view and the check boxes that show or hide them,
laid out in the order of VIEWS in the grid of columns that gives each picture the most room in
the space there is (six views: three by two in a wide window, not two by three at a third of the
size), an odd last one spanning its row."""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence

from PySide6.QtCore import Signal
from PySide6.QtGui import QResizeEvent
from PySide6.QtWidgets import QCheckBox, QGridLayout, QWidget

from stereo_gui.pipeline.live import DEFAULT_VIEWS
from stereo_gui.qt.widgets.image_view import COLOR_BAR_WIDTH_PX, ImagePanel

# view key -> title; all views are in rectified-left pixel coordinates except "right"
VIEWS: dict[str, str] = {
    "left": "Rectified left",
    "right": "Rectified right",
    "raw": "Raw disparity (SGBM), bright = near",
    "closed": "After the closing filter",
    "depth": "Depth (what a click reads), colour = distance",
    "wls": "WLS filtered (a picture: holes filled, not measured)",
}
SHORT_NAMES = {"left": "Left", "right": "Right", "raw": "Raw", "closed": "Closed",
               "depth": "Depth", "wls": "WLS"}
COLOR_VIEWS = ("depth", "wls")  # the views coloured by distance, each with its colour bar
# the least height all rows of views together ask for, px: the rows share it, so that showing
# another view never makes the window taller (a third row of panels at their own minimum height
# pushed a 720 or 768 px high window's status bar off the screen)
GRID_MIN_HEIGHT_PX = 240
PANEL_MIN_WIDTH_PX = 200
PICTURE_ASPECT = 4 / 3  # a camera picture's width over its height, for choosing the columns
TITLE_PX = 24  # a panel's title line


def best_columns(n: int, width: int, height: int, spacing: int = 4,
                 color_views: int = 0) -> int:
    """How many columns lay `n` panels out in `width` x `height` px with the largest picture in
    each (the smallest of them where panels differ); no more columns than fit panels of
    PANEL_MIN_WIDTH_PX."""
    if n <= 1:
        return 1
    most = max(1, min(n, (width + spacing) // (PANEL_MIN_WIDTH_PX + spacing)))
    best, best_scale = 1, -1.0
    for cols in range(1, most + 1):
        rows = -(-n // cols)
        cell_w = (width - spacing * (cols - 1)) / cols
        cell_h = (height - spacing * (rows - 1)) / rows - TITLE_PX
        picture_w = cell_w - (COLOR_BAR_WIDTH_PX if color_views else 0)
        scale = min(picture_w / PICTURE_ASPECT, cell_h)  # the picture's height, px
        if scale > best_scale + 0.5:  # fewer columns where it hardly differs
            best, best_scale = cols, scale
    return best


class ViewGrid(QWidget):
    """The panels of the views shown, in a grid. `changed` (the keys shown) follows every
    change of the check boxes and `set_visible`."""

    changed = Signal(list)

    def __init__(self, shown: Iterable[str] = (), parent: QWidget | None = None) -> None:
        super().__init__(parent)
        shown = tuple(v for v in (shown or DEFAULT_VIEWS) if v in VIEWS) or DEFAULT_VIEWS
        self.panels: dict[str, ImagePanel] = {}
        self.checks: dict[str, QCheckBox] = {}
        # every panel, shown or not, is a child of this grid: a hidden one is deleted with the
        # window, never left to the interpreter's exit as a top-level widget of its own
        for key, title in VIEWS.items():
            panel = ImagePanel(key, title, color_bar=(key in COLOR_VIEWS), parent=self)
            panel.hide()
            self.panels[key] = panel
            check = QCheckBox(SHORT_NAMES[key])
            check.setToolTip(title)
            check.setChecked(key in shown)
            check.toggled.connect(self.lay_out)
            self.checks[key] = check
        self._grid = QGridLayout(self)
        self._grid.setContentsMargins(0, 0, 0, 0)
        self._grid.setSpacing(4)
        self._cols = 1

    def visible(self) -> list[str]:
        return [k for k in VIEWS if self.checks[k].isChecked()]

    def set_visible(self, keys: Collection[str]) -> None:
        for k, c in self.checks.items():
            c.blockSignals(True)
            c.setChecked(k in keys)
            c.blockSignals(False)
        self.lay_out()

    def columns(self) -> int:
        """The columns the views shown are laid out in now."""
        return self._cols

    def _best_columns(self, keys: Sequence[str]) -> int:
        width, height = self.width(), self.height()
        if width < PANEL_MIN_WIDTH_PX or height < GRID_MIN_HEIGHT_PX // 2:  # not laid out yet
            return 1 if len(keys) == 1 else 2
        return best_columns(len(keys), width, height, self._grid.spacing(),
                            sum(k in COLOR_VIEWS for k in keys))

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt's name)
        super().resizeEvent(event)
        if self._best_columns(self.visible()) != self._cols:
            self._place()  # the same views in other columns: nothing to tell

    def lay_out(self, *_args: object) -> None:
        """Place the panels of the views ticked, and say which they are (`changed`)."""
        self._place()
        self.changed.emit(self.visible())

    def _place(self) -> None:
        """The panels of the views ticked in the grid of the columns that suit the size now."""
        for panel in self.panels.values():
            self._grid.removeWidget(panel)
            panel.hide()
        keys = self.visible()
        cols = self._cols = self._best_columns(keys)
        rows = max(1, -(-len(keys) // cols))
        row_min = (GRID_MIN_HEIGHT_PX - self._grid.spacing() * (rows - 1)) // rows
        # the columns share the least width two ask for: three columns never make the window
        # wider than two did (nor keep it from shrinking back to two)
        spacing = self._grid.spacing()
        col_min = (min(cols, 2) * (PANEL_MIN_WIDTH_PX + spacing) - spacing * cols) // cols
        for panel in self.panels.values():
            panel.setMinimumSize(col_min, row_min)
        for c in range(len(VIEWS)):  # columns and rows of equal size, whatever the panels ask
            self._grid.setColumnStretch(c, 1 if c < cols else 0)
            self._grid.setRowStretch(c, 1 if c < rows else 0)
        for i, key in enumerate(keys):
            # an odd last view spans the row: no empty cell beside it (2-2-1 with Right on)
            span = cols if i == len(keys) - 1 and len(keys) % cols else 1
            self._grid.addWidget(self.panels[key], i // cols, i % cols, 1, span)
            self.panels[key].show()
