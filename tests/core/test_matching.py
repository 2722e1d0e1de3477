"""The frame pipeline: parameters, fixed point, stages, reduced resolution, presets on Middlebury."""

import math

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import (
    NO_MATCH_BGR,
    NOT_SEEN_BGR,
    DisplayParams,
    MatcherParams,
    Preset,
    StereoPipeline,
    ThreadParams,
    color_scale,
    colorize,
    fixed_to_px,
)
from stereo_gui.core.stereo_calibration import StereoCalibration

W, H, SHIFT = 240, 160, 12  # px; the synthetic pair is a plane at constant disparity SHIFT


def textured_pair(shift=SHIFT, w=W, h=H, seed=3):
    """An already rectified pair of a fronto-parallel textured plane: right(u) = left(u + shift)."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.random((h, w + shift)).astype(np.float32), (0, 0), 1.0)
    big = cv2.normalize(big, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    left = big[:, :w]
    right = big[:, shift:shift + w]
    return cv2.cvtColor(left, cv2.COLOR_GRAY2BGR), cv2.cvtColor(right, cv2.COLOR_GRAY2BGR)


def calib(w=W, h=H, f=300.0, b=100.0):
    return StereoCalibration.identity((w, h), f, b)


def test_params_validate_and_round_trip():
    with pytest.raises(InputError, match="block_size"):
        MatcherParams(block_size=4)
    with pytest.raises(InputError, match="num_disparities"):
        MatcherParams(num_disparities=100)
    with pytest.raises(InputError, match="mode"):
        MatcherParams(mode="fast")
    p = Preset("x", matcher=MatcherParams(mode="3way", scale=0.5, z_min_mm=400.0),
               display=DisplayParams(colormap="jet"), threads=ThreadParams(parallel=True))
    assert Preset.from_dict(p.to_dict()) == p
    assert Preset.from_dict({"block_size": 5, "no_such_key": 1}).matcher.block_size == 5
    # the reference loop's own names are understood
    reference = Preset.from_dict({"window_size": 3, "minDisparity": 2, "numDisparities": 128,
                               "lmbda": 80000}).matcher
    assert (reference.block_size, reference.min_disparity, reference.wls_lambda) == (3, 2, 80000)
    with pytest.raises(InputError, match="must be a number"):
        Preset.from_dict({"block_size": "5"})
    with pytest.raises(InputError, match="true or false"):
        Preset.from_dict({"wls": 1})
    with pytest.raises(InputError, match="whole number"):
        Preset.from_dict({"block_size": 3.5})
    assert Preset.from_dict({"block_size": 5.0}).matcher.block_size == 5
    with pytest.raises(InputError, match="color_z_far_mm"):
        Preset.from_dict({"color_z_near_mm": 900, "color_z_far_mm": 800})
    with pytest.raises(InputError, match="cv_threads"):
        Preset.from_dict({"cv_threads": -1})


def test_a_preset_is_a_flat_object_of_its_parts_fields_in_the_files_order():
    """Files hold one flat object: the matcher's, display's and threads' fields after the name,
    as before the parts were split; a flat change goes to the part that declares the field."""
    d = Preset().to_dict()
    assert list(d)[:3] == ["name", "description", "block_size"]
    assert list(d)[-6:] == ["colormap", "color_range", "color_z_near_mm", "color_z_far_mm",
                            "parallel", "cv_threads"]
    p = Preset().replace(name="n", block_size=5, colormap="jet", parallel=True)
    assert (p.name, p.matcher.block_size, p.display.colormap, p.threads.parallel) == \
        ("n", 5, "jet", True)
    assert p.get("colormap") == "jet" and p.get("block_size") == 5
    with pytest.raises(TypeError):
        Preset().replace(no_such_parameter=1)


def test_default_penalties_are_the_reports():
    p = MatcherParams(block_size=3)
    assert (p.p1_value, p.p2_value) == (8 * 3 * 9, 32 * 3 * 9)
    assert MatcherParams(p1=10, p2=99).p2_value == 99


def test_disparity_range_from_working_distances():
    c = calib(f=700.0, b=110.0)  # f*B = 77000 px mm
    lo, num = MatcherParams(z_min_mm=500.0).disparity_range(c)
    assert lo == 0 and num % 16 == 0 and lo + num - 1 >= 154 and num - 16 < 155
    lo, num = MatcherParams(z_min_mm=500.0, z_max_mm=2000.0).disparity_range(c)
    assert lo == math.floor(77000 / 2000) and lo + num - 1 >= 154
    assert MatcherParams(min_disparity=2, num_disparities=128).disparity_range(c) == (2, 128)


def test_fixed_point_is_divided_once_and_invalid_is_nan():
    d16 = np.array([[16 * 10 + 8, 16, 32]], np.int16)  # 10.5 px, (min-1)*16 invalid, 2 px
    out = fixed_to_px(d16, min_disparity=2)
    assert out[0, 0] == pytest.approx(10.5) and np.isnan(out[0, 1]) and out[0, 2] == 2.0
    assert fixed_to_px(d16, 2, factor=2.0)[0, 0] == pytest.approx(21.0)


@pytest.mark.parametrize("scale,mode,parallel", [(1.0, "sgbm", False), (0.5, "3way", True)])
def test_pipeline_recovers_a_constant_disparity(scale, mode, parallel):
    left, right = textured_pair()
    p = Preset(matcher=MatcherParams(min_disparity=0, num_disparities=32, block_size=5,
                                     scale=scale, mode=mode, wls_lambda=8000.0),
               threads=ThreadParams(parallel=parallel))
    with StereoPipeline(calib(), p) as pipe:
        r = pipe.process(left, right)
    assert r.size == (W, H)
    for m in (r.disparity_px, r.closed_px, r.wls_px, r.final_px):
        assert m.shape == (H, W) and m.dtype == np.float32
    # every column is searched: depth from just right of the strip the right camera cannot see
    # (SHIFT px) to the right edge, not only right of minDisparity + numDisparities
    core = np.s_[20:-20, SHIFT + 8:-20]
    raw = r.disparity_px[core]
    assert np.isfinite(raw).mean() > 0.9
    assert np.nanmedian(raw) == pytest.approx(SHIFT, abs=0.25)
    assert np.nanmedian(r.wls_px[core]) == pytest.approx(SHIFT, abs=0.25)
    assert np.isfinite(r.final_px[core]).mean() > 0.9
    # the strip the right camera cannot see has no depth, and says why
    assert not np.isfinite(r.final_px[:, :SHIFT - 1]).any()
    assert r.not_seen is not None and not np.isfinite(r.disparity_px[r.not_seen]).any()
    # the final map is the WLS output where its left-right confidence holds, nothing elsewhere
    conf = r.wls_confidence > 0
    assert np.array_equal(r.valid, np.isfinite(r.final_px))
    assert not r.valid[~conf].any()
    np.testing.assert_array_equal(r.final_px[r.valid], r.wls_px[r.valid])
    assert r.color_bgr.shape == (H, W, 3) and r.color_bgr.dtype == np.uint8
    # invalid pixels have colours of their own (black is OCEAN's far end): the strip the right
    # camera cannot see grey, no match dark red
    assert (r.color_bgr[r.not_seen] == NOT_SEEN_BGR).all()
    assert (r.color_bgr[~r.valid & ~r.not_seen] == NO_MATCH_BGR).all()
    assert {"rectify", "match", "closing", "wls", "colormap", "total"} <= set(r.timings_ms)
    lo, hi = r.disparity_range_px
    assert lo <= 0 and hi >= 31


def test_parallel_matchers_give_the_same_result_as_sequential():
    left, right = textured_pair()
    base = MatcherParams(min_disparity=0, num_disparities=32, block_size=5)
    a = StereoPipeline(calib(), base).process(left, right)
    with StereoPipeline(calib(), Preset(matcher=base, threads=ThreadParams(parallel=True))) as pipe:
        b = pipe.process(left, right)
    np.testing.assert_array_equal(a.disparity_px, b.disparity_px)
    np.testing.assert_array_equal(a.wls_px, b.wls_px)


def test_set_params_applies_to_the_next_frame_and_without_wls_final_is_closed():
    left, right = textured_pair()
    pipe = StereoPipeline(calib(), MatcherParams(min_disparity=0, num_disparities=32))
    pipe.set_params(MatcherParams(min_disparity=0, num_disparities=32, wls=False, closing_kernel=0,
                                  bilateral=True))
    assert pipe.params.matcher.wls  # not yet
    r = pipe.process(left, right)
    assert not pipe.params.matcher.wls and r.wls_px is None
    assert r.final_px is r.closed_px is r.disparity_px
    assert "bilateral" in r.timings_ms


def test_a_closed_pipeline_refuses_frames():
    left, right = textured_pair()
    with StereoPipeline(calib(), MatcherParams(min_disparity=0, num_disparities=32)) as pipe:
        assert pipe.process(left, right).valid.any()
    # its maps and matchers are gone: a frame is refused, not passed through unrectified
    with pytest.raises(RuntimeError, match="closed"):
        pipe.process(left, right)
    with pytest.raises(RuntimeError, match="closed"):
        pipe.rectify(left, right)
    pipe.close()  # again: nothing happens


def test_wrong_image_size_is_an_input_error():
    left, right = textured_pair()
    pipe = StereoPipeline(calib(w=W + 2), MatcherParams(min_disparity=0, num_disparities=32))
    with pytest.raises(InputError, match="calibration is for"):
        pipe.process(left, right)


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


def test_final_output_is_never_worse_than_the_seeds_raw_sgbm_on_middlebury(shared_data):
    """The quality preset's final map (what the view shows and every export writes) has a bad-2.0
    rate no higher than the seed's raw SGBM and a density no lower (within 2 points), on both
    benchmark pairs; and it is better than its own raw map (the WLS output is kept only where
    its left-right confidence holds, so the filter invents no values)."""
    from stereo_gui.commands.accuracy import middlebury_scores

    scores = {(s.pair, s.preset, s.stage): s for s in middlebury_scores(shared_data / "middlebury")}
    assert {pair for pair, _, _ in scores} == {"teddy", "tsukuba"}
    for pair in ("teddy", "tsukuba"):
        seed_raw = scores[pair, "seed", "raw"]
        for preset in ("quality", "live"):
            final, raw = scores[pair, preset, "final"], scores[pair, preset, "raw"]
            assert final.bad <= seed_raw.bad, (pair, preset, final, seed_raw)
            assert final.density >= seed_raw.density - 0.02, (pair, preset, final, seed_raw)
            assert final.bad < raw.bad, (pair, preset, final, raw)


@pytest.mark.parametrize("kind, far, near", [("distance", 3000.0, 500.0),
                                             ("disparity", 20.0, 160.0)])
def test_colorize_paints_the_levels_of_its_scale(kind, far, near):
    """The fast per-frame colouring agrees with ColorScale.level (what the colour bar uses)."""
    from stereo_gui.core.matching import ColorScale

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


def _reference_and_seed(seed=5):
    from stereo_gui.core.reference_loop import ReferenceLoop
    from stereo_gui.files.presets import load_preset
    from stereo_gui.sources.sim import Scene, SimRig

    rig = SimRig(seed=seed)
    calib = rig.true_calibration()
    left, right = rig.render_scene(Scene.demo(), np.random.default_rng(1))
    reference = ReferenceLoop(calib).process(left, right)
    ours = StereoPipeline(calib, load_preset("seed")).process(left, right)
    return reference, ours


def test_seed_preset_is_the_reference_loop_pixel_for_pixel():
    """The seed preset gives exactly what the reference loop's code (Lanczos remap, its SGBM, the
    right matcher and WLS made from it, 3x3 closing) gives, on a calibrated (not identity) rig."""
    reference, ours = _reference_and_seed()
    np.testing.assert_array_equal(ours.rectified_left, reference.rectified_left)
    np.testing.assert_array_equal(ours.rectified_right, reference.rectified_right)
    np.testing.assert_array_equal(ours.disparity_px, reference.disparity_px)  # NaN where invalid
    np.testing.assert_array_equal(ours.wls_px, fixed_to_px(reference.filtered16, 2))
    # the loop closes its normalised float map; closing commutes with that affine map
    closed = (reference.closing * 128 + 2).astype(np.float32)
    ok = np.isfinite(ours.closed_px)
    np.testing.assert_allclose(ours.closed_px[ok], closed[ok], atol=1e-4)
    assert (closed[~ok] < 2).all()
    assert ours.not_seen is None  # the seed keeps the reference loop's dead band


def test_presets_keep_their_matcher_checks_with_wls():
    """OpenCV's createDisparityWLSFilter switches off the uniqueness, speckle and left-right
    checks of the matcher it is made from; live and quality keep the checks their parameters
    name (their raw map is the one the same matcher gives without WLS), the seed reproduces the
    reference loop's raw map, made without them."""
    from stereo_gui.files.presets import load_preset

    left, right = textured_pair()
    for name, kept in (("live", True), ("quality", True), ("seed", False)):
        preset = load_preset(name).replace(z_min_mm=None, min_disparity=0, num_disparities=32,
                                           parallel=False)
        with_wls = StereoPipeline(calib(), preset).process(left, right).disparity_px
        alone = StereoPipeline(calib(), preset.replace(wls=False)).process(left, right)
        assert np.array_equal(with_wls, alone.disparity_px, equal_nan=True) is kept, name


