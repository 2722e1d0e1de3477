"""The click benchmark's scoring (`core.click_score`) on made-up truths and readings."""

import math

import numpy as np
import pytest

from stereo_gui.core.click_score import (
    Click, ClickScore, click_points, map_right, plain_patch_disparity, seen_by_both, true_z_mm,
    true_z_span_mm, truth_step_px)
from stereo_gui.core.stereo_calibration import StereoCalibration


def _box_truth(w=120, h=40, far=10.0, near=30.0, x0=60, x1=90):
    """A far wall with a nearer box in columns x0..x1-1: the box hides from the right camera the
    wall just left of it, and the right camera sees nothing left of column `far`."""
    t = np.full((h, w), far, np.float32)
    t[:, x0:x1] = near
    return t


def test_seen_by_both_marks_what_a_nearer_surface_hides_and_the_left_edge():
    t = _box_truth()
    seen = seen_by_both(t)
    # the wall left of the box whose right-image columns the box covers (x - 10 > 60 - 30 - 1)
    assert not seen[:, 45:60].any()
    assert seen[:, 20:40].all() and seen[:, 60:90].all() and seen[:, 95:].all()
    # a pixel whose match falls left of the right image is not seen either
    assert not seen[:, :10].any() and seen[:, 10:12].all()


def test_unknown_truth_is_never_seen_and_hides_nothing():
    t = _box_truth()
    t[:, 70:75] = 0
    seen = seen_by_both(t)
    assert not seen[:, 70:75].any() and seen[:, 75:90].all()


def test_click_points_keep_only_patches_known_and_seen_whole():
    t = _box_truth(w=220, h=80)
    seen = seen_by_both(t)
    points = click_points(t, seen, grid=(11, 4), patch=9)
    assert points and all(seen[y - 4:y + 5, x - 4:x + 5].all() for x, y in points)
    xs = sorted({x for x, _ in points})
    # the grid's columns sit at the cells' centres; the ones in the hidden strip are dropped
    assert 30 in xs and 70 in xs
    assert 10 not in xs and 50 not in xs  # the left edge's, the hidden strip's
    assert len({y for _, y in points}) == 4


def test_a_sparse_truth_needs_its_centre_and_a_third_of_the_patch():
    t = np.zeros((80, 220), np.float32)
    t[::2, ::2] = 20.0  # a quarter known (every grid point's centre too): under a third
    t[:, 100:120] = 20.0  # known whole around the grid's column at 110
    points = click_points(t, t > 0, grid=(11, 4))
    assert {x for x, _ in points} == {110} and len(points) == 4
    t[:, 100:120] = 0.0
    t[:, 100:120:2] = 20.0  # half of those columns: still over a third of each patch
    assert {x for x, _ in click_points(t, t > 0, grid=(11, 4))} == {110}


def test_plain_reads_the_patch_median_with_enough_values():
    d = np.full((20, 20), np.nan, np.float32)
    d[5:10, 5:10] = 12.0
    d[5, 5] = 40.0
    assert plain_patch_disparity(d, 7, 7) == 12.0
    d[5:10, 5:10] = np.nan
    d[6, 6:10] = 12.0  # four values: fewer than five
    assert math.isnan(plain_patch_disparity(d, 7, 7))


def test_true_z_and_a_right_map_go_through_the_calibration():
    calib = StereoCalibration.identity((200, 100), 1000.0, 100.0)
    assert true_z_mm(calib, 100, 50, 20.0) == pytest.approx(5000.0)
    assert map_right(calib, 100, 50, 20.4, 20.0, 5000.0)  # within 0.5 px
    assert map_right(calib, 100, 50, 80.9, 80.0, 1250.0)  # 0.9 px but within 2 % of Z
    assert not map_right(calib, 100, 50, 21.0, 20.0, 5000.0)
    assert not map_right(calib, 100, 50, float("nan"), 20.0, 5000.0)


def test_the_sums_count_shares_of_the_clicks_and_of_the_readings():
    clicks = [Click(0, 0, 1000.0, 1005.0, 10.0),  # 0.5 %, covered
              Click(0, 0, 1000.0, 1015.0, 10.0),  # 1.5 %, not covered
              Click(0, 0, 1000.0, 1100.0, 200.0),  # 10 %, covered
              Click(0, 0, 1000.0, reason="ambiguous match", map_right=True),
              Click(0, 0, 1000.0, reason="ambiguous match", map_right=False),
              Click(0, 0, 1000.0, reason="no texture", map_right=False)]
    s = ClickScore().add(clicks).summary()
    assert s["points"] == 6 and s["read"] == pytest.approx(0.5)
    assert s["within_1pct"] == pytest.approx(1 / 6) and s["within_2pct"] == pytest.approx(2 / 6)
    assert s["worst"] == pytest.approx(0.1) and s["covers"] == pytest.approx(2 / 3)
    # the +- judged on the readings of the clicked surface (within 5 %) alone: the 10 % one,
    # covered by a wide +-, is not among them
    assert s["covers_within_5pct"] == pytest.approx(1 / 2)
    assert s["reasons"] == {"ambiguous match": {"refused": 2, "map_right": 1},
                            "no texture": {"refused": 1, "map_right": 0}}
    empty = ClickScore().summary()
    assert empty["points"] == 0 and empty["read"] is None and empty["worst"] is None
    assert empty["covers_within_5pct"] is None


