"""Coverage by image region and readiness to calibrate, in words a person can follow."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.coverage import (
    MIN_PAIRS,
    REGIONS,
    cell_counts,
    empty_regions,
    readiness,
    regions_filled,
    regions_in_words,
)
from stereo_gui.core.detect import detect_pair
from stereo_gui.sources.sim import RigConfig, SimRig

SIZE = (640, 480)


def test_regions_are_named_and_cover_the_grid():
    cells = [c for cells in REGIONS.values() for c in cells]
    assert len(cells) == 25 and len(set(cells)) == 25
    counts = cell_counts([np.array([[10.0, 10.0], [630.0, 470.0]] * 3)], SIZE)
    empty = empty_regions(counts)
    assert "top-left corner" not in empty and "bottom-right corner" not in empty
    assert "top-right corner" in empty and "centre" in empty


def test_words_name_each_image():
    text = regions_in_words({"left": ["top-left corner", "right edge"],
                             "right": ["top-left corner"]})
    assert text == "the top-left corner of both images and the right edge of the left image"
    assert regions_in_words({"left": [], "right": []}) == ""


def test_a_pose_that_fills_a_region_is_told_apart():
    counts = cell_counts([np.tile([320.0, 240.0], (20, 1))], SIZE)
    assert regions_filled(np.array([[5.0, 5.0], [20.0, 30.0]]), counts, SIZE) == ["top-left corner"]
    assert regions_filled(np.array([[320.0, 240.0]]), counts, SIZE) == []


@pytest.mark.slow
def test_readiness_follows_coverage_not_a_pair_count():
    board = BoardSpec(7, 5, 30.0, "charuco", 22.0)
    rig = SimRig(RigConfig(board=board), seed=71)
    rng = np.random.default_rng(0)
    centre = [rig.random_board_pose(rng, where=(0.5, 0.5)) for _ in range(MIN_PAIRS + 2)]
    pairs = [detect_pair(str(i), *rig.render_board_pair(p, rng), board)
             for i, p in enumerate(centre)]
    r = readiness(pairs, board, SIZE)
    assert r.pairs >= MIN_PAIRS and not r.ready  # plenty of pairs, all in the middle
    words = " ".join(r.missing())
    assert "top-left corner" in words and "bottom-right corner" in words
    assert r.summary().startswith("Not ready yet")
    # the rig's calibration set visits the regions both cameras share, corners included (the
    # far side of each image, the left image's left edge and the right image's right edge,
    # needs views that the other camera does not share)
    spread = [detect_pair(str(i), l, rr, board)
              for i, (l, rr) in enumerate(rig.calibration_set(18))]
    r = readiness(spread, board, SIZE)
    far = {"left": ("top-left corner", "left edge", "bottom-left corner"),
           "right": ("top-right corner", "right edge", "bottom-right corner")}
    for side in ("left", "right"):
        assert not [e for e in r.empty[side] if e not in far[side]], r.empty
    assert r.tilt_ok and r.distance_ok and r.ready, r.summary()
    assert r.summary().startswith("Ready to calibrate")
