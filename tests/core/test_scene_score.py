"""Scoring a disparity map against ground truth, on maps made in the test."""

import math

import numpy as np
import pytest

from stereo_gui.core.scene_score import disparity_search_range, plain_sgbm, score_disparity


def test_bad_rates_and_density_count_known_pixels_with_a_value():
    truth = np.array([[10, 10, 10, 10, 0]], np.float32)  # the last pixel is unknown
    nan = np.nan
    # errors 0.5, 1.5, 3, (none), and a value where the truth is unknown (not counted)
    d = np.array([[10.5, 11.5, 13.0, nan, 99.0]], np.float32)
    s = score_disparity(d, truth)
    assert s.known == 4
    assert s.density == pytest.approx(3 / 4)
    assert s.bad1 == pytest.approx(2 / 3)  # 1.5 and 3 exceed 1 px
    assert s.bad2 == pytest.approx(1 / 3)  # only 3 exceeds 2 px
    assert s.bad4 == 0.0
    assert s.median_error_px == pytest.approx(1.5)
    assert s.correct_density == pytest.approx(3 / 4 * 2 / 3)
    assert s.to_dict()["correct_density"] == s.correct_density  # each scene's, in --json


def test_an_error_of_exactly_the_threshold_is_not_bad():
    truth = np.full((2, 2), 20.0, np.float32)
    s = score_disparity(truth + np.float32(2.0), truth)
    assert s.bad2 == 0.0 and s.bad1 == 1.0 and s.density == 1.0


def test_a_map_without_values_has_no_error_rate_and_no_density():
    truth = np.full((3, 3), 5.0, np.float32)
    s = score_disparity(np.full((3, 3), np.nan, np.float32), truth)
    assert s.density == 0.0 and math.isnan(s.bad2) and s.correct_density == 0.0


def test_shapes_must_agree():
    with pytest.raises(ValueError):
        score_disparity(np.zeros((2, 3), np.float32), np.zeros((3, 2), np.float32))


def test_search_range_covers_the_truth_with_a_margin_in_steps_of_16():
    assert disparity_search_range(np.array([[0, 50]], np.float32)) == 64  # 57.5 -> 64
    assert disparity_search_range(np.array([[0, 56]], np.float32)) == 80  # 64.4 -> 80
    assert disparity_search_range(np.zeros((2, 2), np.float32)) == 16


def test_plain_baseline_finds_a_shifted_texture_at_full_and_reduced_size():
    rng = np.random.default_rng(2)
    h, w, shift = 120, 200, 16
    big = rng.integers(0, 256, (h, w + shift, 3), np.uint8)
    left, right = np.ascontiguousarray(big[:, :w]), np.ascontiguousarray(big[:, shift:])
    for scale in (1.0, 0.5):
        d = plain_sgbm(left, right, 48, scale)
        assert d.shape == (h, w)
        inner = d[10:-10, 60:-10]
        assert np.nanmedian(inner) == pytest.approx(shift, abs=0.5), scale
        assert np.isfinite(inner).mean() > 0.9
