"""What the map says around a click: the histogram's mode, a nearer surface that hides a point."""

import numpy as np
import pytest

from stereo_gui.core.click_map import hidden_by_nearer, histogram_mode


def test_histogram_mode_finds_the_peak_between_bins():
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.normal(40.3, 0.2, 2000), rng.uniform(10, 60, 300)])
    assert histogram_mode(values) == pytest.approx(40.3, abs=0.1)


def test_a_far_match_left_of_a_nearer_surface_is_not_seen():
    """A wall at disparity 27 px from column 40 on; at the image's left edge a cluster of wrong
    matches at 4 px (a point 7 times farther) with nothing between: the right camera sees the
    wall at that cluster's column, so the cluster's point is not seen. A background that is
    matched all the way to a nearer object is seen; so is the wall itself."""
    m = np.full((9, 200), np.nan, np.float32)
    m[:, 40:] = 27.0
    m[:, 4:13] = 4.0
    assert hidden_by_nearer(m, 8, 0, 9, 4.0, 1.0) == (True, None)
    assert hidden_by_nearer(m, 60, 0, 9, 27.0, 1.0) == (False, None)
    scene = np.full((9, 200), 10.0, np.float32)
    scene[:, 100:] = 80.0  # a near object right of a far background, both matched
    assert hidden_by_nearer(scene, 20, 0, 9, 10.0, 1.0) == (False, None)
    assert hidden_by_nearer(scene, 95, 0, 9, 10.0, 1.0)[0]  # the object covers its match (u = 85)


def test_the_shadow_a_nearer_surface_casts_hides_only_what_it_covers():
    """Lampshade1 (Middlebury 2006): a wall at 15 px, matched for 6 px right of the click, then
    the empty strip the lamp (28 px, from 23 px right of the click) hides from the right camera.
    The strip is the wall's, not the lamp's: the right camera sees the click's point (its match
    at x - 15 lies left of the lamp's leftmost match), and it was refused as not seen. The map
    cannot tell the shadow from the lamp unmatched: the lamp's disparity goes to the images."""
    m = np.full((9, 300), np.nan, np.float32)
    m[:, :144] = 15.0
    m[:, 160:] = 28.0
    assert hidden_by_nearer(m, 137, 0, 9, 15.0, 1.0) == (False, 28.0)
    # a reading of the wall inside the shadow is hidden: its match, 150 - 15, the lamp covers
    # from 160 - 28 on
    assert hidden_by_nearer(m, 150, 0, 9, 15.0, 1.0) == (True, None)
