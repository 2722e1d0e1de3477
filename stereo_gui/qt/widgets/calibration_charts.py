"""The Calibration tab's charts: reprojection error per pair (click a bar to select the pair)
and a rectified pair with horizontal lines to check the rectification by eye."""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Signal

LINE_EVERY_PX = 32  # rectification check: a horizontal line every this many rows
LEGEND_HEADROOM = 1.5  # the error chart's y range over its tallest bar
_BAR_LEFT = "#4f8fd6"
_BAR_RIGHT = "#e08a3c"
_BAR_SELECTED = "#f5e342"


class ErrorBarChart(pg.PlotWidget):
    """Reprojection error per pair (left and right bars); a click selects a pair."""

    pairClicked = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setLabel("left", "reprojection error", units="px")
        self.getAxis("left").enableAutoSIPrefix(False)  # not "mpx"
        self.getAxis("bottom").enableAutoSIPrefix(False)  # not "pair (x0.001)" while empty
        self.setLabel("bottom", "pair")
        self.setMouseEnabled(x=False, y=False)
        self.hideButtons()
        self.setMenuEnabled(False)
        self.addLegend(offset=(-10, 10))
        self.names: list[str] = []
        self.selected: str | None = None
        self._left = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_LEFT, name="left")
        self._right = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_RIGHT, name="right")
        self._mark = pg.BarGraphItem(x=[], height=[], width=0.9, brush=pg.mkBrush(245, 227, 66, 90),
                                     pen=pg.mkPen(_BAR_SELECTED, width=2))
        for it in (self._mark, self._left, self._right):
            self.addItem(it)
        self.scene().sigMouseClicked.connect(self._clicked)
        self.setToolTip("Click a bar to look at that pair (and exclude it if it is bad)")

    def set_errors(self, names: list[str], left: list[float], right: list[float]) -> None:
        self.names = list(names)
        x = np.arange(len(names), dtype=float)
        self._left.setOpts(x=x - 0.2, height=np.asarray(left, float))
        self._right.setOpts(x=x + 0.2, height=np.asarray(right, float))
        ax = self.getAxis("bottom")
        step = max(1, math.ceil(len(names) / 25))
        ax.setTicks([[(i, _short(n)) for i, n in enumerate(names) if i % step == 0], []])
        top = max([*left, *right, 0.1])
        self.setXRange(-0.7, max(len(names) - 0.3, 0.5), padding=0)
        # headroom above the tallest bar: the legend (top right) sits there, not on the bars
        self.setYRange(0, top * LEGEND_HEADROOM, padding=0)
        self.select(self.selected if self.selected in self.names else None)

    def bar_count(self) -> int:
        return len(self.names)

    def heights(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(self._left.opts["height"]), np.asarray(self._right.opts["height"]))

    def select(self, name: str | None) -> None:
        self.selected = name
        if name is None or name not in self.names:
            self._mark.setOpts(x=[], height=[])
            return
        i = self.names.index(name)
        lh, rh = self.heights()
        self._mark.setOpts(x=[float(i)], height=[float(max(lh[i], rh[i])) * 1.05 + 1e-3])

    def _clicked(self, ev) -> None:
        if not self.names:
            return
        p = self.plotItem.vb.mapSceneToView(ev.scenePos())
        i = int(round(p.x()))
        inside = self.plotItem.vb.sceneBoundingRect().contains(ev.scenePos())
        if inside and 0 <= i < len(self.names):
            self.select(self.names[i])
            self.pairClicked.emit(self.names[i])


def _short(name: str) -> str:
    """A short tick label: the number of 'chessboard-L3' style names, else the name."""
    digits = "".join(ch for ch in name if ch.isdigit())
    return digits if digits and len(name) > 6 else name


class RectifiedPairView(pg.GraphicsLayoutWidget):
    """A rectified pair side by side with horizontal lines: matching points sit on one line."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setBackground("#202020")
        self.title = pg.LabelItem("Rectification check: select a pair", color="w")
        self.addItem(self.title, row=0, col=0)
        self.vb = self.addViewBox(row=1, col=0, lockAspect=True, enableMouse=True)
        self.vb.invertY(True)
        self.image = pg.ImageItem(axisOrder="row-major")
        self.vb.addItem(self.image)
        self.lines = pg.PlotCurveItem(pen=pg.mkPen((80, 255, 80, 150), width=1), connect="pairs")
        self.vb.addItem(self.lines)
        self.shown: str | None = None

    def show_pair(self, name: str, left_rect: np.ndarray, right_rect: np.ndarray,
                  note: str = "") -> None:
        h, w = left_rect.shape[:2]
        gap = np.zeros((h, 6, 3), np.uint8)
        both = np.ascontiguousarray(np.hstack([left_rect, gap, right_rect])[:, :, ::-1])
        self.image.setImage(both, levels=(0, 255), autoLevels=False)
        ys = np.arange(LINE_EVERY_PX // 2, h, LINE_EVERY_PX, dtype=float)
        xs = np.tile([0.0, float(both.shape[1])], len(ys))
        self.lines.setData(xs, np.repeat(ys, 2))
        self.vb.setRange(xRange=(0, both.shape[1]), yRange=(0, h), padding=0.01)
        self.title.setText(f"Rectified pair {name}: left | right. A point should lie on the same "
                           f"row in both{note}")
        self.shown = name

    def clear_pair(self) -> None:
        self.image.clear()
        self.lines.setData([], [])
        self.title.setText("Rectification check: select a pair")
        self.shown = None
