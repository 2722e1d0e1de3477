"""The Calibration tab's charts: reprojection error per pair (click a bar to select the pair)
and a rectified pair with horizontal lines to check the rectification by eye: side by side with
one zoom for both halves, as an anaglyph, or blended."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

LINE_EVERY_PX = 32  # rectification check: a horizontal line every this many rows
LEGEND_HEADROOM = 1.5  # the error chart's y range over its tallest bar
_BAR_LEFT = "#4f8fd6"
_BAR_RIGHT = "#e08a3c"
_BAR_SELECTED = "#f5e342"
_BAR_EXCLUDED = "#8a8a8a"  # a pair excluded since this calibration: hatched grey


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
        self.excluded: set[str] = set()  # pairs excluded in the session (shown hatched)
        self._left = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_LEFT, name="left")
        self._right = pg.BarGraphItem(x=[], height=[], width=0.38, brush=_BAR_RIGHT, name="right")
        self._mark = pg.BarGraphItem(x=[], height=[], width=0.9, brush=pg.mkBrush(245, 227, 66, 90),
                                     pen=pg.mkPen(_BAR_SELECTED, width=2))
        self._excluded = pg.BarGraphItem(
            x=[], height=[], width=0.82, pen=pg.mkPen(_BAR_EXCLUDED, width=1),
            brush=pg.mkBrush(_BAR_EXCLUDED, style=Qt.BrushStyle.BDiagPattern))
        self._excluded_in_legend = False
        for it in (self._mark, self._left, self._right, self._excluded):
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
        self.set_excluded(self.excluded)

    def set_excluded(self, names) -> None:
        """Hatch the bars of the pairs excluded in the session: they are still part of this
        calibration until Recalibrate (issue 12: they were not marked until then)."""
        self.excluded = set(names)
        idx = [i for i, n in enumerate(self.names) if n in self.excluded]
        lh, rh = self.heights()
        self._excluded.setOpts(x=np.asarray(idx, float),
                               height=[float(max(lh[i], rh[i])) for i in idx])
        legend = self.plotItem.legend
        if idx and not self._excluded_in_legend:
            legend.addItem(self._excluded, "excluded: Recalibrate")
        elif not idx and self._excluded_in_legend:
            legend.removeItem(self._excluded)
        self._excluded_in_legend = bool(idx)

    def excluded_bars(self) -> list[str]:
        """Names of the pairs whose bars are marked excluded (for tests)."""
        xs = self._excluded.opts["x"]
        return [self.names[int(round(x))] for x in (xs if xs is not None else [])]

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


RECT_MODES = {
    "side": "Side by side (one zoom)",
    "anaglyph": "Anaglyph: left red, right cyan",
    "blend": "Blend: left and right 50/50",
}


def anaglyph(left_bgr: np.ndarray, right_bgr: np.ndarray) -> np.ndarray:
    """RGB image: the left image's grey in red, the right's in green and blue (cyan). Where
    rectification is right, a point of the scene far away is grey, a near one a red-cyan pair
    side by side on one row; a vertical offset shows as colour fringes above and below."""
    lg = cv2.cvtColor(left_bgr, cv2.COLOR_BGR2GRAY) if left_bgr.ndim == 3 else left_bgr
    rg = cv2.cvtColor(right_bgr, cv2.COLOR_BGR2GRAY) if right_bgr.ndim == 3 else right_bgr
    return np.ascontiguousarray(np.dstack([lg, rg, rg]))


def blend(left_bgr: np.ndarray, right_bgr: np.ndarray) -> np.ndarray:
    """RGB image: the two images averaged."""
    mix = cv2.addWeighted(left_bgr, 0.5, right_bgr, 0.5, 0.0)
    return np.ascontiguousarray(mix[:, :, ::-1] if mix.ndim == 3 else
                                np.dstack([mix, mix, mix]))


class RectifiedPairView(QWidget):
    """A rectified pair with horizontal lines: matching points sit on one line. Side by side
    (both halves zoom and pan together), as an anaglyph or blended into one image."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.mode_combo = QComboBox()
        for key, text in RECT_MODES.items():
            self.mode_combo.addItem(text, key)
        self.mode_combo.setToolTip("How to look at the rectified pair")
        self.mode_combo.currentIndexChanged.connect(lambda _i: self._draw())
        self.glw = pg.GraphicsLayoutWidget()
        self.glw.setBackground("#202020")
        self.title = pg.LabelItem("Rectification check: select a pair", color="w")
        self.glw.addItem(self.title, row=0, col=0, colspan=2)
        self.views: list[pg.ViewBox] = []
        self.images: list[pg.ImageItem] = []
        self.line_items: list[pg.PlotCurveItem] = []
        for col in (0, 1):
            vb = self.glw.addViewBox(row=1, col=col, lockAspect=True, enableMouse=True)
            vb.invertY(True)
            img = pg.ImageItem(axisOrder="row-major")
            vb.addItem(img)
            lines = pg.PlotCurveItem(pen=pg.mkPen((80, 255, 80, 150), width=1),
                                     connect="pairs")
            vb.addItem(lines)
            self.views.append(vb)
            self.images.append(img)
            self.line_items.append(lines)
        # one zoom for both halves: a point stays on the same row and column in both
        self.views[1].setXLink(self.views[0])
        self.views[1].setYLink(self.views[0])
        self.vb = self.views[0]
        self.image = self.images[0]
        self.lines = self.line_items[0]
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(QLabel("Show:"))
        row.addWidget(self.mode_combo)
        row.addStretch(1)
        col = QVBoxLayout(self)
        col.setContentsMargins(0, 0, 0, 0)
        col.addLayout(row)
        col.addWidget(self.glw, 1)
        self.shown: str | None = None
        self._pair: tuple[np.ndarray, np.ndarray] | None = None
        self._title = ""

    @property
    def mode(self) -> str:
        return str(self.mode_combo.currentData())

    def set_mode(self, mode: str) -> None:
        """"side", "anaglyph" or "blend"."""
        self.mode_combo.setCurrentIndex(list(RECT_MODES).index(mode))

    def show_pair(self, name: str, left_rect: np.ndarray, right_rect: np.ndarray,
                  note: str = "") -> None:
        self._pair = (left_rect, right_rect)
        self._title = (f"Rectified pair {name}: a point should lie on the same row in both"
                       f"{note}")
        self.shown = name
        h, w = left_rect.shape[:2]
        self._draw()
        self.vb.setRange(xRange=(0, w), yRange=(0, h), padding=0.01)

    def _draw(self) -> None:
        if self._pair is None:
            return
        left, right = self._pair
        h, w = left.shape[:2]
        side = self.mode == "side"
        if side:
            shown = (left[:, :, ::-1], right[:, :, ::-1])
        else:
            shown = ((anaglyph if self.mode == "anaglyph" else blend)(left, right), None)
        ys = np.arange(LINE_EVERY_PX // 2, h, LINE_EVERY_PX, dtype=float)
        xs = np.tile([0.0, float(w)], len(ys))
        for vb, img, lines, arr in zip(self.views, self.images, self.line_items, shown,
                                       strict=True):
            vb.setVisible(arr is not None)
            if arr is None:
                img.clear()
                lines.setData([], [])
                continue
            img.setImage(np.ascontiguousarray(arr), levels=(0, 255), autoLevels=False)
            lines.setData(xs, np.repeat(ys, 2))
        # one image: the right column gives its room to it
        self.glw.ci.layout.setColumnMaximumWidth(1, 1e6 if side else 0.0)
        what = "left | right" if side else RECT_MODES[self.mode].lower()
        self.title.setText(f"{self._title} ({what})")

    def clear_pair(self) -> None:
        for img, lines in zip(self.images, self.line_items, strict=True):
            img.clear()
            lines.setData([], [])
        self._pair = None
        self.title.setText("Rectification check: select a pair")
        self.shown = None
