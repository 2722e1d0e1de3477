"""Image panels: pixel mapping, double-click and hover signals, markers, distance colour bar."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication

from stereo_gui.core.colouring import ColorScale
from stereo_gui.qt.widgets.image_view import ImagePanel, colormap_lut, distance_ticks


@pytest.fixture
def panel(qtbot):
    p = ImagePanel("wls", "test view", color_bar=True)
    qtbot.addWidget(p)
    p.resize(700, 560)
    p.show()
    p.set_image(np.zeros((48, 64), np.uint8))
    return p


def test_double_click_reports_image_pixel(qtbot, panel):
    pos = panel.widget_pos_of_pixel(40, 10)
    left = Qt.MouseButton.LeftButton
    with qtbot.waitSignal(panel.doubleClicked, timeout=30000) as sig:
        qtbot.mousePress(panel.viewport(), left, pos=pos)
        qtbot.mouseRelease(panel.viewport(), left, pos=pos)
        qtbot.mouseDClick(panel.viewport(), left, pos=pos)
        qtbot.mouseRelease(panel.viewport(), left, pos=pos)
    key, x, y = sig.args
    assert key == "wls"
    assert abs(x - 40) <= 0.5 and abs(y - 10) <= 0.5


def test_hover_reports_pixel_and_exit(qtbot, panel):
    got = []
    panel.hovered.connect(lambda k, x, y: got.append((x, y)))
    qtbot.mouseMove(panel.viewport(), panel.widget_pos_of_pixel(20, 30))
    qtbot.waitUntil(lambda: bool(got), timeout=30000)
    x, y = got[-1]
    assert abs(x - 20) <= 0.5 and abs(y - 30) <= 0.5


def test_images_are_shown_as_they_are_and_fit_once(panel):
    img = np.full((48, 64, 3), 7, np.uint8)
    panel.set_image(img)
    assert panel.item.levels is None  # no auto-levels, no per-pixel rescaling
    panel.item.render()
    assert panel.item.qimage.pixelColor(3, 3).red() == 7
    with pytest.raises(TypeError):
        panel.set_image(img.astype(np.float32))
    panel.view.setRange(xRange=(0, 10), yRange=(0, 10), padding=0)
    panel.set_image(img)  # same size: the user's zoom stays
    assert panel.view.viewRange()[0][1] == pytest.approx(10, abs=2)
    panel.set_image(np.zeros((96, 128), np.uint8))  # new size: fit again
    assert panel.image_size() == (128, 96)


def test_markers_stay_until_cleared(panel):
    panel.add_marker(10, 10, "1.503 m")
    panel.add_marker(20, 10, "B", line_to=(10, 10))
    assert panel.marker_count() == 2
    panel.set_image(np.zeros((48, 64), np.uint8))
    assert panel.marker_count() == 2
    panel.clear_markers()
    assert panel.marker_count() == 0


def _image_panel(qtbot):
    p = ImagePanel("wls", "test view")
    qtbot.addWidget(p)
    p.resize(660, 520)
    p.show()
    p.set_image(np.zeros((480, 640), np.uint8))
    qtbot.waitExposed(p)
    return p


def test_labels_stay_inside_the_view_and_clear_of_each_other(qtbot):
    p = _image_panel(qtbot)
    bounds = p.view_rect()
    # a point at the very top (its label above it was cut off), points close together, a
    # point in the top-right corner and a ruler whose middle label sat on its end labels
    for x, y, text in ((30, 4, "3.002 m"), (45, 14, "2.996 m"), (60, 8, "✕ no texture"),
                       (632, 3, "1.234 m"), (300, 240, "A: 2.991 m")):
        p.add_marker(x, y, text)
    p.add_marker(330, 246, "B: 3.003 m", line_to=(300, 240), line_text="A–B 0.112 m")
    _assert_apart(p.label_rects(), bounds, 7)
    # a smaller view (the window resized, the toolbar wrapped) places them again
    p.resize(430, 340)
    qtbot.waitUntil(lambda: p.view_rect().width() < bounds.width() - 100, timeout=5000)
    p.fit()
    QApplication.processEvents()
    _assert_apart(p.label_rects(), p.view_rect(), 7)


def test_a_label_set_away_from_its_point_is_tied_to_it_by_a_line(qtbot):
    """Six readings clicked close together: the labels keep clear of each other, so some sit
    a few rows away, and it was not plain which point each one named. Each label further than
    a gap or two from its point has a line from the point's dot to the label; the others none."""
    from PySide6.QtWidgets import QGraphicsLineItem

    p = _image_panel(qtbot)
    points = [(300, 240), (312, 250), (306, 262), (322, 244), (296, 256), (318, 266)]
    for i, (x, y) in enumerate(points):
        p.add_marker(x, y, f"{1 + i / 10:.3f} m")
    QApplication.processEvents()
    labels = p.label_rects()
    _assert_apart(labels, p.view_rect(), 6)
    dots = [p.screen_pos(x + 0.5, y + 0.5) for x, y in points]
    lines = [it for it in p.view.scene().items()
             if isinstance(it, QGraphicsLineItem) and it.isVisible()]

    def gap(rect, c):
        nx, ny = min(max(c.x(), rect.left()), rect.right()), min(max(c.y(), rect.top()),
                                                                rect.bottom())
        return ((nx - c.x()) ** 2 + (ny - c.y()) ** 2) ** 0.5

    far = [i for i, (r, c) in enumerate(zip(labels, dots, strict=True)) if gap(r, c) > 14]
    assert far, "six crowded labels all fit beside their points: the test shows nothing"
    assert len(lines) == len(far)
    for line in lines:
        a = line.mapToScene(line.line().p1())
        b = line.mapToScene(line.line().p2())
        # one end at the rim of a far label's dot, the other on that label's rect
        owner = [i for i in far if ((a.x() - dots[i].x()) ** 2 + (a.y() - dots[i].y()) ** 2)
                 ** 0.5 <= 7 and gap(labels[i], b) <= 1]
        assert len(owner) == 1, (a, b)


