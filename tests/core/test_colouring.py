"""Colouring a disparity map: colour scales, the view range, the legend, the colour view."""


import cv2
import numpy as np
import pytest

from stereo_gui.core.colouring import NO_MATCH_BGR, color_scale, colorize
from stereo_gui.core.preset import DisplayParams
from stereo_gui.core.stereo_calibration import StereoCalibration

W, H = 240, 160  # px


def calib(w=W, h=H, f=300.0, b=100.0):
    return StereoCalibration.identity((w, h), f, b)


def test_fixed_colour_range_maps_a_distance_to_a_fixed_colour():
    c = calib(f=700.0, b=110.0)
    fb = 700.0 * 110.0
    p = DisplayParams(color_range="fixed", color_z_near_mm=500.0, color_z_far_mm=3000.0)

    def paint(d, params=p):
        d = np.asarray(d, np.float32)
        return colorize(d, color_scale(d, params, c), params.colormap)

    def ocean(level):
        return cv2.applyColorMap(np.full((1, 1), level, np.uint8), cv2.COLORMAP_OCEAN)[0, 0]

    d = np.full((4, 4), fb / 500.0, np.float32)
    d[0, 0] = np.nan
    near = paint(d)
    assert (near[1, 1] == ocean(255)).all() and (near[0, 0] == NO_MATCH_BGR).all()
    assert (paint(np.full((2, 2), fb / 6000.0))[0, 0] == ocean(0)).all()  # farther than far
    # linear in distance: 1.75 m, halfway between 0.5 and 3 m, gets the middle colour
    assert (paint(np.full((1, 1), fb / 1750.0))[0, 0] == ocean(127)).all()
    # min-max (the reference loop): one farther pixel in the same map changes the rest's colour
    p2 = DisplayParams(color_range="minmax")
    d[2, 2] = 100.0
    d2 = d.copy()
    d2[3, 3] = 10.0
    assert not np.array_equal(paint(d, p2)[2, 2], paint(d2, p2)[2, 2])
    assert np.array_equal(paint(d)[2, 2], paint(d2)[2, 2])


@pytest.mark.parametrize("kind, far, near", [("distance", 3000.0, 500.0),
                                             ("disparity", 20.0, 160.0)])
def test_colorize_paints_the_levels_of_its_scale(kind, far, near):
    """The fast per-frame colouring agrees with ColorScale.level (what the colour bar uses)."""
    from stereo_gui.core.colouring import ColorScale

    rng = np.random.default_rng(5)
    d = rng.uniform(5.0, 200.0, (60, 80)).astype(np.float32)
    d[::7, ::5] = np.nan
    scale = ColorScale(kind, far, near, 700.0 * 110.0)
    color = colorize(d, scale, "ocean")
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_OCEAN)[:, 0]
    level = np.rint(np.clip(scale.level(d), 0, 255))
    ok = np.isfinite(d)
    assert (color[~ok] == NO_MATCH_BGR).all()
    for dl in (-1, 0, 1):
        near_level = lut[np.clip(level[ok] + dl, 0, 255).astype(int)]
        ok_here = (color[ok] == near_level).all(axis=1)
        if dl == -1:
            matched = ok_here
        else:
            matched |= ok_here
    assert matched.all()


# ---- the colour range that follows the view ---------------------------------------------------
KITTI_F, KITTI_B = 718.856, 537.2  # px, mm: a road scene, everything farther than 3 m