def test_every_column_is_searched_whatever_the_range():
    """A wide disparity range does not blank the left third of the image: depth right of the
    strip the right camera cannot see (SHIFT px) at any range."""
    left, right = textured_pair()
    for num in (32, 96, 160):
        p = MatcherParams(min_disparity=0, num_disparities=num, block_size=5, wls_lambda=8000.0)
        r = StereoPipeline(calib(), p).process(left, right)
        band = r.final_px[20:-20, SHIFT + 8:num]
        assert band.size and np.isfinite(band).mean() > 0.9, num
        assert np.nanmedian(band) == pytest.approx(SHIFT, abs=0.25)
    with pytest.raises(InputError, match="too narrow"):  # the reference loop's way: columns run out
        StereoPipeline(calib(), MatcherParams(min_disparity=0, num_disparities=240,
                                              full_frame=False)).process(left, right)


def test_new_parameters_validate():
    with pytest.raises(InputError, match="remap_interpolation"):
        MatcherParams(remap_interpolation="nearest")
    with pytest.raises(InputError, match="pre_filter_cap"):
        MatcherParams(pre_filter_cap=64)
    with pytest.raises(InputError, match="true or false"):
        Preset.from_dict({"full_frame": "yes"})


def test_a_principal_point_offset_shifts_the_disparity_range_and_the_colours():
    """With doffs = cx_right - cx_left, d = f B / Z - doffs: the matcher searches the disparities
    of the working distances and a colour still means the same distance."""
    from stereo_gui.core.matching import ColorScale

    fb, doffs = 700.0 * 110.0, 30.0
    c = StereoCalibration.identity((W, H), 700.0, 110.0, doffs_px=doffs)
    assert c.disparity_offset_px == pytest.approx(doffs)
    d_min, d_max = MatcherParams(z_min_mm=500.0, z_max_mm=2000.0).disparity_limits(c)
    assert d_min == pytest.approx(fb / 2000.0 - doffs) and d_max == pytest.approx(fb / 500.0 - doffs)
    lo, num = MatcherParams(z_min_mm=500.0, z_max_mm=2000.0).disparity_range(c)
    assert lo == math.floor(fb / 2000.0 - doffs) and lo + num - 1 >= fb / 500.0 - doffs
    # fixed colours: the disparity of 1.75 m (halfway between 0.5 and 3 m) gets the middle colour
    p = DisplayParams(color_range="fixed", color_z_near_mm=500.0, color_z_far_mm=3000.0)
    d = np.full((2, 2), fb / 1750.0 - doffs, np.float32)
    scale = color_scale(d, p, c)
    assert scale.doffs_px == pytest.approx(doffs)
    assert scale.level_of_distance(1750.0) == pytest.approx(127.5, abs=1e-3)
    ocean = cv2.applyColorMap(np.full((1, 1), 127, np.uint8), cv2.COLORMAP_OCEAN)[0, 0]
    assert (colorize(d, scale, "ocean")[0, 0] == ocean).all()
    # the fast colouring agrees with ColorScale.level here too
    s2 = ColorScale("distance", 3000.0, 500.0, fb, doffs)
    dd = np.array([[fb / 800.0 - doffs, fb / 2500.0 - doffs]], np.float32)
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_OCEAN)[:, 0]
    levels = np.rint(s2.level(dd)).astype(int)[0]
    got = colorize(dd, s2, "ocean")[0]
    for g, lv in zip(got, levels, strict=True):
        assert any((g == lut[np.clip(lv + k, 0, 255)]).all() for k in (-1, 0, 1))


