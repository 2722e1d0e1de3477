"""The Capture tab's coverage maps and the words under them name the same regions."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF

from stereo_gui.core.coverage import GRID, MIN_POINTS_PER_CELL, REGIONS, Readiness
from stereo_gui.qt.widgets.coverage import CoverageWidget


def _colour_of_cell(cmap, row: int, col: int):
    """(r, g, b) drawn at the middle of one cell of a map, as on the screen."""
    image = cmap.grab().toImage()
    ratio = image.devicePixelRatio()
    p = cmap.mapFromScene(cmap.view.mapViewToScene(QPointF(col + 0.5, row + 0.5)))
    c = image.pixelColor(int(p.x() * ratio), int(p.y() * ratio))
    return c.red(), c.green(), c.blue()


def _green(rgb) -> bool:
    r, g, b = rgb
    return g > 100 and g > 1.5 * r and g > 1.5 * b


def test_a_region_named_as_empty_is_not_shown_green(qtbot):
    """One cell of the centre with a point too few: the words say the centre is still empty,
    and the map draws that cell amber (it was green) and outlines the centre."""
    left = np.full((GRID, GRID), 50)
    left[2, 2] = MIN_POINTS_PER_CELL - 1
    right = np.full((GRID, GRID), 50)
    r = Readiness({"left": left, "right": right}, (640, 480), pairs=12, tilt=0.8,
                  size_spread=0.3)
    widget = CoverageWidget()
    qtbot.addWidget(widget)
    widget.resize(360, 400)
    widget.show()
    qtbot.waitExposed(widget)
    widget.set_readiness(r)
    assert "the centre of the left image" in widget.readiness_label.text()
    assert widget.left_map.outlined_regions() == ["centre"]
    assert widget.right_map.outlined_regions() == []
    assert not _green(_colour_of_cell(widget.left_map, 2, 2))
    assert _colour_of_cell(widget.left_map, 2, 2)[0] > 150  # amber: too few points
    assert _green(_colour_of_cell(widget.left_map, 1, 1))
    assert _green(_colour_of_cell(widget.right_map, 2, 2))


def test_every_region_the_words_name_is_outlined_on_its_map(qtbot):
    """Random counts: the regions outlined on each map are those the readiness names, image by
    image (the far sides included), and a region not named has every cell green."""
    rng = np.random.default_rng(5)
    widget = CoverageWidget()
    qtbot.addWidget(widget)
    widget.resize(360, 400)
    widget.show()
    qtbot.waitExposed(widget)
    for _ in range(5):
        counts = {side: rng.choice([0, 1, 2, 10, 40], size=(GRID, GRID), p=[.1, .1, .1, .3, .4])
                  for side in ("left", "right")}
        r = Readiness(counts, (640, 480), pairs=12, tilt=0.8, size_spread=0.3)
        widget.set_readiness(r)
        for side, cmap in (("left", widget.left_map), ("right", widget.right_map)):
            assert cmap.outlined_regions() == r.empty[side]
            for name, cells in REGIONS.items():
                if name not in r.empty[side]:
                    assert all(_green(_colour_of_cell(cmap, row, col)) for row, col in cells)


def test_the_grid_fills_its_map(qtbot):
    """The maps were about 60 px square inside 160 x 125 px: the view's own range took in the
    outlines and left a margin of nothing around the grid. The grid now takes the map's height
    (or width, whichever is less) but for a small margin."""
    w = CoverageWidget()
    qtbot.addWidget(w)
    w.resize(350, 330)
    w.show()
    qtbot.waitExposed(w)
    for cmap in (w.left_map, w.right_map):
        grid = cmap.item.sceneBoundingRect()
        assert min(grid.width(), grid.height()) >= 0.85 * min(cmap.width(), cmap.height())
        assert cmap.height() >= 110  # room enough to tell a cell from its neighbours
