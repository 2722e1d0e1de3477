"""Distances at clicked pixels: the simulated rig's walls, reasons for invalid readings, object
mode, refinement, fits."""

import math
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from stereo_gui.core.align import (
    map_slope,
    one_surface,
    refine_disparity,
    refine_point,
    window_correlation,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.measure import (
    Reason,
    departs_on_plain_window,
    measure_map,
    measure_point,
)
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.reading_bound import MAP_SCATTER_FLOOR_PX
from stereo_gui.core.regression import fit_inverse
from stereo_gui.core.stereo_calibration import StereoCalibration, triangulate
from stereo_gui.core.uncertainty import Z95
from stereo_gui.files.presets import load_preset
from stereo_gui.sources.sim import Scene, SimRig
from stereo_gui.sources.sim.conditions import CONDITIONS

DISTANCES_MM = (500.0, 1000.0, 1500.0, 2000.0, 3000.0)
POINTS = ((320, 240), (200, 150), (450, 330), (560, 420))  # spread over the rectified image
TOLERANCE = {"quality": 0.005, "live": 0.01}


@pytest.fixture(scope="module")
def rig():
    return SimRig(seed=7)


@pytest.fixture(scope="module")
def walls(rig):
    """Rendered wall pairs per distance (rendering is the slow part; done once)."""
    return {z: (Scene.wall(z, seed=int(z)), rig.render_scene(Scene.wall(z, seed=int(z)),
                                                             np.random.default_rng(int(z))))
            for z in DISTANCES_MM}


def _errors(rig, calib, walls, preset, truth_calib=None):
    params = load_preset(preset)
    rows = []
    with StereoPipeline(calib, params) as pipe:
        for z, (scene, (left, right)) in walls.items():
            result = pipe.process(left, right)
            for x, y in POINTS:
                m = measure_point(result, x, y)
                assert m.valid, (preset, z, x, y, m.reason)
                true = rig.true_point_rectified(truth_calib or calib, scene, x, y)
                rows.append((z, x, y, (m.Z_mm - true[2]) / true[2], m))
    return rows


@pytest.mark.parametrize("preset", ["live", "quality"])
@pytest.mark.slow
def test_walls_measured_within_tolerance_with_the_true_calibration(rig, walls, preset):
    rows = _errors(rig, rig.true_calibration(alpha=0.0), walls, preset)
    worst = max(abs(r[3]) for r in rows)
    assert worst <= TOLERANCE[preset], [(z, x, y, f"{100 * e:.2f}%") for z, x, y, e, _ in rows]
    # the reported uncertainty is in the right order of magnitude (not zero, not absurd)
    for z, _, _, e, m in rows:
        assert 0 < m.expected_error_mm < 0.05 * z


@pytest.mark.slow
def test_walls_measured_with_a_calibration_computed_from_board_images(rig, walls):
    from stereo_gui.core.calibrate import calibrate_stereo
    from stereo_gui.core.detect import detect_pairs

    pairs = rig.calibration_set(20)
    dets = detect_pairs([(str(i), l, r) for i, (l, r) in enumerate(pairs)], rig.truth.board)
    calib = calibrate_stereo(dets, rig.truth.board, rig.truth.image_size).calibration
    # truth in the calibrated rectified frame: the rig's ray through the same rectified pixel
    rows = _errors(rig, calib, walls, "live")
    worst = max(abs(r[3]) for r in rows)
    assert worst <= TOLERANCE["live"], [(z, x, y, f"{100 * e:.2f}%") for z, x, y, e, _ in rows]


def test_refinement_beats_the_matchers_subpixel_estimate_at_3m(rig, walls):
    calib = rig.true_calibration()
    scene, (left, right) = walls[3000.0]
    result = StereoPipeline(calib, load_preset("quality")).process(left, right)
    raw, refined = [], []
    for x, y in POINTS:
        true_z = rig.true_point_rectified(calib, scene, x, y)[2]
        true_d = calib.focal_px * calib.rectified_baseline_mm / true_z
        m = measure_point(result, x, y)
        assert m.refined
        raw.append(abs(m.raw_disparity_px - true_d))
        refined.append(abs(m.disparity_px - true_d))
    assert np.mean(refined) < np.mean(raw)
    assert max(refined) < 0.14  # 0.5 % of the disparity at 3 m


def test_surface_nearer_than_the_range_is_too_near_never_a_number(rig):
    calib = rig.true_calibration()
    scene = Scene.wall(350.0)  # live's range ends at 0.45 m
    left, right = rig.render_scene(scene, np.random.default_rng(1))
    result = StereoPipeline(calib, load_preset("live")).process(left, right)
    readings = [measure_point(result, x, y) for x, y in POINTS]
    assert all(not m.valid for m in readings), readings
    assert sum(m.reason == "too near" for m in readings) >= len(POINTS) - 1
    assert all(m.reason in ("too near", "no valid pixels") for m in readings)


def test_surface_farther_than_a_limited_range_is_too_far(rig, walls):
    calib = rig.true_calibration()
    scene, (left, right) = walls[3000.0]
    p = load_preset("live").replace(z_min_mm=450.0, z_max_mm=1500.0)
    result = StereoPipeline(calib, p).process(left, right)
    m = measure_point(result, 320, 240)
    assert not m.valid and m.reason == "too far"


def test_outside_the_image_and_no_valid_pixels():
    c = StereoCalibration.identity((64, 48), 500.0, 100.0)
    disp = np.full((48, 64), np.nan, np.float32)
    assert measure_map(disp, 70, 10, calibration=c).reason == "outside the image"
    assert measure_map(disp, -1, 10, calibration=c).reason == "outside the image"
    assert measure_map(disp, 10, 10, calibration=c).reason == "no valid pixels"
    with pytest.raises(InputError):
        measure_map(disp, 10, 10)  # a bare map needs the calibration


def test_a_reason_is_an_enum_member_written_as_its_words():
    import json

    c = StereoCalibration.identity((64, 48), 500.0, 100.0)
    m = measure_map(np.full((48, 64), np.nan, np.float32), 70, 10, calibration=c)
    assert m.reason is Reason.OUTSIDE and m.reason == "outside the image"
    assert f"{m.reason}" == "outside the image"
    doc = json.loads(json.dumps(m.to_json_dict()))
    assert doc["reason"] == "outside the image" and type(m.to_json_dict()["reason"]) is str
    assert Reason.of("too near") is Reason.TOO_NEAR
    assert Reason.of("a reason of an older version") is None and Reason.of("") is None


def test_bare_map_triangulates_through_q_with_median_and_spread():
    f, b = 500.0, 100.0
    c = StereoCalibration.identity((64, 48), f, b)
    disp = np.full((48, 64), 25.0, np.float32)
    disp[20, 30] = 80.0  # an outlier the median ignores
    disp[21, 31] = np.nan
    m = measure_map(disp, 30, 20, calibration=c, patch=5)
    assert m.valid and m.method == "triangulation"
    assert m.Z_mm == pytest.approx(f * b / 25.0)
    assert m.valid_fraction == pytest.approx(24 / 25)
    X, Y, Z = triangulate(c, 30, 20, 25.0)
    assert (m.X_mm, m.Y_mm) == pytest.approx((X, Y))
    assert m.range_mm == pytest.approx(math.sqrt(X * X + Y * Y + Z * Z))
    # a bare map's 95 % bound: the disparity moved by 1.96 times its spread (at least the
    # 1/16 px quantum) towards the far side
    bound = Z95 / 16.0
    assert m.disparity_bound_px == pytest.approx(bound)
    assert m.expected_error_mm == pytest.approx(f * b / (25.0 - bound) - f * b / 25.0)


def test_the_bound_follows_q_on_a_rig_whose_principal_points_differ():
    """Middlebury's rigs read Z = f B / (d + doffs). The bound is the change of that Z for the
    disparity moved by its bound, not f B / d's change scaled to Z: that was (d + doffs) / d
    times too wide, 4.5x on Adirondack at quarter size."""
    f, b, doffs = 1038.0, 176.3, 53.3
    c = StereoCalibration.identity((64, 48), f, b, doffs_px=doffs)
    m = measure_map(np.full((48, 64), 15.0, np.float32), 30, 20, calibration=c, patch=5)
    bound = Z95 / 16.0
    assert m.valid and m.Z_mm == pytest.approx(f * b / (15.0 + doffs))
    far_side = f * b / (15.0 + doffs - bound) - f * b / (15.0 + doffs)
    assert m.expected_error_mm == pytest.approx(far_side, rel=1e-6)
    assert m.expected_error_mm < 0.3 * (f * b / (15.0 - bound) - f * b / 15.0)


def test_a_fit_replaces_triangulation_inside_its_span_only():
    f, b = 500.0, 100.0
    c = StereoCalibration.identity((64, 48), f, b)
    fit = fit_inverse([(d, 1.01 * f * b / d) for d in (10.0, 20.0, 30.0, 40.0)])
    disp = np.full((48, 64), 25.0, np.float32)
    m = measure_map(disp, 30, 20, calibration=c, fit=fit)
    assert m.valid and m.method == "inverse"
    assert m.Z_mm == pytest.approx(1.01 * f * b / 25.0, rel=1e-6)
    far = measure_map(np.full((48, 64), 5.0, np.float32), 30, 20, calibration=c, fit=fit)
    assert not far.valid and far.reason == "out of disparity range"
    # the bound follows the fit's own curve: the larger change of Z for d +- the disparity bound
    z = 1.01 * f * b
    bound = Z95 / 16.0
    assert m.expected_error_mm == pytest.approx(z / (25.0 - bound) - z / 25.0, rel=1e-3)


def test_a_hartley_calibration_measures_in_mm_only_through_a_fit():
    """Hartley's rectification has no metric scale: triangulating would give a number in
    unknown units labelled mm. Without a fit the reading says so; with one it is in mm."""
    f, b = 500.0, 100.0
    c = StereoCalibration.identity((64, 48), f, 1.0).with_updates(method="hartley")
    disp = np.full((48, 64), 25.0, np.float32)
    m = measure_map(disp, 30, 20, calibration=c)
    assert not m.valid and m.reason == "no metric scale" and m.disparity_px == pytest.approx(25.0)
    assert math.isnan(m.Z_mm)
    fit = fit_inverse([(d, f * b / d) for d in (10.0, 20.0, 30.0, 40.0)])
    m = measure_map(disp, 30, 20, calibration=c, fit=fit)
    assert m.valid and m.Z_mm == pytest.approx(f * b / 25.0, rel=1e-6)


def test_object_mode_reads_the_surface_around_the_click(rig):
    calib = rig.true_calibration()
    scene = Scene.demo()
    left, right = rig.render_scene(scene, np.random.default_rng(2))
    result = StereoPipeline(calib, load_preset("live")).process(left, right)
    # a pixel on the board at 2 m (the truth tells which object a ray hits), right of the band
    # at the left edge that the matcher cannot see
    hits = [(x, y) for y in range(120, 460, 20) for x in range(240, 600, 20)
            if abs(rig.true_point_rectified(calib, scene, x, y)[2] - 2000.0) < 1.0]
    assert hits
    x, y = hits[len(hits) // 2]
    m = measure_point(result, x, y, mode="object")
    assert m.valid and m.mode == "object"
    assert m.Z_mm == pytest.approx(2000.0, rel=0.02)


def _shifted_pair(true_d: float):
    """A textured 300x60 pair with right(u) = left(u + true_d), sampled from one wide image."""
    import cv2

    rng = np.random.default_rng(5)
    big = cv2.GaussianBlur(rng.random((60, 400)).astype(np.float32) * 255, (0, 0), 2.0)
    xs = np.arange(300, dtype=np.float32)
    mx = np.tile(xs + 50 + true_d, (60, 1)).astype(np.float32)
    my = np.repeat(np.arange(60, dtype=np.float32)[:, None], 300, axis=1)
    return big[:, 50:350], cv2.remap(big, mx, my, cv2.INTER_CUBIC)


def test_refine_disparity_finds_a_subpixel_shift():
    left, right = _shifted_pair(20.37)
    r = refine_disparity(left, right, 150, 30, 20.0, 5)
    assert r.converged and r.disparity_px == pytest.approx(20.37, abs=0.03)


def _warped_pair(d_centre: float, slope: float = 0.0, rows: float = 0.0, x_c: float = 150.0,
                 slantwise: bool = True):
    """A textured 300x120 pair whose disparity is d_centre + slope * (x - x_c) (a plane turned
    about the vertical axis), the right image's rows `rows` px lower than the left's (what a
    real rig's rectification leaves); `slantwise`: with stripes across the rows."""
    rng = np.random.default_rng(9)
    big = cv2.GaussianBlur(rng.random((160, 500)).astype(np.float32) * 255, (0, 0), 2.0)
    yy, xx = np.mgrid[0:160, 0:500].astype(np.float32)
    if slantwise:
        big += 40.0 * np.sin(2 * np.pi * (xx + yy) / 11.0)
    left = big[20:140, 100:400]
    # the right image at column u shows the left's x with u = x - d(x)
    u = np.arange(300, dtype=np.float32)
    x = (u + d_centre - slope * x_c) / (1.0 - slope)
    mx = np.tile(x + 100, (120, 1)).astype(np.float32)
    my = np.repeat(np.arange(120, dtype=np.float32)[:, None] + 20 - rows, 300, axis=1)
    return left, cv2.remap(big, mx, my, cv2.INTER_CUBIC)


def test_the_alignment_takes_a_rectification_rows_apart_in_its_stride():
    """Middlebury 2014's own rectification leaves the rows 0.2-0.4 px apart; on texture that runs
    slantwise a row offset moves a horizontal-only alignment off the disparity."""
    left, right = _warped_pair(20.3, rows=0.4)
    for x in (60, 150, 240):
        r = refine_disparity(left, right, x, 60, 20.0, 6)
        assert r.converged and r.disparity_px == pytest.approx(20.3, abs=0.03)


def test_a_grown_window_is_aligned_along_the_slope_the_map_shows():
    """On a slanted surface a 97 px window sees disparities 0.1 * 48 px either side of its
    centre's: aligned as one disparity it lands off the centre's value; along the map's
    slope it reads the centre."""
    slope = 0.1
    left, right = _warped_pair(30.0, slope=slope, slantwise=False)
    plane = (30.0 + slope * (np.arange(300, dtype=np.float32) - 150.0))[None, :].repeat(120, 0)
    tilt = map_slope(plane, 150, 60, 48)
    assert tilt == pytest.approx((slope, 0.0), abs=1e-3)
    along = refine_disparity(left, right, 150, 60, 30.0, 48, slope=tilt)
    assert along.converged and along.disparity_px == pytest.approx(30.0, abs=0.03)
    flat = refine_disparity(left, right, 150, 60, 30.0, 48)
    assert abs(flat.disparity_px - 30.0) > abs(along.disparity_px - 30.0)


def test_the_map_shows_no_slope_where_a_wall_faces_the_rig_or_values_are_few():
    rng = np.random.default_rng(2)
    wall = 25.0 + rng.normal(0.0, 0.3, (120, 300)).astype(np.float32)
    wall[::7, ::5] = 60.0  # wrong matches do not tilt it
    assert map_slope(wall, 150, 60, 48) == (0.0, 0.0)
    sparse = np.full((120, 300), np.nan, np.float32)
    sparse[60, 150:160] = 30.0
    assert map_slope(sparse, 150, 60, 48) == (0.0, 0.0)


def test_bad_arguments():
    disp = np.zeros((10, 10), np.float32)
    c = StereoCalibration.identity((10, 10), 500.0, 100.0)
    with pytest.raises(InputError):
        measure_map(disp, 5, 5, calibration=c, patch=0)
    with pytest.raises(InputError):
        measure_map(disp, 5, 5, calibration=c, mode="blob")
    assert Preset().name == "custom"


def test_reduced_resolution_preset_rematches_a_full_resolution_strip(rig, walls):
    from stereo_gui.core.click_map import rematch_strip

    calib = rig.true_calibration()
    scene, (left, right) = walls[2000.0]
    with StereoPipeline(calib, load_preset("live")) as pipe:
        result = pipe.process(left, right)
    band = rematch_strip(result, 240, 4)
    assert band.shape == (9, 640)
    true_d = calib.focal_px * calib.rectified_baseline_mm / rig.true_point_rectified(
        calib, scene, 320, 240)[2]
    assert np.nanmedian(band[:, 316:325]) == pytest.approx(true_d, abs=0.5)
    # full resolution: steps of 1/16 px, where the half-resolution map has steps of 1/8 px
    frac = np.unique(np.round((band[np.isfinite(band)] * 16) % 2))
    assert 1.0 in frac


def test_where_the_full_resolution_strip_finds_nothing_the_frames_own_values_stand(
        monkeypatch, rig, walls):
    """A full-resolution window can miss the texture the reduced frame matched (the webcams'
    walls: the live map right, the strip empty): the frame's own values are read where they lie
    on the surface around them, refined against the images; where the strip has values, only
    those agreeing with the frame's count."""
    import stereo_gui.core.measure as measure

    calib = rig.true_calibration()
    scene, (left, right) = walls[2000.0]
    with StereoPipeline(calib, load_preset("live")) as pipe:
        result = pipe.process(left, right)
    true_z = rig.true_point_rectified(calib, scene, 320, 240)[2]
    monkeypatch.setattr(measure, "rematch_strip",
                        lambda r, y, half: np.full((2 * half + 1, 640), np.nan, np.float32))
    m = measure_point(result, 320, 240)
    assert m.valid and m.Z_mm == pytest.approx(true_z, rel=0.01)
    assert m.valid_fraction > 0.5  # the patch's own values, not the surface around an empty one
    # ... only where they lie on the surface the checked matches around show (a blob of wrong
    # values in a dim corner read a wall at 0.5 m as 2.75 m)
    around = measure.surrounding_estimate(result, 320, 240)
    assert around == pytest.approx(m.raw_disparity_px, abs=1.0)
    monkeypatch.setattr(measure, "surrounding_estimate", lambda r, x, y: around + 10.0)
    assert measure_point(result, 320, 240).valid_fraction == 0.0
    monkeypatch.setattr(measure, "surrounding_estimate", lambda r, x, y: None)
    assert measure_point(result, 320, 240).valid_fraction == 0.0
    monkeypatch.undo()
    monkeypatch.setattr(measure, "rematch_strip",
                        lambda r, y, half: np.full((2 * half + 1, 640), np.nan, np.float32))
    # a strip that disagrees with the frame everywhere leaves the patch empty (the surface around
    # it may still be read); where nothing is read, the reason says that the map has values
    # there that the full-resolution images do not bear out
    monkeypatch.setattr(measure, "rematch_strip",
                        lambda r, y, half: np.full((2 * half + 1, 640), 5.0, np.float32))
    assert measure_point(result, 320, 240).valid_fraction == 0.0
    with monkeypatch.context() as m_none:
        m_none.setattr(measure, "surrounding_estimate", lambda r, x, y: None)
        m = measure_point(result, 320, 240)
        assert not m.valid and m.reason == Reason.NOT_CONFIRMED

    # ... but a strip that found a few values, all on the frame's surface, confirms it as far as
    # it found anything: the frame's own values stand (the rig's quarter-contrast walls at 0.5 m,
    # where such strips found 2-3 values and the patch was refused as too few)
    frame_d = float(np.nanmedian(result.final_px[236:245, 316:325]))

    def few_agreeing(r, y, half):
        band = np.full((2 * half + 1, 640), np.nan, np.float32)
        band[half, 318:321] = frame_d
        return band

    monkeypatch.setattr(measure, "rematch_strip", few_agreeing)
    m = measure_point(result, 320, 240)
    assert m.valid and m.Z_mm == pytest.approx(true_z, rel=0.01)
    assert m.valid_fraction > 0.5

    # ... but a few scattered strip values that agree with nothing (under a quarter of the patch:
    # the webcams' wall at 0.5 m, seed 109, where the strip found 9 values at 6 px on a wall at
    # 165 px) are a strip that found nothing: the frame's own values stand
    def scattered(r, y, half):
        band = np.full((2 * half + 1, 640), np.nan, np.float32)
        band[::4, ::4] = 5.0
        return band

    monkeypatch.setattr(measure, "rematch_strip", scattered)
    m = measure_point(result, 320, 240)
    assert m.valid and m.Z_mm == pytest.approx(true_z, rel=0.01)
    assert m.valid_fraction > 0.5  # the patch's own values, not the surface around it


def test_left_edge_strip_says_not_seen_and_the_seeds_band_not_searched(rig, walls):
    calib = rig.true_calibration()
    scene, (left, right) = walls[1000.0]  # d = f*B/Z = 82 px: the strip the right camera misses
    quality = StereoPipeline(calib, load_preset("quality")).process(left, right)
    seed = StereoPipeline(calib, load_preset("seed")).process(left, right)
    for y in (60, 240, 420):
        assert measure_point(quality, 30, y).reason == Reason.NOT_SEEN
        assert measure_point(seed, 30, y).reason == Reason.NOT_SEARCHED
        # right of the strip but inside the seed's 130 px dead band: quality reads it
        m = measure_point(quality, 110, y)
        true = rig.true_point_rectified(calib, scene, 110, y)[2]
        assert m.valid and m.Z_mm == pytest.approx(true, rel=0.01)
        assert measure_point(seed, 110, y).reason == Reason.NOT_SEARCHED
    # the view paints the strip as not seen, and a click there agrees with it
    assert quality.not_seen[240, :70].all() and not quality.not_seen[240, 100:].any()


def test_a_flat_surface_has_no_texture():

    c = StereoCalibration.identity((200, 120), 500.0, 100.0)
    rng = np.random.default_rng(3)
    flat = np.clip(128 + rng.normal(0, 1.0, (120, 200, 3)), 0, 255).astype(np.uint8)
    other = np.clip(128 + rng.normal(0, 1.0, (120, 200, 3)), 0, 255).astype(np.uint8)
    p = MatcherParams(min_disparity=0, num_disparities=32, block_size=5)
    result = StereoPipeline(c, p).process(flat, other)
    m = measure_point(result, 120, 60)
    assert not m.valid and m.reason == "no texture"


def test_refinement_near_the_right_images_edge_uses_a_narrower_window():
    true_d = 20.37
    left, right = _shifted_pair(true_d)
    # x - d = 6 px from the right image's left edge: a centred 9 px window plus margin does not
    # fit, the clipped one does
    r = refine_disparity(left, right, 26, 30, 20.0, 4, max_shift_px=2.0)
    assert r.converged and r.disparity_px == pytest.approx(true_d, abs=0.05)
    assert r.moved_px == pytest.approx(abs(r.disparity_px - 20.0))


def test_a_point_within_the_margin_of_the_right_images_edge_is_refined_beside_it():
    true_d = 20.37
    left, right = _shifted_pair(true_d)
    # x - d = 2 px: no window centred on the point fits with the margin; the columns just right
    # of it (the same surface) give the disparity
    r = refine_disparity(left, right, 22, 30, 20.0, 6, max_shift_px=2.0)
    assert r.converged and r.disparity_px == pytest.approx(true_d, abs=0.05)
    # further than the margin from the usable columns there is nothing to refine
    far = refine_disparity(left, right, 14, 30, 20.0, 6, max_shift_px=2.0)
    assert not far.converged and not far.ran_off


def test_an_estimate_the_images_pull_away_from_is_contradicted():
    left, right = _shifted_pair(20.37)
    ref = refine_point(left, right, 150, 30, 23.5, 4)  # the matcher 3 px off
    assert ref is not None and not ref.converged and ref.ran_off
    good = refine_point(left, right, 150, 30, 20.0, 4)
    assert good is not None and good.converged and not good.ran_off
    assert good.disparity_px == pytest.approx(20.37, abs=0.03)


def test_window_correlation_is_high_at_the_match_and_low_off_it():
    left, right = _shifted_pair(20.37)
    at, n = window_correlation(left, right, 150, 30, 20.37, 6)
    off, _ = window_correlation(left, right, 150, 30, 26.0, 6)
    assert n == 13 * 13 and at > 0.99 and off < 0.5
    assert window_correlation(left, right, 5, 30, 20.0, 6) == (0.0, 0)  # left of the right image


@pytest.mark.slow
def test_a_chessboard_is_read_not_refused_for_its_repeating_squares(rig):
    """The board's period gives correlation peaks nearly as high as the true one: that alone is
    no reason to refuse a reading (a double-click on the board read 'no valid pixels' at 10 of
    24 poses), and the readings are right within their bound."""
    calib = rig.true_calibration()
    rng = np.random.default_rng(3)
    scene = Scene.demo()  # the board in front of the demo scene, as the live rig shows it
    errors, bounds, reasons = [], [], []
    for _ in range(6):
        pose = rig.random_board_pose(rng)
        left, right = rig.render_board_pair(pose, rng, scene=scene)
        result = StereoPipeline(calib, load_preset("quality")).process(left, right)
        # points spread over the squares (corners, edges and the middle of squares)
        b = rig.truth.board
        on_board = [pose.R @ np.array([u, v, 0.0]) + pose.t
                    for u in np.linspace(0, (b.cols - 1) * b.square_mm, 7)
                    for v in np.linspace(0, (b.rows - 1) * b.square_mm, 5)]
        right_centre = -np.asarray(rig.truth.R).T @ np.asarray(rig.truth.T).reshape(3)
        for point in on_board:
            if any(hidden is not None and hidden < np.linalg.norm(point - eye) - 1.0
                   for eye, hidden in ((eye, scene.depth_along_ray(eye, point - eye))
                                       for eye in (np.zeros(3), right_centre))):
                continue  # an object of the scene hides this point from one of the cameras
            p = np.asarray(calib.R1) @ point
            q = np.asarray(calib.P1) @ np.append(p, 1.0)
            m = measure_point(result, q[0] / q[2], q[1] / q[2])
            if m.reason == "no texture":  # inside a plain square: rightly not read
                continue
            errors.append(abs(m.Z_mm - p[2]) if m.valid else np.nan)
            bounds.append(m.expected_error_mm)
            reasons.append(m.reason)
    errors, bounds = np.array(errors), np.array(bounds)
    read = np.isfinite(errors)
    assert read.mean() >= 0.9, (read.mean(), reasons)
    assert (errors[read] <= bounds[read]).mean() >= 0.9


@pytest.fixture(scope="module")
def weak_rig():
    """The rig with the sensor noise of a cheap webcam (1.5 grey levels)."""
    from dataclasses import replace

    from stereo_gui.sources.sim import RigConfig

    return SimRig(replace(RigConfig(), noise_sigma=1.5), seed=5)


@pytest.mark.parametrize("preset", ["live", "quality"])
@pytest.mark.slow
def test_a_painted_wall_of_weak_texture_is_read_over_the_whole_frame(weak_rig, preset):
    """A smooth wall at 1 m whose texture is about as strong as the sensor noise (a 9x9 window's
    grey-level spread near 1.5): a reading at nearly every point of a grid over the whole frame,
    each within its +-, the worst within 2 %."""
    from stereo_gui.commands.accuracy import WallTruth, grid_pixels

    calib = weak_rig.true_calibration()
    wall = 1000.0
    left, right = weak_rig.render_scene(Scene.wall(wall, seed=21, contrast=0.06),
                                        np.random.default_rng(4))
    truth = WallTruth(weak_rig, calib, wall)
    with StereoPipeline(calib, load_preset(preset)) as pipe:
        result = pipe.process(left, right)
    seen = read = covered = 0
    worst = 0.0
    for x, y in grid_pixels(calib.image_size):
        z_true, visible = truth.point(x, y)
        if not visible:
            continue
        seen += 1
        m = measure_point(result, x, y)
        if m.valid:
            read += 1
            covered += abs(m.Z_mm - z_true) <= m.expected_error_mm
            worst = max(worst, abs(m.Z_mm - z_true) / z_true)
    # (at 1 m one grid column's match lies 3.5 px inside the right image, where live's
    # half-resolution window reaches past its edge: 7 of 56 points)
    assert read >= 0.85 * seen, (read, seen)
    assert covered >= 0.95 * read and worst <= 0.02, (covered, read, worst)


@pytest.mark.parametrize("preset", ["live", "quality"])
def test_a_blank_wall_is_refused_for_having_no_texture(weak_rig, preset):
    """Nothing but sensor noise to match: no number anywhere, and the reason says why."""
    calib = weak_rig.true_calibration()
    left, right = weak_rig.render_scene(Scene.wall(1000.0, seed=21, contrast=0.0),
                                        np.random.default_rng(4))
    with StereoPipeline(calib, load_preset(preset)) as pipe:
        result = pipe.process(left, right)
    readings = [measure_point(result, x, y) for x, y in POINTS]
    assert not any(m.valid for m in readings), readings
    assert sum(m.reason == "no texture" for m in readings) >= len(POINTS) - 1, readings


def test_correlated_stderr_counts_residuals_that_move_together():
    """Independent residuals: about the usual standard error. Residuals shared by 8 x 8 blocks
    (what MJPG leaves): several times more, as the fit has far fewer independent pixels."""
    from stereo_gui.core.align import correlated_stderr

    rng = np.random.default_rng(3)
    shape = (32, 32)
    # a texture's gradient changes smoothly from pixel to pixel
    g = cv2.GaussianBlur(rng.normal(0, 10, shape), (0, 0), 3.0)
    g *= 10 / g.std()
    A = np.column_stack([rng.normal(100, 5, g.size), np.ones(g.size), g.reshape(-1)])
    inv = np.linalg.inv(A.T @ A)
    ratios = []
    for blocky in (False, True):
        if blocky:
            resid = np.kron(rng.normal(0, 2, (4, 4)), np.ones((8, 8))).reshape(-1)
            resid += rng.normal(0, 0.2, resid.size)
        else:
            resid = rng.normal(0, 2, g.size)
        iid = np.sqrt(resid @ resid / (g.size - 3) * inv[2, 2])
        ratios.append(correlated_stderr(A, resid, shape) / iid)
    assert 0.6 < ratios[0] < 1.4, ratios
    assert ratios[1] > 2.0, ratios


@pytest.mark.parametrize("preset", ["live", "quality"])
@pytest.mark.slow
def test_on_an_mjpg_wall_the_plus_minus_still_covers_the_truth(preset):
    """MJPG at quality 75 on a painted wall at half contrast: the blocks move the readings by
    more than independent pixels would, and the +- says so (it counts the residuals'
    correlation): it covers the true error at 95 % or more of the points read (counting the
    pixels as independent it covered 90-91 % here)."""
    from stereo_gui.commands.accuracy import evaluate_wall
    from stereo_gui.sources.sim.conditions import CONDITIONS

    condition = CONDITIONS["mjpg"]
    base = SimRig(seed=31)
    rig = SimRig(condition.rig_config(base.config), seed=31)
    calib = rig.true_calibration()
    read = covered = 0
    for wall in (1000.0, 2000.0):
        report = evaluate_wall(rig, calib, preset, wall, 31, condition=condition)
        read += sum(g.read for g in report.seen)
        covered += sum(g.covered for g in report.seen if g.read)
    assert read > 60 and covered >= 0.95 * read, (covered, read)


@pytest.mark.slow
def test_a_wrong_far_reading_at_the_left_edge_is_refused():
    """On the webcams' wall at 3 m a wrong match 8 px from the left edge read 21 m; now it says
    the right camera cannot see the point."""
    from stereo_gui.commands.accuracy import BENCH_SEED, evaluate_wall
    condition = CONDITIONS["webcams"]
    rig = SimRig(condition.rig_config(SimRig(seed=BENCH_SEED).config), seed=BENCH_SEED)
    report = evaluate_wall(rig, rig.true_calibration(), "live", 3000.0, BENCH_SEED,
                           condition=condition)
    assert report.unseen_read == 0
    edge = [g for g in report.readings if g.x < 20]
    assert edge and not any(g.read and abs(g.z_mm - g.true_z_mm) > 0.1 * g.true_z_mm
                            for g in edge)


def _blank(result, x0: int, x1: int, y0: int = 0, y1: int | None = None) -> None:
    """Empty the maps a reading takes its values from in the given block (a patch the matcher
    left empty), and their left-right checks."""
    for arr in (result.final_px, result.disparity_px):
        arr[y0:y1, x0:x1] = np.nan
    if result.wls_confidence is not None:
        result.wls_confidence[y0:y1, x0:x1] = 0


@pytest.mark.parametrize("preset", ["live", "quality"])
def test_a_patch_the_matcher_left_empty_is_read_from_the_surface_around_it(weak_rig, preset):
    """On a painted wall, a click whose own patch has no valid pixels (17 px of the map emptied
    around it) is read from the surface around it, once the images confirm it there; within
    its +-, and the +- says the alignment carried it."""
    calib = weak_rig.true_calibration()
    scene = Scene.wall(1000.0, seed=21, contrast=0.3)
    left, right = weak_rig.render_scene(scene, np.random.default_rng(4))
    with StereoPipeline(calib, load_preset(preset)) as pipe:
        result = pipe.process(left, right)
    read = 0
    for x, y in POINTS:
        _blank(result, x - 8, x + 9, y - 8, y + 9)
        m = measure_point(result, x, y, rematch=False)
        if m.valid:
            read += 1
            true = weak_rig.true_point_rectified(calib, scene, x, y)[2]
            assert m.refined and abs(m.Z_mm - true) <= m.expected_error_mm, (x, y, m)
        else:
            assert m.reason == Reason.NO_VALID_PIXELS
    assert read >= len(POINTS) - 1


@pytest.mark.parametrize("contrast", [0.0, 1.0])
def test_an_object_the_matcher_missed_is_not_read_as_the_wall_behind_it(rig, contrast):
    """A pole 40 mm wide at 1 m in front of a wall at 2 m, which the map misses entirely (its
    columns emptied): clicks on the pole are refused, never read as the wall behind it."""
    from factories import pole_before_wall

    calib = rig.true_calibration()
    scene = pole_before_wall(1000.0, contrast=contrast)
    left, right = rig.render_scene(scene, np.random.default_rng(5))
    on_pole = [x for x in range(200, 450)
               if rig.true_point_rectified(calib, scene, x, 240)[2] < 1001.0]
    for preset in ("live", "quality"):
        with StereoPipeline(calib, load_preset(preset)) as pipe:
            result = pipe.process(left, right)
        _blank(result, on_pole[0] - 2, on_pole[-1] + 3)
        for y in range(40, 440, 40):
            for x in range(on_pole[0] + 3, on_pole[-1] - 2, 4):  # inside the pole
                m = measure_point(result, x, y, rematch=False)
                assert not m.valid or m.Z_mm < 1500.0, (preset, x, y, m)


@pytest.mark.parametrize("wall", [2000.0, 3000.0])
@pytest.mark.slow
def test_a_chance_peak_of_a_small_window_is_not_called_too_near(wall):
    """On the webcams' wall (MJPG blocks, shading, weak texture) an 11 px window correlates at
    0.7-0.8 with stretches of the right image far beyond the range by chance; a wall at 2 or 3 m
    lies well inside it. Where the map shows one surface, a larger window settles it: no grid
    point is called too near (before, 2-4 per wall were)."""
    from stereo_gui.commands.accuracy import evaluate_wall
    condition = CONDITIONS["webcams"]
    rig = SimRig(condition.rig_config(SimRig(seed=11).config), seed=11)
    calib = rig.true_calibration()
    for preset in ("live", "quality"):
        report = evaluate_wall(rig, calib, preset, wall, 11, condition=condition)
        assert not any(g.reason == Reason.TOO_NEAR for g in report.seen), (preset, report.reasons)


def test_one_surface_holds_a_scattered_wall_and_not_two_surfaces():
    """A wall at 27 px whose matches scatter as on a weak MJPG wall (1.2 px, a tenth of them 3 px
    off) is one surface; the same window with 30 % of it on a pole at 40 px is not,
    though the pole is a minority that a robust spread alone would not notice."""
    rng = np.random.default_rng(3)
    wall = 27.0 + rng.normal(0.0, 1.2, (97, 97)).astype(np.float32)
    wall[rng.random((97, 97)) < 0.1] += 3.0
    wall[rng.random((97, 97)) < 0.3] = np.nan  # holes the checks left
    assert one_surface(wall, 48, 48, 48)
    two = wall.copy()
    two[:, 34:63] = 40.0 + rng.normal(0.0, 0.3, (97, 29))
    assert not one_surface(two, 48, 48, 48)
    assert not one_surface(np.full((97, 97), np.nan, np.float32), 48, 48, 48)


@pytest.mark.slow
def test_on_the_webcams_wall_far_off_the_window_grows_until_it_is_sure():
    """Two webcams' wall (half contrast, the right camera's own gain and black level, darker
    corners, MJPG) at 2 and 3 m, a rig seed no benchmark uses: the matcher's map scatters in
    blobs up to 3 px off, and a 13 or 25 px window fitted such a blob (7.7 % off at 3 m, beyond
    its +- of 5.4 %). Now the window keeps growing while the map shows one surface, starts again
    where a smaller window settled, and a wider window that settles elsewhere refuses the reading:
    every reading within 2 %, at 90 % of the points or more, the +- covering 95 %."""
    from stereo_gui.commands.accuracy import evaluate_wall
    condition = CONDITIONS["webcams"]
    rig = SimRig(condition.rig_config(SimRig(seed=5).config), seed=5)
    calib = rig.true_calibration()
    for preset in ("live", "quality"):
        seen = [g for wall in (2000.0, 3000.0)
                for g in evaluate_wall(rig, calib, preset, wall, 5, condition=condition).seen]
        read = [g for g in seen if g.read]
        worst = max(abs(g.error_pct) for g in read)
        assert len(read) >= 0.9 * len(seen), (preset, len(read), len(seen))
        assert worst <= 2.0, (preset, worst)
        assert sum(g.covered for g in read) >= 0.95 * len(read), preset


@pytest.mark.slow
@pytest.mark.parametrize("seed, x, y", [(101, 86, 8), (108, 631, 8)])
def test_on_the_webcams_wall_a_blob_past_which_the_surface_lies_elsewhere_is_not_read(seed, x, y):
    """The webcams' wall at 3 m, top row: the quality map's blobs stopped the window's growth at
    25x25 on a blob 1.6-1.8 px off (6.0 % and 6.3 %, the worst readings of ten seeds), while the
    97x97 window past it lies within 1.5 % of the truth. The click is refused, or reads within
    2 %; live reads it within 2 %."""
    from stereo_gui.commands.accuracy import WallTruth
    from stereo_gui.pipeline.concurrency import preset_pipeline

    condition = CONDITIONS["webcams"]
    rig = SimRig(condition.rig_config(SimRig(seed=seed).config), seed=seed)
    calib = rig.true_calibration()
    scene = Scene.wall(3000.0, seed=seed + 3000, contrast=condition.contrast)
    left, right = rig.render_scene(scene, np.random.default_rng(seed * 7 + 3000))
    z_true, _ = WallTruth(rig, calib, 3000.0).point(x, y)
    for name in ("live", "quality"):
        with preset_pipeline(calib, Preset.of(load_preset(name))) as pipe:
            m = measure_point(pipe.process(left, right), x, y)
        assert m.valid or name == "quality", (name, m.reason)
        if m.valid:
            assert abs(m.Z_mm - z_true) <= 0.02 * z_true, (name, m.Z_mm, z_true)
        else:
            assert m.reason == Reason.AMBIGUOUS


def _textured_pair(contrast: float, noise: float, shift: float = 24.0, seed: int = 3):
    """A 400x240 plane `shift` px apart, its texture's spread `contrast` grey levels, each
    camera's own noise `noise` grey levels (BGR uint8)."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.random((240, 520)).astype(np.float32), (0, 0), 1.5)
    big = 128 + contrast * (big - big.mean()) / big.std()
    xs = np.arange(400, dtype=np.float32)
    ys = np.repeat(np.arange(240, dtype=np.float32)[:, None], 400, axis=1)
    out = []
    for dx in (60.0, 60.0 + shift):
        img = cv2.remap(big, np.tile(xs + dx, (240, 1)), ys, cv2.INTER_CUBIC)
        img = img + rng.normal(0.0, noise, img.shape)
        out.append(cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    return out


def _textured_result(contrast: float, noise: float):
    """The quality preset's processing of `_textured_pair` (a plane 24 px apart)."""
    calib = StereoCalibration.identity((400, 240), 800.0, 100.0)
    params = load_preset("quality").replace(z_min_mm=None, z_max_mm=None, min_disparity=0,
                                            num_disparities=64)
    with StereoPipeline(calib, params) as pipe:
        return pipe.process(*_textured_pair(contrast, noise))


@pytest.mark.parametrize("contrast, noise, read", [(40.0, 1.0, True), (8.0, 3.0, True),
                                                    (5.0, 3.0, False), (3.0, 2.0, False)])
def test_an_alignment_that_runs_off_leaves_the_map_only_on_rich_texture(monkeypatch, contrast,
                                                                        noise, read):
    """Where the alignment cannot settle near the map's estimate, a patch whose matches agree
    and whose window matches there as only rich texture does (Middlebury's slanted and curved
    surfaces) is read unrefined; on weak texture (the webcams' wall, whose map's blobs are
    wrong) it stays refused."""
    import stereo_gui.core.measure as measure

    result = _textured_result(contrast, noise)
    monkeypatch.setattr(measure, "refine_point", lambda *a, **k: measure.Refinement(
        a[4], float("inf"), False, ran_off=True))
    m = measure_point(result, 200, 120)
    assert m.valid == read
    if read:
        assert not m.refined and m.disparity_px == pytest.approx(24.0, abs=0.25)
    else:
        assert m.reason == Reason.AMBIGUOUS


@pytest.mark.parametrize("contrast, noise, read", [(40.0, 1.0, True), (3.0, 2.0, False)])
def test_a_loose_alignment_leaves_the_map_only_on_rich_texture(monkeypatch, contrast, noise,
                                                               read):
    """An alignment that settles 1.5 px from the map's estimate with a bound over a quarter of
    the distance: on a patch whose matches agree and whose window matches there as only rich
    texture does, the map's patch is read (on the 13 public scenes 16 more clicks right within
    2 %, teddy's and Lampshade's among them), its bound widened by the alignment's disagreement;
    on weak texture the refusal stands."""
    import stereo_gui.core.measure as measure

    result = _textured_result(contrast, noise)
    monkeypatch.setattr(measure, "refine_point", lambda *a, **k: measure.Refinement(
        a[4] + 1.5, 4.0, True, moved_px=1.5, correlation=0.95, pixels=625, half_px=12))
    m = measure_point(result, 200, 120)
    assert m.valid == read
    if read:
        assert not m.refined and m.disparity_px == pytest.approx(24.0, abs=0.25)
        assert m.disparity_bound_px >= 1.96 * 1.5  # the disagreement counts
        assert m.expected_error_mm <= measure.AMBIGUOUS_SHARE * m.Z_mm
    else:
        assert m.reason == Reason.AMBIGUOUS


@pytest.mark.parametrize("offset, windows_px, refined", [(0.6, 0.3, False), (0.6, 0.02, True),
                                                         (0.2, 0.3, True)])
def test_a_rich_patch_surer_than_its_alignment_overrules_it(monkeypatch, offset, windows_px,
                                                            refined):
    """An alignment that settles 0.6 px from a rich patch's median, its windows disagreeing by
    0.3 px (a bound of about 1.8 px, wider than the patch's own of 0.4 px): the patch's median
    is read, with the alignment's wider bound kept (on the 13 public scenes such readings lay a
    median 0.65-0.77 px from the truth refined and 0.24-0.33 px unrefined). An alignment tighter
    than the patch keeps its refined reading, and so does a loose one that settles within the
    patch's bound (0.2 px): there it undoes SGBM's bias towards whole pixels."""
    import stereo_gui.core.measure as measure

    result = _textured_result(40.0, 1.0)
    monkeypatch.setattr(measure, "refine_point", lambda *a, **k: measure.Refinement(
        a[4] + offset, 0.05, True, moved_px=offset, correlation=0.95, pixels=625, half_px=12,
        windows_px=windows_px))
    m = measure_point(result, 200, 120)
    assert m.valid and m.refined == refined
    patch = measure_point(result, 200, 120, refine=False)
    assert patch.disparity_bound_px == pytest.approx(1.96 * math.hypot(patch.spread_px, 0.19),
                                                     rel=1e-3)
    if refined:
        assert m.disparity_px == pytest.approx(patch.disparity_px + offset, abs=1e-6)
    else:
        assert m.disparity_px == pytest.approx(patch.disparity_px, abs=1e-6)
        # the alignment's wider bound stays
        assert m.disparity_bound_px >= 1.96 * 3.0 * windows_px > patch.disparity_bound_px


def test_a_window_past_a_second_surface_that_settles_elsewhere_marks_the_reading():
    """Where a blob of wrong matches 3 px off fills a quarter of the 49x49 window (two surfaces
    to the map) but little of the 97x97 one, the larger window is aligned from the reading: a
    reading 1.4 px off the surface is marked by how far beyond the windows' noise it lies; a
    right one is not, nor one where no larger window holds one surface."""
    from stereo_gui.core.align import Refinement, _beyond_two_surfaces

    left, right = (cv2.cvtColor(i, cv2.COLOR_BGR2GRAY) for i in _textured_pair(40.0, 1.0))
    surface = np.full(left.shape, 24.0, np.float32)
    surface[96:108, 176:225] = 27.0  # inside the 49x49 window, outside the 25x25 one
    assert one_surface(surface, 200, 120, 12) and not one_surface(surface, 200, 120, 24)
    off = Refinement(25.4, 0.2, True, half_px=12)
    marked = _beyond_two_surfaces(left, right, 200, 120, 4, 24, surface, off)
    assert marked.disparity_px == 25.4  # the reading itself is kept: measure decides
    assert marked.beyond_px == pytest.approx(1.4 - Z95 * 0.2, abs=0.05)
    right_one = _beyond_two_surfaces(left, right, 200, 120, 4, 24, surface,
                                     Refinement(24.0, 0.2, True, half_px=12))
    assert right_one.beyond_px == 0.0
    # a larger window whose one surface is another than the reading's (a background around a
    # leaf) checks nothing
    background = np.full(left.shape, 16.0, np.float32)
    background[108:133, 188:213] = 24.0
    assert not one_surface(background, 200, 120, 24) and one_surface(background, 200, 120, 48)
    assert _beyond_two_surfaces(left, right, 200, 120, 4, 24, background, off).beyond_px == 0.0
    surface[:, 200:] = 40.0  # half of every larger window on a second surface
    assert _beyond_two_surfaces(left, right, 200, 120, 4, 24, surface, off).beyond_px == 0.0


@pytest.mark.parametrize("contrast, noise, beyond, read", [
    (3.0, 2.0, 1.0, False), (3.0, 2.0, 0.3, True), (3.0, 2.0, 0.0, True), (40.0, 1.0, 1.0, True)])
def test_a_reading_a_larger_window_contradicts_stands_only_on_rich_texture(
        monkeypatch, contrast, noise, beyond, read):
    """A refined reading that the window past the second surface contradicts by more than
    BEYOND_SHARE of its disparity (1 px at 24 px; 0.3 px is within it) is refused as ambiguous
    on weak texture (the webcams' wall at 3 m, seeds 101 and 108: 6 % off); a patch rich enough
    to be read unrefined keeps its refined reading (teddy's slanted surface, where the larger
    window reads a depth edge the map does not show)."""
    import stereo_gui.core.measure as measure

    result = _textured_result(contrast, noise)
    monkeypatch.setattr(measure, "refine_point", lambda *a, **k: measure.Refinement(
        a[4], 0.2, True, correlation=0.9, pixels=625, half_px=12, beyond_px=beyond))
    m = measure_point(result, 200, 120)
    assert m.valid == read, m.reason
    if not read:
        assert m.reason == Reason.AMBIGUOUS


def test_the_texture_evidence_is_judged_without_the_row_offsets_fit():
    """The correlation a reading's texture check uses is the aligned windows' at the rows as
    they are: a free row offset lets noise correlate a little better, and a weak wall at the
    threshold passed on it (the webcams' wall at 3 m, seed 11: 12.8 % off)."""
    left, right = _warped_pair(20.3, rows=0.4)
    r = refine_disparity(left, right, 150, 60, 20.0, 6)
    plain, _ = window_correlation(left, right, 150, 60, r.disparity_px, 6)
    assert r.converged and r.correlation == pytest.approx(plain, abs=0.01)


def test_a_reading_of_a_nearer_edge_says_so(monkeypatch, rig, walls):
    import stereo_gui.core.measure as measure

    calib = rig.true_calibration()
    with StereoPipeline(calib, load_preset("quality")) as pipe:
        result = pipe.process(*walls[1000.0][1])
    assert measure_point(result, 320, 240).valid
    monkeypatch.setattr(measure, "reads_nearer_edge", lambda *a: True)
    m = measure_point(result, 320, 240)
    assert not m.valid and m.reason == Reason.NEARER_EDGE


def test_a_reading_a_nearer_surface_beside_it_would_hide_says_so_not_that_it_is_unseen(
        monkeypatch, rig, walls):
    """Where the map's nearer surface beside the click would hide the patch's farther reading,
    one of the two is wrong or the point is hidden: the reason says that, not "not seen" (on
    the 13 public scenes both cameras saw the point at all 21 such refusals)."""
    import stereo_gui.core.measure as measure

    calib = rig.true_calibration()
    with StereoPipeline(calib, load_preset("quality")) as pipe:
        result = pipe.process(*walls[1000.0][1])
    assert measure_point(result, 320, 240).valid
    monkeypatch.setattr(measure, "hidden_by_nearer", lambda *a: (True, None))
    m = measure_point(result, 320, 240)
    assert not m.valid and m.reason == Reason.NEARER_HIDES
    # the reason the views paint the unseen strip with stays its own
    assert measure_point(result, 3, 240).reason == Reason.NOT_SEEN


def _webcams_wall(seed: int, wall_mm: float):
    """The rig's webcams wall as `bench --accuracy --condition webcams` renders it, processed by
    the quality preset with the true calibration."""
    condition = CONDITIONS["webcams"]
    rig = SimRig(condition.rig_config(SimRig(seed=seed).config), seed=seed)
    calib = rig.true_calibration()
    scene = Scene.wall(wall_mm, seed=seed + int(wall_mm), contrast=condition.contrast)
    left, right = rig.render_scene(scene, np.random.default_rng(seed * 7 + int(wall_mm)))
    with StereoPipeline(calib, load_preset("quality")) as pipe:
        return calib, pipe.process(left, right)


def test_a_plain_dark_corner_does_not_read_a_match_its_surroundings_contradict():
    """Seed 105's 3 m webcams wall: in the top right corner (dark, MJPG, no texture beyond the
    noise) a streak of the map and the images' blocks agree on 59 px where the wall is at 28 px:
    it read 1.39 m +- 32 mm. The surface around says otherwise, and the reading is refused."""
    calib, result = _webcams_wall(105, 3000.0)
    m = measure_point(result, 631, 8)
    assert not m.valid and m.reason == Reason.AMBIGUOUS
    assert m.disparity_px > 50.0  # (the wrong match it did not read out)


def test_a_plain_corner_reading_on_its_surface_is_kept():
    """Seed 101's 0.5 m webcams wall, bottom right corner: as plain, read right (within 0.1 %),
    and 2 px from the plane the matches around it extrapolate to in the corner: kept."""
    calib, result = _webcams_wall(101, 500.0)
    m = measure_point(result, 631, 471)
    assert m.valid
    assert abs(m.Z_mm - 500.0) / 500.0 < 0.01


def test_departs_on_plain_window_needs_a_plain_window_and_a_surface_far_off(monkeypatch):
    """The rule's three conditions: a window without texture, a surface around, and a reading
    more than a tenth of that surface's disparity (and two matched pixels) from it."""
    import stereo_gui.core.measure as measure

    rng = np.random.default_rng(5)
    plain = (120 + rng.normal(0, 1.0, (60, 60))).clip(0, 255).astype(np.uint8)
    textured = (120 + rng.normal(0, 20.0, (60, 60))).clip(0, 255).astype(np.uint8)
    result = SimpleNamespace(match_scale=1.0)
    monkeypatch.setattr(measure, "surrounding_estimate", lambda r, x, y: 28.0)
    assert departs_on_plain_window(result, plain, 30, 30, 59.0)  # twice as near: refused
    assert departs_on_plain_window(result, plain, 30, 30, 20.0)  # farther, as far off
    assert not departs_on_plain_window(result, plain, 30, 30, 30.5)  # within a tenth
    assert not departs_on_plain_window(result, textured, 30, 30, 59.0)  # texture decides
    half = SimpleNamespace(match_scale=0.5)  # two matched pixels are 4 px here
    monkeypatch.setattr(measure, "surrounding_estimate", lambda r, x, y: 10.0)
    assert not departs_on_plain_window(half, plain, 30, 30, 13.5)
    assert departs_on_plain_window(half, plain, 30, 30, 14.5)
    monkeypatch.setattr(measure, "surrounding_estimate", lambda r, x, y: None)
    assert not departs_on_plain_window(result, plain, 30, 30, 59.0)  # nothing around to say


def test_a_window_the_images_do_not_bear_out_is_called_no_texture_only_where_it_has_none():
    """The aligned windows' correlation check refuses what noise alone could give: a plain
    window has nothing to match ("no texture"), but a textured one the right image does not
    show at the reading (the two views differ there) is an ambiguous match, not a plain wall
    (on the 13 public scenes 8 such refusals were of windows of 8-21 grey levels' spread)."""
    from stereo_gui.core import measure

    rng = np.random.default_rng(4)
    textured = rng.uniform(0, 255, (80, 120)).astype(np.uint8)
    other = rng.uniform(0, 255, (80, 120)).astype(np.uint8)  # the right view shows none of it
    plain = np.full((80, 120), 128, np.uint8) + rng.integers(0, 2, (80, 120)).astype(np.uint8)
    disp = np.full((80, 120), 10.0, np.float32)
    click = measure._Click.at(60, 40, 9, "point", disp.shape)
    read = measure._MapReading(10.0, np.full(81, 10.0, np.float32), 1.0)
    refused = measure._checked_in_images(textured, other, disp, click, read, None)
    assert isinstance(refused, measure.Measurement) and refused.reason == Reason.AMBIGUOUS
    refused = measure._checked_in_images(plain, plain[:, ::-1].copy(), disp, click, read, None)
    assert isinstance(refused, measure.Measurement) and refused.reason == Reason.NO_TEXTURE
    # where the right view does show the window, it is borne out
    shifted = np.roll(textured, -10, axis=1)
    assert measure._checked_in_images(textured, shifted, disp, click, read, None) == 10.0


@pytest.mark.parametrize("scatter", [0.0, 0.04, 0.5])
def test_the_maps_scatter_about_its_plane_widens_a_refined_readings_bound_only(monkeypatch,
                                                                               scatter):
    """A refined reading's bound has the patch's scatter about its plane beyond the floor a
    right match shows (MAP_SCATTER_FLOOR_PX, 0.05 px) added in quadrature (1.96 sigma): the
    alignment's fit does not see how the map's matches around the click scatter. The reading
    itself stays; so does an unrefined one's bound, the patch's spread already."""
    import stereo_gui.core.measure as measure

    result = _textured_result(40.0, 1.0)
    monkeypatch.setattr(measure, "plane_scatter_px", lambda *a: 0.0)
    alone = measure_point(result, 200, 120)
    patch = measure_point(result, 200, 120, refine=False)
    monkeypatch.setattr(measure, "plane_scatter_px", lambda *a: scatter)
    m = measure_point(result, 200, 120)
    assert alone.valid and alone.refined and m.valid and m.refined
    assert m.disparity_px == alone.disparity_px and m.Z_mm == alone.Z_mm
    excess = math.sqrt(max(0.0, scatter ** 2 - MAP_SCATTER_FLOOR_PX ** 2))
    assert m.disparity_bound_px == pytest.approx(math.hypot(alone.disparity_bound_px,
                                                            Z95 * excess))
    assert (m.expected_error_mm > alone.expected_error_mm) == (scatter > MAP_SCATTER_FLOOR_PX)
    unrefined = measure_point(result, 200, 120, refine=False)
    assert unrefined.disparity_bound_px == patch.disparity_bound_px