def test_a_wide_frame_is_matched_at_most_max_match_width_wide():
    """The live preset keeps its speed on a 1280x720 camera: it matches at most 320 px wide."""
    p = MatcherParams(min_disparity=0, num_disparities=64, block_size=5, scale=0.5,
                      max_match_width=320)
    assert p.effective_scale(640) == 0.5 and p.effective_scale(1280) == 0.25
    assert MatcherParams(scale=0.5).effective_scale(1280) == 0.5
    left, right = textured_pair(shift=24, w=1280, h=160, seed=4)
    left, right = cv2.GaussianBlur(left, (0, 0), 2.0), cv2.GaussianBlur(right, (0, 0), 2.0)
    r = StereoPipeline(calib(w=1280, h=160), p).process(left, right)
    assert r.match_scale == 0.25 and r.final_px.shape == (160, 1280)
    assert np.nanmedian(r.disparity_px[20:-20, 80:-20]) == pytest.approx(24, abs=0.5)
    with pytest.raises(InputError, match="max_match_width"):
        MatcherParams(max_match_width=10)


def test_a_smaller_left_right_check_keeps_the_final_map():
    """check_scale 0.5 runs the right matcher (which serves only the left-right check behind the
    WLS confidence) on images halved again: the final map keeps nearly all of its pixels and the
    same disparity, and the confidence stays as high where the scene is textured."""
    left, right = textured_pair(shift=24, w=320, h=200)
    base = MatcherParams(min_disparity=0, num_disparities=64, block_size=5, wls_lambda=8000.0)
    full = StereoPipeline(calib(w=320, h=200), base)
    small = StereoPipeline(calib(w=320, h=200), base.replace(check_scale=0.5))
    a, b = full.process(left, right), small.process(left, right)
    core = np.s_[20:-20, 24 + 8:-20]
    assert np.isfinite(b.final_px[core]).mean() > 0.97 * np.isfinite(a.final_px[core]).mean()
    assert np.nanmedian(b.final_px[core]) == pytest.approx(24, abs=0.25)
    # the left-right check behind the WLS confidence trusts the textured core as much
    assert np.median(b.wls_confidence[core]) >= np.median(a.wls_confidence[core]) > 200
    with pytest.raises(InputError, match="check_scale"):
        MatcherParams(check_scale=0.1)


