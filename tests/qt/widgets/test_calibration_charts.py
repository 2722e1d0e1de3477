"""The Calibration tab's rectification check: side by side with one zoom, anaglyph, blend; the
error chart's legend room."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.qt.widgets.calibration_charts import (Y_HEADROOM, ErrorBarChart,
                                                      RectifiedPairView, anaglyph)


@pytest.fixture
def view(qtbot):
    v = RectifiedPairView()
    qtbot.addWidget(v)
    v.resize(800, 400)
    v.show()
    return v


def _pair():
    rng = np.random.default_rng(3)
    left = rng.integers(0, 255, (60, 80, 3), dtype=np.uint8)
    right = np.roll(left, -5, axis=1)
    return left, right


def test_side_by_side_halves_zoom_and_pan_together(view, qtbot):
    left, right = _pair()
    view.show_pair("7", left, right)
    assert view.shown == "7" and view.mode == "side"
    assert all(vb.isVisible() for vb in view.views)
    assert view.images[1].image.shape == (60, 80, 3)
    view.views[1].setRange(xRange=(10, 30), yRange=(5, 20), padding=0)  # zoom the right half
    qtbot.waitUntil(lambda: abs(view.views[0].viewRange()[0][0] - 10) < 1, timeout=5000)
    (x0, x1), (y0, y1) = view.views[0].viewRange()
    assert x1 == pytest.approx(30, abs=1) and y0 == pytest.approx(5, abs=1)


def test_anaglyph_and_blend_put_both_images_in_one(view):
    left, right = _pair()
    view.show_pair("7", left, right)
    view.set_mode("anaglyph")
    img = view.images[0].image
    want = anaglyph(left, right)
    assert img.shape == (60, 80, 3) and np.array_equal(img, want)
    assert not np.array_equal(img[..., 0], img[..., 1])  # red from the left, cyan the right
    assert not view.views[1].isVisible()
    assert "anaglyph" in view.title.text
    view.set_mode("blend")
    mixed = view.images[0].image.astype(int)
    expect = (left[:, :, ::-1].astype(int) + right[:, :, ::-1].astype(int)) / 2
    assert np.abs(mixed - expect).max() <= 1
    view.set_mode("side")
    assert view.views[1].isVisible() and "left | right" in view.title.text
    view.clear_pair()
    assert view.shown is None and view.images[0].image is None


def test_error_chart_legend_sits_above_the_bars_whole(qtbot):
    chart = ErrorBarChart()
    qtbot.addWidget(chart)
    names = [f"pair-{i}" for i in range(12)]
    chart.set_errors(names, [0.1] * 11 + [0.6], [0.12] * 12)
    chart.set_excluded({"pair-3"})
    chart.set_threshold(0.3)
    chart.select("pair-11")  # the tallest bar, its frame 5 % higher still
    assert chart.viewRange()[1][1] == pytest.approx(0.6 * Y_HEADROOM)
    chart.set_threshold(0.9)  # above every bar: the line stays in view, to be dragged down
    assert chart.viewRange()[1][1] == pytest.approx(0.9 * Y_HEADROOM)
    chart.set_threshold(0.3)
    for width, height in ((700, 190), (420, 220)):  # the tab at 1366 px wide, and narrow
        chart.resize(width, height)
        chart.show()
        qtbot.waitUntil(lambda w=width: chart.plotItem.width() > w - 30, timeout=5000)
        # the row above the plot follows the legend's height once the layout has run
        qtbot.waitUntil(lambda: chart.legend_rect().bottom()
                        <= chart.plotItem.vb.sceneBoundingRect().top() + 1, timeout=5000)
        legend = chart.legend_rect()
        plot = chart.plotItem.vb.sceneBoundingRect()
        whole = chart.plotItem.sceneBoundingRect()
        assert len(chart.plotItem.legend.items) == 5
        assert whole.contains(legend), (legend, whole)  # not cut off at either side
        assert legend.bottom() <= plot.top() + 1, (legend, plot)  # over no bar nor line
