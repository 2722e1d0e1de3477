"""The Calibration tab's rectification check: side by side with one zoom, anaglyph, blend; the
error chart's legend room."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.qt.widgets.calibration_charts import (LEGEND_HEADROOM, ErrorBarChart,
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


def test_error_chart_leaves_room_for_its_legend(qtbot):
    chart = ErrorBarChart()
    qtbot.addWidget(chart)
    chart.set_errors(["a", "b", "c"], [0.2, 0.4, 0.3], [0.25, 0.35, 0.5])
    assert chart.viewRange()[1][1] == pytest.approx(0.5 * LEGEND_HEADROOM)