def test_labels_are_placed_again_when_the_view_shrinks(qtbot):
    p = _image_panel(qtbot)
    p.add_marker(100, 200, "2.994 m")
    p.add_marker(200, 200, "3.005 m")  # side by side, apart, at this size
    _assert_apart(p.label_rects(), p.view_rect(), 2)
    p.resize(330, 270)  # half the size: the points come closer, the labels do not shrink
    qtbot.waitUntil(lambda: p.view_rect().width() < 400, timeout=5000)
    p.fit()
    QApplication.processEvents()
    _assert_apart(p.label_rects(), p.view_rect(), 2)


def _assert_apart(rects, bounds, n):
    assert len(rects) == n
    for i, r in enumerate(rects):
        assert bounds.contains(r), (i, r, bounds)
        for other in rects[i + 1:]:
            assert not r.intersects(other), (r, other)


def test_colour_bar_shows_no_placeholder_ticks_before_the_first_frame(panel):
    assert panel.color_bar.ticks == []
    lo, hi = panel.color_bar.getViewBox().viewRange()[1]
    assert lo < 0 and hi > 256  # room for the end labels


def test_distance_ticks_are_round_and_in_order():
    fb = 700.0 * 110.0  # f px * B mm
    for scale in (ColorScale("distance", 3000.0, 500.0, fb),
                  ColorScale("disparity", fb / 3000.0, fb / 500.0, fb)):  # 0.5 .. 3 m
        ticks = distance_ticks(scale)
        labels = [t[1] for t in ticks]
        assert "3 m" in labels and "1 m" in labels and "0.5 m" in labels
        levels = [t[0] for t in ticks]
        assert levels == sorted(levels) and levels[0] == 0.0 and levels[-1] == 255.0
        # 1 m sits where the colour view puts a pixel at 1 m
        one = dict((s, t) for t, s in ticks)["1 m"]
        assert one == pytest.approx(float(scale.level(np.float32(fb / 1000.0))), abs=1e-3)
    # linear in distance: 1 m is 1/5 of the way from 0.5 m (top) to 3 m (bottom)
    one = dict((s, t) for t, s in distance_ticks(ColorScale("distance", 3000.0, 500.0, fb)))
    assert one["1 m"] == pytest.approx(255 * 2000 / 2500, abs=1e-3)
    # near range only: millimetres
    # one unit rule: metres below a metre too ("0.3 m", not "300 mm")
    labels = [s for _t, s in distance_ticks(ColorScale("distance", 900, 300, fb))]
    assert labels and all(s.endswith(" m") for s in labels) and "0.3 m" in labels
    # a min-max range down to zero disparity reaches infinity
    assert distance_ticks(ColorScale("disparity", 0.0, fb / 500.0, fb))[0][1] == "∞"
    assert distance_ticks(ColorScale("disparity", 5.0, 5.0, fb)) == []


def test_color_bar_matches_opencv_colormap(panel):
    import cv2

    lut = colormap_lut(cv2.COLORMAP_OCEAN)
    ref = cv2.applyColorMap(np.array([[200]], np.uint8), cv2.COLORMAP_OCEAN)[0, 0, ::-1]
    assert tuple(lut[200]) == tuple(ref)
    panel.color_bar.set_scale(cv2.COLORMAP_OCEAN, ColorScale("disparity", 20.0, 150.0, 77000.0))
    ticks = panel.color_bar.ticks
    assert ticks and not any(math.isnan(t) for t, _s in ticks)


