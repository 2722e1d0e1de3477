"""The Live tab's views: one image panel per view and the check boxes that show or hide them,
laid out two by two in the order of VIEWS (an odd last one spanning its row)."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QGridLayout, QWidget

from stereo_gui.pipeline.live import DEFAULT_VIEWS
from stereo_gui.qt.widgets.image_view import ImagePanel

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


class ViewGrid(QWidget):
    """The panels of the views shown, in a grid. `changed` (the keys shown) follows every
    change of the check boxes and `set_visible`."""

    changed = Signal(list)

    def __init__(self, shown=(), parent: QWidget | None = None) -> None:
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

    def visible(self) -> list[str]:
        return [k for k in VIEWS if self.checks[k].isChecked()]

    def set_visible(self, keys) -> None:
        for k, c in self.checks.items():
            c.blockSignals(True)
            c.setChecked(k in keys)
            c.blockSignals(False)
        self.lay_out()

    def lay_out(self, *_args) -> None:
        for panel in self.panels.values():
            self._grid.removeWidget(panel)
            panel.hide()
        keys = self.visible()
        cols = 1 if len(keys) == 1 else 2
        rows = max(1, -(-len(keys) // cols))
        row_min = (GRID_MIN_HEIGHT_PX - self._grid.spacing() * (rows - 1)) // rows
        for panel in self.panels.values():
            panel.setMinimumSize(PANEL_MIN_WIDTH_PX, row_min)
        for c in range(2):  # columns of equal width, whatever the panels' own size hints
            self._grid.setColumnStretch(c, 1 if c < cols else 0)
        for i, key in enumerate(keys):
            # an odd last view spans the row: no empty cell beside it (2-2-1 with Right on)
            span = cols if i == len(keys) - 1 and len(keys) % cols else 1
            self._grid.addWidget(self.panels[key], i // cols, i % cols, 1, span)
            self.panels[key].show()
        self.changed.emit(keys)