def test_blank_sets_nan_where_the_mask_is_set_in_place():
    from stereo_gui.core.matching import blank

    rng = np.random.default_rng(1)
    a = rng.random((30, 40)).astype(np.float32)
    mask = rng.random((30, 40)) < 0.3
    for m in (mask, mask.astype(np.uint8) * 255):
        b = a.copy()
        blank(b, m)
        np.testing.assert_array_equal(np.isnan(b), mask)
        np.testing.assert_array_equal(b[~mask], a[~mask])
    view = a.copy()[:, ::2]  # not contiguous: OpenCV would fill a copy, so numpy does it
    blank(view, mask[:, ::2])
    np.testing.assert_array_equal(np.isnan(view), mask[:, ::2])


def test_unseen_masks_made_in_the_band_equal_those_of_the_whole_map():
    from stereo_gui.core.matching import unseen_columns, unseen_mask, unseen_strip

    rng = np.random.default_rng(5)
    h, w, largest, margin = 40, 120, 30.0, 3.0
    band = unseen_columns(largest, margin, w)
    assert band == 35 and unseen_columns(largest, margin, 20) == 20
    assert unseen_columns(-5.0, 0.0, w) == 0
    d = (rng.random((h, w)) * largest).astype(np.float32)
    d[:, 0] = largest  # the largest disparity at the edge: the widest strip there can be
    d[rng.random((h, w)) < 0.4] = np.nan
    d[3, :] = np.nan  # a row without any reading
    d[5, :60] = np.nan  # rows whose first reading lies right of the band
    d[6, :band] = np.nan
    d[6, band:] = largest
    for m in (0.0, margin):
        np.testing.assert_array_equal(unseen_mask(d, m, band), unseen_mask(d, m))
        np.testing.assert_array_equal(unseen_strip(d, m, band), unseen_strip(d, m))
        assert not unseen_mask(d, m)[:, band:].any() and not unseen_strip(d, m)[:, band:].any()
    assert unseen_strip(d, margin)[6, :band - 2].all()  # set by a reading beyond the band


