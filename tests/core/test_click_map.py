"""What the map says around a click: the histogram's mode, a nearer surface that hides a point,
the scatter of a patch about its plane."""

from types import SimpleNamespace

import numpy as np
import pytest

from stereo_gui.core.click_map import (
    SURROUND_FILL_RATIO,
    hidden_by_nearer,
    histogram_mode,
    plane_scatter_px,
    surrounding_estimate,
)


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


def _empty_patch_on_a_wall(fill_px: np.ndarray, match_scale: float = 0.5) -> SimpleNamespace:
    """A frame of a second-window preset matched at `match_scale` whose map shows a wall at 30 px
    everywhere but in the clicked patch (17x17 around (100, 100)), with `fill_px` as its filled
    (WLS) view."""
    final = np.full((200, 200), 30.0, np.float32)
    final[92:109, 92:109] = np.nan
    return SimpleNamespace(final_px=final, wls_px=fill_px, wls_confidence=None,
                           match_scale=match_scale, params=SimpleNamespace(check_block_size=5))


def test_the_surface_around_an_empty_patch_unless_the_fill_shows_something_nearer():
    """The wall around the click is its estimate where the fill agrees, and where a reduced
    preset's fill lies a little off the matches all over the region (its smoothing beside an
    edge: 10 % here). A fill nearer at the click than over the wall is an object in front the
    checks threw out; a fill far nearer than the wall everywhere (twice its disparity) says the
    matches around are the wrong ones: no estimate for either. At full resolution a fill off
    the matches is not forgiven."""
    flat = np.full((200, 200), 30.0, np.float32)
    assert surrounding_estimate(_empty_patch_on_a_wall(flat), 100, 100) == pytest.approx(30.0)
    off = flat + 3.3
    assert surrounding_estimate(_empty_patch_on_a_wall(off), 100, 100) == pytest.approx(30.0)
    assert surrounding_estimate(_empty_patch_on_a_wall(off, match_scale=1.0), 100, 100) is None
    bump = flat.copy()
    bump[90:111, 90:111] = 33.3  # the same fill at the click, the wall's own beside it
    assert surrounding_estimate(_empty_patch_on_a_wall(bump), 100, 100) is None
    far_off = np.full((200, 200), 30.0 * (SURROUND_FILL_RATIO + 0.5), np.float32)
    assert surrounding_estimate(_empty_patch_on_a_wall(far_off), 100, 100) is None


def test_a_patch_scatters_about_its_plane_not_along_its_slant():
    """A floor's slant (1.5 px of disparity per row) is no scatter; noise of 0.3 px about it
    is, and so is the same noise on a wall facing the rig; five values show no plane."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:9, 0:9].astype(np.float32)
    slant = 30.0 + 1.5 * (yy - 4) + 0.2 * (xx - 4)
    every = np.ones((9, 9), bool)
    assert plane_scatter_px(slant, every, 100, 50, 104, 54) == pytest.approx(0.0, abs=1e-4)
    noise = rng.normal(0.0, 0.3, (9, 9)).astype(np.float32)
    assert plane_scatter_px(slant + noise, every, 100, 50, 104, 54) == pytest.approx(0.3, rel=0.3)
    assert plane_scatter_px(30.0 + noise, every, 100, 50, 104, 54) == pytest.approx(0.3, rel=0.3)
    few = np.zeros((9, 9), bool)
    few[4, :5] = True
    assert plane_scatter_px(slant + noise, few, 100, 50, 104, 54) == 0.0
