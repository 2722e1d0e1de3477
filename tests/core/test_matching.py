"""The frame pipeline: stages, reduced resolution, the band masks, presets on Middlebury."""

import math

import cv2
import numpy as np
import pytest

from stereo_gui.core.colouring import (
    NO_MATCH_BGR,
    NOT_SEEN_BGR,
    color_scale,
    colorize,
)
from stereo_gui.core.disparity import fixed_to_px
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import DisplayParams, MatcherParams, Preset, ThreadParams
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


def test_a_principal_point_offset_shifts_the_disparity_range_and_the_colours():
    """With doffs = cx_right - cx_left, d = f B / Z - doffs: the matcher searches the disparities
    of the working distances and a colour still means the same distance."""
    from stereo_gui.core.colouring import ColorScale

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


def _matched_at(p: MatcherParams, size: tuple[int, int], scale: float) -> None:
    """A textured plane 24 px apart, `size` (w, h), runs at `scale` and still reads 24 px."""
    w, h = size
    left, right = textured_pair(shift=24, w=w, h=h, seed=4)
    left, right = cv2.GaussianBlur(left, (0, 0), 2.0), cv2.GaussianBlur(right, (0, 0), 2.0)
    r = StereoPipeline(calib(w=w, h=h), p).process(left, right)
    assert r.match_scale == scale and r.final_px.shape == (h, w)
    assert np.nanmedian(r.disparity_px[20:-20, 80:-20]) == pytest.approx(24, abs=0.5)


def test_a_wide_frame_is_matched_at_most_max_match_width_wide():
    """The live preset keeps its speed on a 1280x720 camera: it matches at most 320 px wide."""
    p = MatcherParams(min_disparity=0, num_disparities=64, block_size=5, scale=0.5,
                      max_match_width=320)
    assert p.effective_scale(640) == 0.5 and p.effective_scale(1280) == 0.25
    assert MatcherParams(scale=0.5).effective_scale(1280) == 0.5
    _matched_at(p, (1280, 160), 0.25)
    with pytest.raises(InputError, match="max_match_width"):
        MatcherParams(max_match_width=10)


def test_a_frame_of_more_pixels_than_max_match_pixels_is_matched_at_half_and_so_on():
    """The quality preset keeps a few frames a second on a 1280x720 camera: it matches frames of
    more than 600,000 pixels at half; a 1241x376 road scene (466,616) stays at full."""
    p = MatcherParams(min_disparity=0, num_disparities=64, block_size=5,
                      max_match_pixels=600_000)
    assert p.effective_scale(1241, 376) == 1.0 and p.effective_scale(640, 480) == 1.0
    assert p.effective_scale(1280, 720) == 0.5 and p.effective_scale(1920, 1080) == 0.5
    assert p.effective_scale(3840, 2160) == 0.25
    assert p.effective_scale(1280) == 1.0  # (the width alone: no height, no pixel count)
    # with a width limit too: the pixels are counted at the scale the width leaves
    both = p.replace(scale=0.5, max_match_width=800)
    assert both.effective_scale(1280, 720) == 0.5 and both.effective_scale(3200, 1800) == 0.25
    assert both.replace(max_match_pixels=300_000).effective_scale(3200, 1800) == 0.125
    _matched_at(p, (1000, 640), 0.5)
    with pytest.raises(InputError, match="max_match_pixels"):
        MatcherParams(max_match_pixels=10)


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
