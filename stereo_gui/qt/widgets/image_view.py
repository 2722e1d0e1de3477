"""Image panels for live views: fast display, pointer mapping, markers, a distance colour bar.

Images are row-major, C-contiguous uint8 (H x W gray or H x W x 3 RGB) drawn with fixed levels
and auto-range off, as pyqtgraph is fastest that way. Pointer positions are reported in image
pixel coordinates: (0, 0) is the centre of the top-left pixel, so (x, y) indexes `image[y, x]`
after rounding — the convention of OpenCV and of `core.measure`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import pyqtgraph as pg
from pyqtgraph.GraphicsScene.mouseEvents import HoverEvent, MouseClickEvent
from PySide6.QtCore import QPoint, QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QFont, QFontMetrics, QPen, QResizeEvent, QTransform
from PySide6.QtWidgets import (
    QGraphicsItem,
    QGraphicsLineItem,
    QGraphicsRectItem,
    QGraphicsSimpleTextItem,
    QWidget,
)

from stereo_gui.core.colouring import ColorScale, color_scale_caption

pg.setConfigOptions(imageAxisOrder="row-major")

# round distances for colour-bar ticks, mm, in order of preference (rounder first)
_NICE_MM_TIERS = (
    (100, 200, 500, 1000, 2000, 3000, 5000, 10000, 20000, 50000, 100000, 200000, 500000),
    (150, 250, 300, 400, 600, 700, 800, 1500, 2500, 4000, 7500, 15000, 30000, 40000, 60000,
     80000, 150000, 250000, 300000, 400000, 600000, 800000),
    (1250, 1750, 3500, 6000, 8000, 25000),
)


class StereoImageItem(pg.ImageItem):  # type: ignore[misc]  # pyqtgraph ships no types
    """An ImageItem that reports hover and double-click positions in image pixel coordinates."""

    hovered = Signal(float, float)  # x, y px; NaN, NaN when the pointer leaves
    doubleClicked = Signal(float, float)  # x, y px

    def __init__(self) -> None:
        super().__init__(axisOrder="row-major")
        self.setAcceptHoverEvents(True)

    @staticmethod
    def to_pixel(pos: QPointF) -> tuple[float, float]:
        """Item coordinates (pixel corners at integers) -> pixel-centre coordinates."""
        return pos.x() - 0.5, pos.y() - 0.5

    def hoverEvent(self, ev: HoverEvent) -> None:  # noqa: N802 - pyqtgraph API
        if ev.isExit():
            self.hovered.emit(math.nan, math.nan)
            return
        x, y = self.to_pixel(ev.pos())
        self.hovered.emit(x, y)

    def mouseClickEvent(self, ev: MouseClickEvent) -> None:  # noqa: N802 - pyqtgraph API
        if ev.button() == Qt.MouseButton.LeftButton and ev.double():
            ev.accept()
            x, y = self.to_pixel(ev.pos())
            self.doubleClicked.emit(x, y)
            return
        super().mouseClickEvent(ev)

    def set_array(self, image: np.ndarray) -> None:
        """Show a uint8 image as it is (0 black, 255 white): no levels, no lookup table.

        Without levels pyqtgraph hands uint8 data straight to a QImage; with levels, even
        (0, 255), it rescales RGB images pixel by pixel on the UI thread (tens of ms).
        """
        if image.dtype != np.uint8:
            raise TypeError(f"live images must be uint8, not {image.dtype}")
        self.levels = None
        self.setImage(np.ascontiguousarray(image), autoLevels=False, autoDownsample=False)


_LABEL_GAP_PX = 6  # between a point and its label, screen px
_DOT_CLEAR_PX = 12  # a marker's dot (11 px): labels keep off it (its own label sits a gap away)
# choose_offset's costs, in places further down label_offsets' order of preference: a label
# crosses an edge of the region box rather than go 4 places further from its point, and hides
# another label or a point (per px² hidden) only when nothing else fits in the view
_EDGE_CROSSED = 3.5
_HIDDEN_COST = 1000.0
_EDGE_CLEAR_PX = 6  # the region box's 2 px outline and its handles' reach: labels keep off it


def _label_item(text: str, color: str, x: float, y: float) -> QGraphicsRectItem:
    """A text label with a dark box, constant size on screen, its top-left corner at (x, y);
    `place_label` then moves it beside its point (the transform's offset, screen px).

    Plain Qt items: pyqtgraph's TextItem re-computes its transform on every paint through a
    signal, which crashes PySide6 6.12 (a reference-count error, "bool_dealloc").
    """
    label = QGraphicsSimpleTextItem(text)
    font = QFont()
    font.setPointSize(10)
    font.setBold(True)
    label.setFont(font)
    label.setBrush(QBrush(QColor("white")))
    r = label.boundingRect()
    box = QGraphicsRectItem(QRectF(0, 0, r.width() + 8, r.height() + 4))
    box.setBrush(QBrush(QColor(0, 0, 0, 180)))
    box.setPen(QPen(QColor(color), 1.5))
    label.setParentItem(box)
    label.setPos(4, 2)
    # a thin line from the point to a label set away from it (by the labels around): which
    # point a label belongs to must be plain when several crowd together
    leader = QGraphicsLineItem(box)
    leader.setPen(QPen(QColor(color), 1.2))
    leader.setFlag(QGraphicsItem.GraphicsItemFlag.ItemStacksBehindParent, True)
    leader.hide()
    box.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
    box.setPos(x, y)
    return box


_LEADER_FROM_PX = 2 * _LABEL_GAP_PX + 2  # a label further than this from its point gets a line


def label_leader(box: QGraphicsRectItem) -> QGraphicsLineItem | None:
    """The line that ties a label to its point (shown only when the label was set away)."""
    for child in box.childItems():
        if isinstance(child, QGraphicsLineItem):
            return child
    return None


def _set_leader(box: QGraphicsRectItem, dx: float, dy: float) -> None:
    """Draw the label's line from its point (the box's origin, before the offset) to the
    nearest point of its rect when that is further than a gap or two away; hide it otherwise.
    (The line is a child of the box: in the box's frame, the point is at (-dx, -dy).)"""
    leader = label_leader(box)
    if leader is None:
        return
    r = box.rect()
    px, py = -dx, -dy
    nx, ny = min(max(px, r.left()), r.right()), min(max(py, r.top()), r.bottom())
    if math.hypot(nx - px, ny - py) <= _LEADER_FROM_PX:
        leader.hide()
        return
    # from the dot's rim, not its centre: the dot stays whole
    d = math.hypot(nx - px, ny - py)
    rim = _DOT_CLEAR_PX / 2 / d
    leader.setLine(px + (nx - px) * rim, py + (ny - py) * rim, nx, ny)
    leader.show()


def label_offsets(w: float, h: float, centred: bool = False) -> list[tuple[float, float]]:
    """Where a label of w x h screen px may go relative to its point, in order of preference:
    above-right, above-left, below-right, below-left, then further up and down and sideways
    (a ruler's middle label: below, then above, centred)."""
    g = _LABEL_GAP_PX
    rows = [k * (h + 2) for k in range(4)]  # not far: a label must stay next to its point
    if centred:
        out = []
        for step in rows:
            out += [(-w / 2, g + step), (-w / 2, -h - g - step)]
        return out
    right, left, above, below = g + 2, -w - g - 2, -h - g, g
    out = []
    for shift in (0.0, 0.5 * w):
        for step in rows:
            out += [(right + shift, above - step), (left - shift, above - step),
                    (right + shift, below + step), (left - shift, below + step)]
    return out


def _overlap(rect: QRectF, taken: list[QRectF]) -> float:
    """How much of `rect` the `taken` rects cover (px², overlaps counted once each)."""
    total = 0.0
    for t in taken:
        i = rect.intersected(t)
        if not i.isEmpty():
            total += i.width() * i.height()
    return total


def choose_offset(anchor: QPointF, size: tuple[float, float], bounds: QRectF | None,
                  taken: list[QRectF], centred: bool = False,
                  edges: Sequence[QRectF] = ()) -> tuple[float, float]:
    """Where a label goes: the offset of `label_offsets` whose label rect (screen px, at
    `anchor` + offset) lies inside `bounds`, covers none of `taken` (labels, dots) and, among
    those, costs least: crossing an edge of the region box (`edges`) is worth a few places
    further down the order of preference, never a hidden label or point.
    The first offset when none fits (`bounds` None: the view is not laid out)."""
    w, h = size
    offsets = label_offsets(w, h, centred)
    if bounds is None or bounds.isEmpty():
        return offsets[0]
    best, best_cost = None, math.inf
    for k, (dx, dy) in enumerate(offsets):
        rect = QRectF(anchor.x() + dx, anchor.y() + dy, w, h)
        if not bounds.contains(rect):
            continue
        crossed = sum(1 for e in edges if rect.intersects(e))
        cost = _HIDDEN_COST * _overlap(rect, taken) + _EDGE_CROSSED * crossed + k
        if cost < best_cost:
            best, best_cost = (dx, dy), cost
    return best if best is not None else offsets[0]


class _Marker:
    """A point with a label (and, for a ruler, a line to its partner) in one view."""

    def __init__(self, panel: ImagePanel, x: float, y: float, text: str, color: str,
                 line_to: tuple[float, float] | None = None, line_text: str = "") -> None:
        self.view = panel.view
        self.items = []
        self.labels: list[QGraphicsRectItem] = []
        self.centred: list[bool] = []  # per label: a ruler's middle label
        # the image points drawn as dots (a ruler's partner has its own marker): no label covers
        self.points = [(x + 0.5, y + 0.5)]
        if line_to is not None:
            line = pg.PlotCurveItem([line_to[0] + 0.5, x + 0.5], [line_to[1] + 0.5, y + 0.5],
                                    pen=pg.mkPen(color, width=2, style=Qt.PenStyle.DashLine))
            self.items.append(line)
            if line_text:
                mx, my = (line_to[0] + x) / 2 + 0.5, (line_to[1] + y) / 2 + 0.5
                self._add_label(panel, line_text, color, mx, my, centred=True)
        dot = pg.ScatterPlotItem([x + 0.5], [y + 0.5], size=11, symbol="o",
                                 pen=pg.mkPen("k", width=1.5), brush=pg.mkBrush(color))
        self.items.append(dot)
        if text:
            self._add_label(panel, text, color, x + 0.5, y + 0.5)
        for it in self.items:
            it.setZValue(10)
            self.view.addItem(it)

    def _add_label(self, panel: ImagePanel, text: str, color: str, x: float, y: float,
                   centred: bool = False) -> None:
        box = _label_item(text, color, x, y)
        taken = (panel.dot_rects(self.points) + panel.label_rects()
                 + [panel.label_rect(b) for b in self.labels])
        panel.place_label(box, taken, centred)
        self.items.append(box)
        self.labels.append(box)
        self.centred.append(centred)

    def remove(self) -> None:
        for it in self.items:
            self.view.removeItem(it)
        self.items.clear()
        self.labels.clear()
        self.centred.clear()


def colormap_lut(colormap_id: int) -> np.ndarray:
    """256 x 3 RGB uint8 lookup table of an OpenCV colour map (index = 8-bit level)."""
    ramp = np.arange(256, dtype=np.uint8).reshape(256, 1)
    bgr = cv2.applyColorMap(ramp, colormap_id).reshape(256, 3)
    return np.ascontiguousarray(bgr[:, ::-1])


def distance_ticks(scale: ColorScale, max_ticks: int = 7) -> list[tuple[float, str]]:
    """Tick positions (0..255 colour level) labelled with distance for a colour bar.

    The levels come from `scale` (core.colouring.ColorScale), the same mapping that made the
    colour view. Labels are round distances in m (below 1 m too: one unit rule everywhere).
    """
    fb = scale.fb_mm_px
    if not (fb > 0 and scale.near != scale.far):
        return []
    z_near, z_far = scale.distance_range_mm()
    if math.isinf(z_near):
        return []
    min_gap = 255.0 / (max_ticks + 1)

    def fmt(z: float, exact: bool = False) -> str:
        return f"{z / 1000:.2f} m" if exact else f"{z / 1000:g} m"

    ticks: list[tuple[float, str]] = []

    def free(level: float) -> bool:
        return all(abs(level - t) >= min_gap for t, _ in ticks)

    def end_label(z: float) -> str:
        for tier in _NICE_MM_TIERS:
            for nice in tier:
                if abs(z - nice) <= 0.01 * nice:
                    return fmt(nice)
        return fmt(z, exact=True)

    # the ends first: the whole range is always readable
    ticks.append((0.0, "∞" if math.isinf(z_far) else end_label(z_far)))
    ticks.append((255.0, end_label(z_near)))
    for tier in _NICE_MM_TIERS:
        for z in tier:
            if z_near <= z <= z_far:
                level = scale.level_of_distance(z)
                if free(level):
                    ticks.append((level, fmt(z)))
    return sorted(ticks)


TITLE_POINTS = 10  # a view's title
COLOR_BAR_AXIS_PX = 66  # the colour bar's axis: tick labels and the title up its side
COLOR_BAR_WIDTH_PX = 98  # the whole colour bar beside a colour view
_BAR_END_ROOM = 14.0  # colour levels of room beyond each end of the colour bar's ramp
# the colour bar's axis title: which kind of scale it is (the ticks give the range); short, as it
# runs up the side of the bar
SCALE_KIND_TITLES = {"view": "follows the view", "fixed": "fixed range",
                     "minmax": "each frame's range"}


class DistanceColorBar(pg.PlotItem):  # type: ignore[misc]  # pyqtgraph ships no types
    """A vertical colour bar whose axis is labelled in distance (near at the top)."""

    def __init__(self) -> None:
        super().__init__()
        self.setMouseEnabled(False, False)
        self.setMenuEnabled(False)
        self.hideButtons()
        self.hideAxis("bottom")
        self.hideAxis("left")
        self.showAxis("right")
        self.getAxis("right").setLabel("distance")
        # room for "1.25 m" beside the axis title running up the side (58 px let them touch)
        self.getAxis("right").setWidth(COLOR_BAR_AXIS_PX)
        self.setFixedWidth(COLOR_BAR_WIDTH_PX)
        self._img = pg.ImageItem(axisOrder="row-major")
        self.addItem(self._img)
        self._lut_id: int | None = None
        # the range the ticks were made for: (kind, mode, far, near)
        self._ticks_of: tuple[str, str, float, float] | None = None
        self.setXRange(0, 1, padding=0)
        # room above and below the ramp: the end labels are centred on the ends (the bottom
        # one was cut in half)
        self.setYRange(-_BAR_END_ROOM, 256 + _BAR_END_ROOM, padding=0)
        self.getViewBox().invertY(False)
        # no ticks until a frame gives the range (the axis' own 0..250 meant nothing)
        self._ticks: list[tuple[float, str]] = []
        self.getAxis("right").setTicks([[], []])
        self._caption = ""

    @property
    def caption(self) -> str:
        """What the bar's scale is, in words, e.g. "colours follow the view: 6–50 m"
        (core.colouring.color_scale_caption); empty before the first range."""
        return self._caption

    @property
    def title(self) -> str:
        """The axis title up the side of the bar: the kind of scale."""
        text: str = self.getAxis("right").labelText
        return text

    @property
    def ticks(self) -> list[tuple[float, str]]:
        """The (bar position, label) ticks the axis shows; empty before the first range."""
        return list(self._ticks)

    def set_scale(self, colormap_id: int, scale: ColorScale) -> None:
        """Show the colour map with distance ticks placed as `scale` maps them (called every
        frame: the ticks are made again only when the range changes)."""
        if colormap_id != self._lut_id:
            lut = colormap_lut(colormap_id)
            self._img.setImage(lut.reshape(256, 1, 3), autoLevels=False)
            self._img.setRect(0, 0, 1, 256)
            self._lut_id = colormap_id
        shown = (scale.kind, scale.mode, round(scale.far, 1), round(scale.near, 1))
        if shown == self._ticks_of:
            return
        self._ticks_of = shown
        self._ticks = [(t + 0.5, s) for t, s in distance_ticks(scale)]
        self.getAxis("right").setTicks([self._ticks, []])
        self._caption = color_scale_caption(scale)
        self.getAxis("right").setLabel(SCALE_KIND_TITLES.get(scale.mode, "distance"))
        self.setToolTip(self._caption)


class ImagePanel(pg.GraphicsLayoutWidget):  # type: ignore[misc]  # pyqtgraph ships no types
    """One titled live view: an image with markers, optionally with a distance colour bar."""

    hovered = Signal(str, float, float)  # view key, x, y px (NaN when left)
    doubleClicked = Signal(str, float, float)  # view key, x, y px
    regionChanged = Signal(tuple)  # (x0, y0, x1, y1) px of the region box, after a drag
    _full_title: str | None = None  # the title as set; None while the base class is built

    def __init__(self, key: str, title: str, color_bar: bool = False,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.key = key
        self.setMinimumSize(200, 160)
        self.ci.setContentsMargins(2, 2, 2, 2)
        self.title = self.addLabel(title, row=0, col=0, colspan=2, size=f"{TITLE_POINTS}pt")
        self._full_title = title
        self.view: pg.ViewBox = self.addViewBox(row=1, col=0, lockAspect=True, invertY=True,
                                                enableMenu=False)
        self.view.setDefaultPadding(0.0)
        self.view.disableAutoRange()
        self.item = StereoImageItem()
        self.view.addItem(self.item)
        self.color_bar: DistanceColorBar | None = None
        if color_bar:
            self.color_bar = DistanceColorBar()
            self.addItem(self.color_bar, row=1, col=1)
        self._shape: tuple[int, int] | None = None
        self._markers: list[_Marker] = []
        self.region_box: pg.RectROI | None = None
        # bound methods, never lambdas that hold `self`: a connection to a child's signal owning
        # the panel kept it alive until the child was destroyed, and a panel without a parent
        # was then destroyed from inside its own image item's destructor (at interpreter exit,
        # while PySide deletes what Python owns): its scene was cleared under the item being
        # destroyed, and the process ended with a segfault (exit 139) in about 1 of 6 quits
        self.item.hovered.connect(self._item_hovered)
        self.view.sigResized.connect(self._relayout_labels)
        self.view.sigRangeChanged.connect(self._relayout_labels)
        self.item.doubleClicked.connect(self._item_double_clicked)

    def _item_hovered(self, x: float, y: float) -> None:
        self.hovered.emit(self.key, x, y)

    def _item_double_clicked(self, x: float, y: float) -> None:
        self.doubleClicked.emit(self.key, x, y)

    def set_title(self, text: str) -> None:
        """Show `text` above the view, cut with "…" where the panel is narrower (a long title
        widened the panel's scene past its edge and cut the colour bar off); the whole of it
        is the title's tooltip."""
        self._full_title = text
        self._fit_title()

    def _fit_title(self) -> None:
        # pyqtgraph's constructor resizes before the title is made, and its close() after the
        # scene (the title with it) was cleared
        if self._full_title is None or self.closed:
            return
        text_item = self.title.item  # the label's text, as drawn (its font, its margins)
        margins = 2 * text_item.document().documentMargin() + 8  # and the layout's, px
        room = max(40, int(self.width() - margins))
        font = QFont(text_item.font())
        font.setPointSize(TITLE_POINTS)  # the label sets its size in its HTML, not its font
        shown = QFontMetrics(font).elidedText(self._full_title, Qt.TextElideMode.ElideRight, room)
        if shown != self.title.text:
            self.title.setText(shown)
        self.setToolTip(self._full_title if shown != self._full_title else "")

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt's name)
        self._fit_title()  # first: the scene is laid out to the view's size with this title
        super().resizeEvent(event)

    def set_image(self, image: np.ndarray) -> None:
        """Show a uint8 image; the view fits it the first time and when its size changes."""
        self.item.set_array(image)
        shape = image.shape[:2]
        if shape != self._shape:
            self._shape = shape
            self.fit()

    def fit(self) -> None:
        """Show the whole image (again, after a zoom or pan)."""
        if self._shape is not None:
            h, w = self._shape
            self.view.setRange(xRange=(0, w), yRange=(0, h), padding=0)

    def image_size(self) -> tuple[int, int] | None:
        """(width, height) px of the image shown, None before the first image."""
        return None if self._shape is None else (self._shape[1], self._shape[0])

    def add_marker(self, x: float, y: float, text: str, color: str = "#ffeb3b",
                   line_to: tuple[float, float] | None = None, line_text: str = "") -> None:
        """A point with a label at image pixel (x, y); with `line_to`, a dashed line from that
        pixel labelled `line_text` at its middle (the ruler). Each label goes beside its point
        where it stays inside the view and clear of the labels already there (as the view is
        zoomed now)."""
        self._markers.append(_Marker(self, x, y, text, color, line_to, line_text))
        self._relayout_labels()  # the labels already there keep off the new point too

    # ---- label placement (screen px of the view's scene) --------------------------------------
    def screen_pos(self, x: float, y: float) -> QPointF:
        """Where item coordinate (x, y) of the view (pixel corners at integers) is drawn,
        in scene px (the frame of the labels' offsets)."""
        self.view.updateMatrix()
        pos: QPointF = self.view.mapViewToScene(QPointF(x, y))
        return pos

    def view_rect(self) -> QRectF | None:
        """The part of the scene showing the image (the view box), None before layout."""
        r = self.view.sceneBoundingRect()
        return None if r.width() < 2 or r.height() < 2 else r

    def place_label(self, box: QGraphicsRectItem, taken: list[QRectF], centred: bool) -> None:
        """Move `box` beside its point, inside the view and clear of the `taken` rects."""
        r = box.rect()
        dx, dy = choose_offset(self.screen_pos(box.pos().x(), box.pos().y()),
                               (r.width(), r.height()), self.view_rect(), taken, centred,
                               self.edge_rects())
        box.setTransform(QTransform.fromTranslate(dx, dy))
        _set_leader(box, dx, dy)

    def _relayout_labels(self, *_args: object) -> None:
        """Place every label again, oldest first: labels keep their size on screen, so a zoom
        or a resize of the view moves them relative to each other."""
        taken = self.dot_rects()
        for m in self._markers:
            for box, centred in zip(m.labels, m.centred, strict=True):
                self.place_label(box, taken, centred)
                taken.append(self.label_rect(box))

    def label_rect(self, box: QGraphicsRectItem) -> QRectF:
        """The scene rect of a marker's label as the view is zoomed now."""
        t = box.transform()
        p = self.screen_pos(box.pos().x(), box.pos().y())  # the point it labels
        r = box.rect()
        return QRectF(p.x() + t.dx(), p.y() + t.dy(), r.width(), r.height())

    def dot_rects(self, more_points: Sequence[tuple[float, float]] = ()) -> list[QRectF]:
        """Where the markers' dots (and `more_points`, image coordinates) are drawn, scene px:
        no label may hide a point."""
        rects = []
        points = [p for m in self._markers for p in m.points] + list(more_points)
        half = _DOT_CLEAR_PX / 2
        for x, y in points:
            c = self.screen_pos(x, y)
            rects.append(QRectF(c.x() - half, c.y() - half, 2 * half, 2 * half))
        return rects

    def edge_rects(self) -> list[QRectF]:
        """The region box's outline as four strips, scene px: labels keep off its edges where
        a place nearby is free."""
        rects = []
        box = self.region()
        if box is not None:
            a, b = self.screen_pos(box[0], box[1]), self.screen_pos(box[2], box[3])
            x0, x1 = sorted((a.x(), b.x()))
            y0, y1 = sorted((a.y(), b.y()))
            e = _EDGE_CLEAR_PX / 2
            rects += [QRectF(x0 - e, y0 - e, x1 - x0 + 2 * e, 2 * e),  # top
                      QRectF(x0 - e, y1 - e, x1 - x0 + 2 * e, 2 * e),  # bottom
                      QRectF(x0 - e, y0 - e, 2 * e, y1 - y0 + 2 * e),  # left
                      QRectF(x1 - e, y0 - e, 2 * e, y1 - y0 + 2 * e)]  # right
        return rects

    def label_rects(self) -> list[QRectF]:
        """The scene rects of the labels drawn now."""
        return [self.label_rect(box) for m in self._markers for box in m.labels]

    # ---- the watched region ---------------------------------------------------------------------
    def show_region(self, box: tuple[int, int, int, int] | None) -> None:
        """Show a box the user can drag and resize over pixels x0..x1-1, y0..y1-1 (None: none);
        `regionChanged` reports where it was moved to."""
        if box is None:
            if self.region_box is not None:
                self.view.removeItem(self.region_box)
                self.region_box = None
                self._relayout_labels()
            return
        x0, y0, x1, y1 = box
        if self.region_box is None:
            roi = pg.RectROI((x0, y0), (x1 - x0, y1 - y0), pen=pg.mkPen(REGION_OK, width=2),
                             snapSize=1.0, translateSnap=True, scaleSnap=True, movable=True)
            roi.setZValue(9)
            roi.sigRegionChangeFinished.connect(self._region_moved)
            roi.sigRegionChangeFinished.connect(self._relayout_labels)
            self.view.addItem(roi)
            self.region_box = roi
        else:
            self.region_box.setPos((x0, y0), finish=False)
            self.region_box.setSize((x1 - x0, y1 - y0), finish=False)
        self._relayout_labels()

    def region(self) -> tuple[int, int, int, int] | None:
        """(x0, y0, x1, y1) px of the region box, None without one."""
        roi = self.region_box
        if roi is None:
            return None
        (x, y), (w, h) = roi.pos(), roi.size()
        return (int(round(x)), int(round(y)), int(round(x + w)), int(round(y + h)))

    def set_region_alarm(self, alarm: bool) -> None:
        if self.region_box is not None:
            pen = pg.mkPen(REGION_ALARM if alarm else REGION_OK, width=3 if alarm else 2)
            self.region_box.setPen(pen)
            self.region_box.currentPen = pen  # what it draws until hovered

    def _region_moved(self, *_args: object) -> None:
        self.regionChanged.emit(self.region())

    def clear_markers(self) -> None:
        for m in self._markers:
            m.remove()
        self._markers.clear()

    def marker_count(self) -> int:
        return len(self._markers)

    def scene_pos_of_pixel(self, x: float, y: float) -> QPointF:
        """Scene position of image pixel (x, y) (for tests and tooltips)."""
        self.view.updateMatrix()  # the view applies a new range lazily, at the next paint
        pos: QPointF = self.item.mapToScene(QPointF(x + 0.5, y + 0.5))
        return pos

    def widget_pos_of_pixel(self, x: float, y: float) -> QPoint:
        """Widget (viewport) position of image pixel (x, y), a QPoint."""
        pos: QPoint = self.mapFromScene(self.scene_pos_of_pixel(x, y))
        return pos


REGION_OK = "#69f0ae"
REGION_ALARM = "#ff1744"


def marker_color(valid: bool) -> str:
    return "#ffeb3b" if valid else "#ff5252"