def test_a_truth_stored_in_steps_is_told_from_one_stored_as_numbers():
    rng = np.random.default_rng(3)
    thirds = np.round(rng.uniform(5, 60, (40, 50)) * 3) / 3  # a third-size scene's whole pixels
    thirds[:5] = 0  # unknown
    assert truth_step_px(thirds.astype(np.float32)) == pytest.approx(1 / 3, rel=1e-4)
    assert truth_step_px(np.round(rng.uniform(1, 15, (40, 50)))) == pytest.approx(1.0)
    assert truth_step_px(rng.uniform(5, 60, (40, 50)).astype(np.float32)) == 0.0  # numbers
    kitti = np.round(rng.uniform(5, 60, (40, 50)) * 256) / 256  # 1/256 px: as good as numbers
    assert truth_step_px(kitti) == 0.0
    assert truth_step_px(np.full((4, 4), 16.0, np.float32)) == 0.0  # one value: no step seen
    planes = np.repeat(np.array([16.0, 24.0, 32.0, 40.0, 48.0], np.float32), 4)
    assert truth_step_px(planes[None, :]) == 0.0  # a grid coarser than a pixel: exact planes
    assert truth_step_px(planes[None, :4]) == 0.0  # (and four values show no grid at all)
    assert truth_step_px(np.array([[16.0, 17.0, 18.0, 20.0]])) == 0.0
    assert truth_step_px(np.zeros((4, 4), np.float32)) == 0.0


def test_the_bound_covers_a_stepped_truth_where_it_reaches_the_steps_span():
    """tsukuba's truth is whole pixels: a true 5 px is anywhere in 4.5..5.5 px. A reading of
    5.3 px +- 0.1 px misses 5.0 but reaches the span; one of 5.7 px +- 0.1 px reaches neither."""
    calib = StereoCalibration.identity((200, 100), 1000.0, 100.0)
    fb = 1000.0 * 100.0
    near, far = true_z_span_mm(calib, 100, 50, 5.0, 1.0)
    assert (near, far) == pytest.approx((fb / 5.5, fb / 4.5))
    assert true_z_span_mm(calib, 100, 50, 0.4, 1.0)[1] == math.inf  # past infinity

    def click(d_read, span):
        z = fb / d_read
        bound = fb / (d_read - 0.1) - z
        return Click(100, 50, fb / 5.0, z, bound, true_z_span=span)

    assert not click(5.3, None).covered
    assert click(5.3, (near, far)).covered and click(4.7, (near, far)).covered
    assert not click(5.7, (near, far)).covered and not click(4.3, (near, far)).covered


def test_a_reading_inside_a_stepped_truths_span_is_not_counted_wrong():
    """tsukuba's true 5 px is anywhere in 4.5..5.5 px: a reading of 4.7 px (6 % from 5.0 in Z)
    is inside that span, error 0; one of 4.3 px is judged by its distance from the span's far
    end (4.5 px), not from 5.0; plain's readings are judged alike. An exact truth keeps
    |Z - true Z|."""
    calib = StereoCalibration.identity((200, 100), 1000.0, 100.0)
    fb = 1000.0 * 100.0
    span = true_z_span_mm(calib, 100, 50, 5.0, 1.0)
    inside = Click(100, 50, fb / 5.0, fb / 4.7, 1.0, true_z_span=span)
    outside = Click(100, 50, fb / 5.0, fb / 4.3, 1.0, true_z_span=span)
    assert inside.error_share == 0.0
    assert outside.error_share == pytest.approx((fb / 4.3 - fb / 4.5) / (fb / 5.0))
    assert Click(100, 50, fb / 5.0, fb / 4.7, 1.0).error_share == pytest.approx(5.0 / 4.7 - 1.0)
    assert math.isnan(Click(100, 50, fb / 5.0, true_z_span=span).error_share)
    s = ClickScore().add([inside, outside]).summary()
    assert s["within_2pct"] == pytest.approx(0.5)
    assert s["worst"] == pytest.approx(outside.error_share)
