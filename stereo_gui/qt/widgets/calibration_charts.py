"""The Calibration tab's charts: reprojection error per pair (click a bar to select the pair),
with the mean error and a threshold line to exclude the pairs above it; and a rectified pair with
horizontal lines to check the rectification by eye: side by side with one zoom for both halves
(with the pair's detected and reprojected corners), as an anaglyph, or blended."""

from __future__ import annotations

import math
from collections.abc import Iterable

import cv2
import numpy as np
import pyqtgraph as pg
from pyqtgraph.GraphicsScene.mouseEvents import MouseClickEvent
from PySide6.QtCore import QRectF, Qt, Signal
from PySide6.QtWidgets import QCheckBox, QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

LINE_EVERY_PX = 32  # rectification check: a horizontal line every this many rows
# the error chart's y range over its tallest bar (or the threshold line, if higher): room for
# the selected pair's frame (5 % higher) and the top tick's label; the legend has its own row
Y_HEADROOM = 1.15
_BAR_LEFT = "#4f8fd6"
_BAR_RIGHT = "#e08a3c"
_BAR_SELECTED = "#f5e342"
_BAR_EXCLUDED = "#8a8a8a"  # a pair excluded since this calibration: hatched grey
_MEAN_LINE = "#e8e8e8"
_THRESHOLD_LINE = "#ff4d4d"
_DETECTED = "#2ee65a"  # corners as detected: circles
_REPROJECTED = "#ff3b3b"  # as the calibration reprojects them: crosses
_ERROR_LINE = "#ffd21f"
ERROR_LINE_PX = 12.0  # the mean error is drawn this long (the scale is said in the title)


def error_scale(mean_px: float | None) -> float:
    """How many times longer to draw reprojection errors so that the mean one is about
    ERROR_LINE_PX long: 1, 2, 5, 10, 20, 50, ... (never shorter than they are)."""
    if not mean_px or not math.isfinite(mean_px) or mean_px <= 0:
        return 1.0
    want = ERROR_LINE_PX / mean_px
    if want <= 1:
        return 1.0
    exp = math.floor(math.log10(want))
    for m in (5, 2, 1):
        if m * 10 ** exp <= want:
            return float(m * 10 ** exp)
    return 1.0