def test_a_panel_is_freed_when_its_last_reference_goes(qtbot):
    """Its own image item's signals must not keep it alive: a panel held only by a connection of
    its child was destroyed from inside the child's destructor at exit (a segfault)."""
    import gc
    import weakref

    panel = ImagePanel("left", "Rectified left")
    seen = []
    panel.hovered.connect(lambda *args: seen.append(args))
    panel.item.hovered.emit(3.0, 4.0)  # still forwarded, with the panel's key
    assert seen == [("left", 3.0, 4.0)]
    ref = weakref.ref(panel)
    del panel
    gc.collect()
    assert ref() is None


def test_labels_keep_off_the_points_and_the_region_box(qtbot):
    p = _image_panel(qtbot)
    # the watched region at its default place, points next to its edges and to each other,
    # and a ruler across it: no label hides a dot or another label
    p.show_region((240, 180, 400, 300))
    for x, y, text in ((236, 200, "3.002 m"), (256, 186, "2.996 m"), (290, 195, "2.990 m"),
                       (396, 296, "1.234 m"), (320, 240, "A: 2.991 m")):
        p.add_marker(x, y, text)
    p.add_marker(380, 250, "B: 3.003 m", line_to=(320, 240), line_text="A–B 0.112 m")
    labels = p.label_rects()
    _assert_apart(labels, p.view_rect(), 7)
    dots = p.dot_rects()
    assert len(dots) == 6 and len(p.edge_rects()) == 4
    _assert_clear(labels, dots)
    # the box moved under the labels: they are placed again
    p.show_region((200, 160, 300, 260))
    _assert_clear(p.label_rects(), p.dot_rects())


def test_a_label_goes_where_it_crosses_no_edge_of_the_region(qtbot):
    p = _image_panel(qtbot)
    p.show_region((240, 180, 400, 300))
    # just inside the top edge: above-right (the first choice) would lie across the edge
    p.add_marker(300, 186, "2.996 m")
    # just inside the right edge: right of it would lie across the edge
    p.add_marker(394, 240, "3.010 m")
    _assert_clear(p.label_rects(), p.edge_rects())


def _assert_clear(rects, obstacles):
    for r in rects:
        for o in obstacles:
            assert r.intersected(o).isEmpty(), (r, o)


def test_the_colour_bar_says_which_scale_it_is(panel):
    """A range that follows the view and a fixed one read differently on the bar (its title up
    the side, its caption in words with the range), and a new range changes both."""
    import cv2

    fb = 718.856 * 537.2
    bar = panel.color_bar
    assert bar.caption == ""
    view = ColorScale("disparity", fb / 50000.0, fb / 6000.0, fb, 0.0, "view")
    bar.set_scale(cv2.COLORMAP_OCEAN, view)
    assert bar.caption == "colours follow the view: 6–50 m"
    assert bar.title == "follows the view" and bar.toolTip() == bar.caption
    assert [s for _t, s in bar.ticks][::len(bar.ticks) - 1] == ["50 m", "6 m"]
    bar.set_scale(cv2.COLORMAP_OCEAN, ColorScale("distance", 3000.0, 500.0, fb))
    assert bar.caption == "fixed colours: 0.5–3 m" and bar.title == "fixed range"
    bar.set_scale(cv2.COLORMAP_OCEAN, ColorScale("disparity", fb / 3000.0, fb / 500.0, fb))
    assert bar.caption == "colours stretched to each frame: 0.5–3 m"
    assert bar.title == "each frame's range"


def test_a_long_title_is_cut_to_the_panel_and_the_colour_bar_stays_whole(qtbot):
    """Six views three by two: the WLS view's long title widened its panel's scene past the
    panel's edge and cut off the colour bar's labels. The title is cut with "…" (whole in the
    tooltip) and everything stays inside the panel, also after set_title and a resize."""
    title = "WLS filtered (a picture: holes filled, not measured)"
    p = ImagePanel("wls", title, color_bar=True)
    qtbot.addWidget(p)
    p.resize(300, 206)
    p.show()
    p.set_image(np.zeros((480, 640, 3), np.uint8))
    qtbot.waitExposed(p)

    def inside() -> bool:
        bar = p.color_bar.geometry()
        return p.ci.geometry().width() <= p.width() + 0.5 and bar.right() <= p.width() + 0.5

    qtbot.waitUntil(inside, timeout=5000)
    assert p.title.text.endswith("…") and p.toolTip() == title
    p.set_title(title + " and more words")
    p.resize(290, 206)
    qtbot.waitUntil(inside, timeout=5000)
    p.resize(900, 500)
    qtbot.waitUntil(lambda: p.title.text == title + " and more words", timeout=5000)
    assert p.toolTip() == ""