def test_blank_and_paint_in_the_band_only():
    from stereo_gui.core.matching import blank, paint

    rng = np.random.default_rng(2)
    mask = rng.random((20, 50)) < 0.5
    mask[:, 15:] = False
    a = rng.random((20, 50)).astype(np.float32)
    whole, banded = a.copy(), a.copy()
    blank(whole, mask)
    blank(banded, mask, 15)
    np.testing.assert_array_equal(whole, banded)
    img = rng.integers(0, 255, (20, 50, 3), dtype=np.uint8)
    whole, banded = img.copy(), img.copy()
    paint(whole, mask, (1, 2, 3))
    paint(banded, mask, (1, 2, 3), 15)
    np.testing.assert_array_equal(whole, banded)
    paint(banded, mask, (9, 9, 9), 0)  # an empty band paints nothing
    np.testing.assert_array_equal(whole, banded)
    beyond = np.zeros_like(mask)
    beyond[:, 30:] = True  # set only right of the band: not looked at
    kept = a.copy()
    blank(kept, beyond, 15)
    np.testing.assert_array_equal(kept, a)
    kept = img.copy()
    paint(kept, beyond, (1, 2, 3), 15)
    np.testing.assert_array_equal(kept, img)


def test_the_masks_made_in_the_band_give_the_whole_frames_results(monkeypatch):
    """The pipeline makes and applies its "not seen" masks only in the band `unseen_columns`
    gives for the maps' largest disparity: the results are those of masks over the whole width.
    On a wall at the working range's near end, where the strip is widest, and with a small WLS
    lambda, whose output overshoots the matcher's range (up to int16's limit)."""
    from stereo_gui.core import matching
    from stereo_gui.files.presets import load_preset
    from stereo_gui.sources.sim import RigConfig, Scene, SimRig

    rig = SimRig(RigConfig.for_size((640, 480)), seed=0)
    cal = rig.true_calibration(alpha=0.0)
    left, right = rig.render_scene(Scene.wall(460.0), np.random.default_rng(3))
    banded = matching.unseen_columns
    fields = ("disparity_px", "closed_px", "wls_px", "final_px", "color_bgr", "valid",
              "not_seen")
    overshoots = False
    for params in (load_preset("live"), load_preset("quality"),
                   load_preset("live").replace(wls_lambda=100.0, wls_sigma=0.5)):
        results = []
        for columns in (banded, lambda largest, margin, width: width):
            monkeypatch.setattr(matching, "unseen_columns", columns)
            with StereoPipeline(cal, params) as pipe:
                results.append(pipe.process(left, right))
        ours, whole = results
        for f in fields:
            np.testing.assert_array_equal(getattr(ours, f), getattr(whole, f), err_msg=f)
        band = ours.not_seen_cols
        assert ours.not_seen[:, :band].any() and not ours.not_seen[:, band:].any()
        if np.nanmax(ours.wls_px) > ours.disparity_range_px[1]:
            overshoots = True  # the case where the band follows the maps, not the range
        else:
            assert band < ours.size[0] // 3
    assert overshoots