def _road_map(z_near_mm: float, z_far_mm: float, h: int = 120, w: int = 400, invalid=0.2,
              seed=1) -> np.ndarray:
    """A disparity map (px, NaN invalid) of distances spread evenly from near to far."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(z_near_mm, z_far_mm, (h, w))
    d = (KITTI_F * KITTI_B / z).astype(np.float32)
    d[rng.random((h, w)) < invalid] = np.nan
    return d


def test_readable_ranges_round_outwards_to_readable_numbers():
    from stereo_gui.core.colouring import readable_range

    assert readable_range(6100.0, 47000.0) == (6000.0, 50000.0)
    assert readable_range(1234.0, 2890.0) == (1200.0, 3000.0)
    assert readable_range(796.0, 2971.0) == (700.0, 3000.0)
    assert readable_range(480.0, 3100.0) == (400.0, 4000.0)
    assert readable_range(1600.0, 2770.0) == (1500.0, 3000.0)
    assert readable_range(3000.0000001, 2999.9999) == (3000.0, 4000.0)  # a wall: still a ramp
    assert readable_range(99.0, 101.0) == (80.0, 120.0)


def test_the_view_range_follows_the_distances_in_view():
    """A road scene 6-45 m away: the fixed 0.5-3 m range paints all of it the far colour (a
    black depth view); the range that follows the view is 6-50 m and spreads it over
    the colour map, near bright. The legend says which scale it is."""
    from stereo_gui.core.colouring import color_scale_caption

    c = calib(w=400, h=120, f=KITTI_F, b=KITTI_B)
    d = _road_map(6100.0, 45000.0)
    fixed = color_scale(d, DisplayParams(color_range="fixed"), c)
    assert np.nanmax(fixed.level(d)) < 0  # beyond the far end everywhere: all black
    view = color_scale(d, DisplayParams(color_range="view"), c)
    assert view.mode == "view"
    assert view.distance_range_mm() == pytest.approx((6000.0, 50000.0))
    levels = np.clip(view.level(d[np.isfinite(d)]), 0, 255)
    assert levels.min() < 10 and levels.max() > 245 and np.percentile(levels, 90) > 128
    def colours(scale):
        return len(np.unique(colorize(d, scale, "ocean")[np.isfinite(d)], axis=0))

    assert colours(fixed) == 1 and colours(view) > 150
    assert color_scale_caption(view) == "colours follow the view: 6–50 m"
    assert color_scale_caption(fixed) == "fixed colours: 0.5–3 m"
    assert color_scale_caption(color_scale(d, DisplayParams(), c)).startswith(
        "colours stretched to each frame: ")


def test_the_view_range_ignores_a_few_stray_distances():
    c = calib(w=400, h=120, f=KITTI_F, b=KITTI_B)
    d = _road_map(6100.0, 45000.0)
    d[:1, :] = KITTI_F * KITTI_B / 900.0  # 0.8 % of the pixels at 0.9 m
    d[1:2, :] = 0.2  # ... and as many far beyond
    view = color_scale(d, DisplayParams(color_range="view"), c)
    assert view.distance_range_mm() == pytest.approx((6000.0, 50000.0))


def test_the_view_range_stays_put_under_small_changes_and_moves_with_the_scene():
    from stereo_gui.core.colouring import view_range

    fallback = (500.0, 3000.0)
    first = view_range((6100.0, 47000.0), fallback)
    assert first == (6000.0, 50000.0)
    # noise around the rounding steps: on its own each frame would round elsewhere
    for seen in ((5900.0, 51000.0), (6050.0, 51000.0), (5600.0, 55000.0), (6900.0, 39000.0)):
        assert view_range(seen, fallback) != first
        assert view_range(seen, fallback, first) == first
    # the scene comes nearer than the range by a clear margin, or goes farther
    assert view_range((4000.0, 47000.0), fallback, first) == (4000.0, 50000.0)
    assert view_range((6100.0, 70000.0), fallback, first) == (6000.0, 70000.0)
    # the scene fills little of the colours: a narrower range fits it
    assert view_range((20500.0, 45000.0), fallback, first) == (20000.0, 50000.0)
    # ... but not when the narrower range is hardly narrower
    assert view_range((7000.0, 14000.0), fallback, (6000.0, 15000.0)) == (6000.0, 15000.0)


def test_a_view_range_does_not_flicker_over_a_sequence_of_noisy_frames():
    """Frames whose distances wander by a few per cent around the rounding steps: the range
    is set once and never changes."""
    from stereo_gui.core.colouring import view_range

    rng = np.random.default_rng(4)
    ranges, previous = [], None
    for _ in range(200):
        seen = (1500.0 * rng.uniform(0.95, 1.05), 2500.0 * rng.uniform(0.95, 1.05))
        previous = view_range(seen, (500.0, 3000.0), previous)
        ranges.append(previous)
    assert len(set(ranges)) == 1


def test_the_view_range_of_a_stream_follows_the_previous_scale():
    """color_scale takes the scale of the frame before (the caller keeps it): a small change
    keeps the range, a new scene moves it, another calibration's scale is not taken."""
    c = calib(w=400, h=120, f=KITTI_F, b=KITTI_B)
    p = DisplayParams(color_range="view")
    first = color_scale(_road_map(6100.0, 45000.0), p, c)
    nearer = _road_map(5400.0, 40000.0, seed=2)
    assert color_scale(nearer, p, c).distance_range_mm() != first.distance_range_mm()
    assert color_scale(nearer, p, c, first).distance_range_mm() == pytest.approx((6000.0, 50000.0))
    moved = color_scale(_road_map(1600.0, 2800.0), p, c, first)
    assert moved.distance_range_mm() == pytest.approx((1500.0, 3000.0))
    other = calib(w=400, h=120, f=KITTI_F, b=2 * KITTI_B)
    assert color_scale(nearer, p, other, first).distance_range_mm() != pytest.approx(
        first.distance_range_mm())


def test_nothing_valid_falls_back_to_the_presets_near_and_far():
    c = calib(w=400, h=120, f=KITTI_F, b=KITTI_B)
    p = DisplayParams(color_range="view", color_z_near_mm=700.0, color_z_far_mm=4000.0)
    empty = np.full((120, 400), np.nan, np.float32)
    scale = color_scale(empty, p, c)
    assert scale.mode == "view" and scale.distance_range_mm() == pytest.approx((700.0, 4000.0))
    assert (colorize(empty, scale, "ocean") == NO_MATCH_BGR).all()
    # in a stream, an empty frame keeps the range the frames before had (the legend holds)
    before = color_scale(_road_map(6100.0, 45000.0), p, c)
    assert color_scale(empty, p, c, before).distance_range_mm() == pytest.approx(
        (6000.0, 50000.0))
    # a few stray pixels are not a view either
    empty[5, 5:10] = 30.0
    assert color_scale(empty, p, c).distance_range_mm() == pytest.approx((700.0, 4000.0))