class ErrorBarChart(pg.PlotWidget):  # type: ignore[misc]  # pyqtgraph ships no types
    """Reprojection error per pair (left and right bars); a click selects a pair."""

    pairClicked = Signal(str)
    thresholdMoved = Signal(float)  # the threshold line dragged to this error, px

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setLabel("left", "reprojection error", units="px")
        self.getAxis("left").enableAutoSIPrefix(False)  # not "mpx"
        self.getAxis("bottom").enableAutoSIPrefix(False)  # not "pair (x0.001)" while empty
        self.setLabel("bottom", "pair")
        self.setMouseEnabled(x=False, y=False)
        self.hideButtons()
        self.setMenuEnabled(False)
        # the legend goes above the plot, in a row of its own (anchored in the plot it sat
        # over the bars and the lines, and was cut off when the chart was narrow)
        self._legend = pg.LegendItem(colCount=5)
        self._legend.setParentItem(self.plotItem)
        self._legend.anchor(itemPos=(1, 0), parentPos=(1, 0), offset=(-8, 2))
        self.plotItem.legend = self._legend  # items named on creation go into it
        self.plotItem.geometryChanged.connect(self._fit_legend)
        self.names: list[str] = []
        self._bars_top = 0.1  # the tallest bar, px
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
        self.mean_px: float | None = None
        # the mean and the threshold are named in the legend, not on the bars
        self._mean = pg.InfiniteLine(angle=0, movable=False,
                                     pen=pg.mkPen(_MEAN_LINE, width=1.5, style=Qt.PenStyle.DashLine))
        self._threshold = pg.InfiniteLine(angle=0, movable=True,
                                          pen=pg.mkPen(_THRESHOLD_LINE, width=1.5),
                                          hoverPen=pg.mkPen(_THRESHOLD_LINE, width=3))
        # legend samples of the two lines (curves with no points)
        self._mean_key = pg.PlotDataItem([], [], pen=self._mean.pen)
        self._threshold_key = pg.PlotDataItem([], [], pen=self._threshold.pen)
        self._lines_in_legend = False
        self._threshold.setToolTip("Drag: the pairs above this error can be excluded")
        self._threshold.sigPositionChanged.connect(self._threshold_dragged)
        self._threshold.setBounds((0, None))
        for line in (self._mean, self._threshold):
            line.setVisible(False)
            self.addItem(line, ignoreBounds=True)
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
        self._bars_top = max([*left, *right, 0.1])
        self.setXRange(-0.7, max(len(names) - 0.3, 0.5), padding=0)
        self.select(self.selected if self.selected in self.names else None)
        self.set_excluded(self.excluded)
        errs = np.asarray([*left, *right], float)
        errs = errs[np.isfinite(errs)]
        self.mean_px = float(errs.mean()) if errs.size else None
        self._mean.setVisible(self.mean_px is not None)
        self._threshold.setVisible(self.mean_px is not None)
        if self.mean_px is not None:
            self._mean.setValue(self.mean_px)
        self._update_line_legend()
        self._fit_y()

    def _update_line_legend(self) -> None:
        legend = self.plotItem.legend
        if self._lines_in_legend:
            legend.removeItem(self._mean_key)
            legend.removeItem(self._threshold_key)
            self._lines_in_legend = False
        if self.mean_px is not None:
            legend.addItem(self._mean_key, f"mean {self.mean_px:.3f}")
            legend.addItem(self._threshold_key, f"threshold {self.threshold_px:.3f}")
            self._lines_in_legend = True
        self._fit_legend()

    def _fit_legend(self) -> None:
        """As many legend entries side by side as the chart's width holds, and the row above
        the plot as high as the legend."""
        legend = self._legend
        entries = len(legend.items)
        room = self.plotItem.width() - 16
        for cols in range(max(entries, 1), 0, -1):
            legend.setColumnCount(cols)
            legend.updateSize()
            if legend.width() <= room or cols == 1:
                break
        self.plotItem.layout.setRowFixedHeight(0, legend.height() + 4 if entries else 0)

    def legend_rect(self) -> QRectF:
        """Where the legend is drawn, scene px."""
        rect: QRectF = self._legend.sceneBoundingRect()
        return rect

    def set_threshold(self, px: float) -> None:
        """Put the threshold line at `px` (no thresholdMoved)."""
        self._threshold.blockSignals(True)
        self._threshold.setValue(float(px))
        self._threshold.blockSignals(False)
        self._update_line_legend()
        self._fit_y()

    def _fit_y(self) -> None:
        """The y range: the tallest bar and the threshold line, with room above them (not
        while the line is dragged: the scale would move under the pointer)."""
        top = self._bars_top
        if self._threshold.isVisible():
            top = max(top, self.threshold_px)
        self.setYRange(0, top * Y_HEADROOM, padding=0)

    @property
    def threshold_px(self) -> float:
        return float(self._threshold.value())

    def _threshold_dragged(self) -> None:
        v = float(self._threshold.value())
        self._update_line_legend()
        self.thresholdMoved.emit(v)

    def set_excluded(self, names: Iterable[str]) -> None:
        """Hatch the bars of the pairs excluded in the session: they are still part of this
        calibration until Recalibrate, and the chart must say which ones will go."""
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
        self._fit_legend()

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

    def _clicked(self, ev: MouseClickEvent) -> None:
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

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.mode_combo = QComboBox()
        for key, text in RECT_MODES.items():
            self.mode_combo.addItem(text, key)
        self.mode_combo.setToolTip("How to look at the rectified pair")
        self.mode_combo.currentIndexChanged.connect(lambda _i: self._draw())
        self._build_views()
        row = self._build_controls_row()
        col = QVBoxLayout(self)
        col.setContentsMargins(0, 0, 0, 0)
        col.addLayout(row)
        col.addWidget(self.glw, 1)
        self.shown: str | None = None
        self._pair: tuple[np.ndarray, np.ndarray] | None = None
        self._title = ""
        # (detected, reprojected) rectified px per side, and how much longer errors are drawn
        self._corners: tuple[tuple[np.ndarray, np.ndarray], ...] | None = None
        self.error_scale = 1.0

    def _build_views(self) -> None:
        """The title over the two halves, each a view box with its image, lines and corners;
        one zoom for both."""
        self.glw = pg.GraphicsLayoutWidget()
        self.glw.setBackground("#202020")
        self.title = pg.LabelItem("Rectification check: select a pair", color="w")
        self.glw.addItem(self.title, row=0, col=0, colspan=2)
        self.views: list[pg.ViewBox] = []
        self.images: list[pg.ImageItem] = []
        self.line_items: list[pg.PlotCurveItem] = []
        self.detected_items: list[pg.ScatterPlotItem] = []
        self.reprojected_items: list[pg.ScatterPlotItem] = []
        self.error_items: list[pg.PlotCurveItem] = []
        for col in (0, 1):
            vb = self.glw.addViewBox(row=1, col=col, lockAspect=True, enableMouse=True)
            vb.invertY(True)
            img = pg.ImageItem(axisOrder="row-major")
            vb.addItem(img)
            lines = pg.PlotCurveItem(pen=pg.mkPen((80, 255, 80, 150), width=1),
                                     connect="pairs")
            vb.addItem(lines)
            errors = pg.PlotCurveItem(pen=pg.mkPen(_ERROR_LINE, width=1), connect="pairs")
            detected = pg.ScatterPlotItem(symbol="o", size=7, brush=None,
                                          pen=pg.mkPen(_DETECTED, width=1))
            reprojected = pg.ScatterPlotItem(symbol="+", size=7, brush=pg.mkBrush(_REPROJECTED),
                                             pen=pg.mkPen(_REPROJECTED, width=1))
            for it in (errors, detected, reprojected):
                vb.addItem(it)
            self.error_items.append(errors)
            self.detected_items.append(detected)
            self.reprojected_items.append(reprojected)
            self.views.append(vb)
            self.images.append(img)
            self.line_items.append(lines)
        # one zoom for both halves: a point stays on the same row and column in both
        self.views[1].setXLink(self.views[0])
        self.views[1].setYLink(self.views[0])
        self.vb = self.views[0]
        self.image = self.images[0]
        self.lines = self.line_items[0]

    def _build_controls_row(self) -> QHBoxLayout:
        """Show: the mode, and the corners' check box."""
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(QLabel("Show:"))
        row.addWidget(self.mode_combo)
        self.corners_check = QCheckBox("Corners: \u25cb detected, + reprojected")
        self.corners_check.setChecked(True)
        self.corners_check.setToolTip(
            "The pair's corners as found (circles) and as the calibration reprojects them "
            "(crosses), side by side; the yellow lines are the errors, drawn longer (the title "
            "says how much). Zoom with the mouse wheel to see the crosses apart.")
        self.corners_check.toggled.connect(lambda _on: self._draw())
        row.addWidget(self.corners_check)
        row.addStretch(1)
        return row

    @property
    def mode(self) -> str:
        return str(self.mode_combo.currentData())

    def set_mode(self, mode: str) -> None:
        """"side", "anaglyph" or "blend"."""
        self.mode_combo.setCurrentIndex(list(RECT_MODES).index(mode))

    def show_pair(self, name: str, left_rect: np.ndarray, right_rect: np.ndarray,
                  note: str = "", corners: tuple[tuple[np.ndarray, np.ndarray], ...] | None = None,
                  error_scale: float = 1.0) -> None:
        """Show a rectified pair; `corners` ((detected, reprojected) of the left image, the same
        of the right), in rectified pixels, are drawn in the side-by-side mode with the errors
        drawn `error_scale` times longer."""
        self._corners = corners
        self.error_scale = float(error_scale)
        self._pair = (left_rect, right_rect)
        self._title = f"Rectified pair {name}: a point lies on one row in both{note}"
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
        shown: tuple[np.ndarray, np.ndarray | None]
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
        corners = self._corners if (side and self.corners_check.isChecked()) else None
        self.corners_check.setEnabled(side and self._corners is not None)
        for k in (0, 1):
            if corners is None:
                for it in (self.detected_items[k], self.reprojected_items[k], self.error_items[k]):
                    it.setData([], [])
                continue
            det, rep = (np.asarray(a, float).reshape(-1, 2) for a in corners[k])
            self.detected_items[k].setData(det[:, 0], det[:, 1])
            self.reprojected_items[k].setData(rep[:, 0], rep[:, 1])
            tip = det + self.error_scale * (rep - det)
            seg = np.empty((2 * len(det), 2))
            seg[0::2], seg[1::2] = det, tip
            self.error_items[k].setData(seg[:, 0], seg[:, 1])
        # one image: the right column gives its room to it
        self.glw.ci.layout.setColumnMaximumWidth(1, 1e6 if side else 0.0)
        what = "left | right" if side else RECT_MODES[self.mode].lower()
        extra = ""
        if corners is not None:
            extra = f"; errors \u00d7{self.error_scale:g}" if self.error_scale != 1 else ""
        self.title.setText(f"{self._title} ({what}{extra})")

    def corner_points(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """(detected, reprojected) points drawn on one half, (N, 2) each (for tests)."""
        d = self.detected_items[side].data
        r = self.reprojected_items[side].data
        return (np.column_stack([d["x"], d["y"]]), np.column_stack([r["x"], r["y"]]))

    def clear_pair(self) -> None:
        for img, lines in zip(self.images, self.line_items, strict=True):
            img.clear()
            lines.setData([], [])
        for it in (*self.detected_items, *self.reprojected_items, *self.error_items):
            it.setData([], [])
        self._corners = None
        self._pair = None
        self.title.setText("Rectification check: select a pair")
        self.shown = None