def test_blank_mask_finds_noise_alone_whatever_the_texture_would_be():
    """Nothing but sensor noise is blank; a weak smooth texture (weaker than the noise per
    pixel, but correlated over pixels) is not, nor is a strong texture as fine as noise."""
    from stereo_gui.core.matching import blank_mask

    rng = np.random.default_rng(8)
    noise = rng.normal(0, 1.5, (120, 160))
    smooth = cv2.GaussianBlur(rng.normal(0, 1.0, (120, 160)), (0, 0), 3.0) * 15.0  # spread 1.4
    fine = rng.normal(0, 30.0, (120, 160))
    for texture, blank in ((0.0, True), (smooth, False), (fine, False)):
        img = np.clip(128 + noise + texture, 0, 255).astype(np.uint8)
        mask = blank_mask(img, 12, 1)
        share = mask[20:-20, 20:-20].mean()
        assert share > 0.95 if blank else share < 0.05, (blank, share)


def test_sensor_noise_of_a_uint8_image_is_the_median_of_its_response_counted():
    """The whole-number count gives np.median's value (odd and even counts, flat images)."""
    from stereo_gui.core.matching import sensor_noise

    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    rng = np.random.default_rng(3)
    for shape in ((3, 3), (3, 4), (5, 7), (37, 51), (120, 160)):
        for sigma in (0.0, 0.7, 3.0, 40.0):
            img = np.clip(128 + rng.normal(0, sigma, shape), 0, 255).astype(np.uint8)
            response = cv2.filter2D(img.astype(np.float32), -1, kernel)[1:-1, 1:-1]
            expected = 1.4826 * float(np.median(np.abs(response))) / 6.0
            assert sensor_noise(img) == pytest.approx(expected, abs=1e-12)
            assert sensor_noise(img.astype(np.float32)) == pytest.approx(expected, abs=1e-9)


def test_nearest_source_is_where_a_nearest_neighbour_resize_takes_each_pixel_from():
    from stereo_gui.core.matching import _nearest_source

    for small, big in (((160, 120), (320, 240)), ((111, 93), (222, 185)), ((80, 67), (443, 370))):
        src = np.arange(small[0] * small[1], dtype=np.float32).reshape(small[1], small[0])
        out = cv2.resize(src, big, interpolation=cv2.INTER_NEAREST)
        ys, xs = _nearest_source(big[1], small[1]), _nearest_source(big[0], small[0])
        assert np.array_equal(out, src[ys[:, None], xs[None, :]])


def test_agreement_keeps_the_mean_where_both_windows_match_and_agree():
    from stereo_gui.core.matching import agreement

    a = np.array([[80, 80, -16, 160, 32]], np.int16)  # x16: 5, 5, no match, 10, 2
    b = np.array([[88, 112, 80, 176, 32]], np.int16)  # x16: 5.5, 7, 5, 11, 2
    out = agreement(a, b, 0, 1.0, (2.5, 100.0))
    assert out[0, 0] == 5.25  # agree within 1 px: their mean
    assert np.isnan(out[0, 1])  # 2 px apart
    assert np.isnan(out[0, 2])  # one found no match
    assert out[0, 3] == 10.5  # exactly 1 px apart still agrees
    assert np.isnan(out[0, 4])  # below the kept range (the searched range's end)


def test_occluded_finds_a_far_match_that_a_nearer_surface_covers():
    """Row: a wrong far match (d 2) at x 8 and a surface at d 27 from x 32: the right camera sees
    the surface at column 5 (32 - 27), where the far match would also be seen (8 - 2 = 6): the
    far one is hidden. The surface's own pixels are not, nor is a far match that lies clear of
    it; `reach` lets the surface go on under the empty pixels just left of it."""
    from stereo_gui.core.matching import occluded

    row = np.full((1, 60), np.nan, np.float32)
    row[0, 8] = 2.0
    row[0, 32:] = 27.0
    mask = occluded(row, 1.0)
    assert mask[0, 8] and not mask[0, 32:].any()
    row[0, 8] = np.nan
    row[0, 3] = 2.0  # matches at column 1: left of what the surface covers (from 5)
    assert not occluded(row, 1.0)[0, 3]
    assert occluded(row, 1.0, reach_px=4)[0, 3]  # the surface taken on to x 28: column 1


def test_enlarge_interpolates_within_a_surface_and_keeps_edges_and_holes():
    from stereo_gui.core.matching import enlarge

    m = np.array([[10.0, 10.5, 30.0, np.nan]], np.float32).repeat(2, axis=0)
    big = enlarge(m, (8, 4), 1.0)
    assert big.shape == (4, 8)
    assert 10.0 < big[0, 2] < 10.5  # between two pixels of one surface: interpolated
    assert set(np.unique(big[:, 3:6][np.isfinite(big[:, 3:6])])) <= {10.5, 30.0}  # the edge
    assert np.isnan(big[:, 7]).all()  # the hole stays a hole


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
    from stereo_gui.core.matching import readable_range

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
    from stereo_gui.core.matching import color_scale_caption

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
    from stereo_gui.core.matching import view_range

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
    from stereo_gui.core.matching import view_range

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
