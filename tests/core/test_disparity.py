"""Disparity maps: fixed point, masks, agreement, occlusion, enlargement."""


import cv2
import numpy as np
import pytest

from stereo_gui.core.disparity import fixed_to_px


def test_fixed_point_is_divided_once_and_invalid_is_nan():
    d16 = np.array([[16 * 10 + 8, 16, 32]], np.int16)  # 10.5 px, (min-1)*16 invalid, 2 px
    out = fixed_to_px(d16, min_disparity=2)
    assert out[0, 0] == pytest.approx(10.5) and np.isnan(out[0, 1]) and out[0, 2] == 2.0
    assert fixed_to_px(d16, 2, factor=2.0)[0, 0] == pytest.approx(21.0)


def test_blank_sets_nan_where_the_mask_is_set_in_place():
    from stereo_gui.core.disparity import blank

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
    from stereo_gui.core.disparity import unseen_columns, unseen_mask, unseen_strip

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
    from stereo_gui.core.colouring import paint
    from stereo_gui.core.disparity import blank

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


def test_blank_mask_finds_noise_alone_whatever_the_texture_would_be():
    """Nothing but sensor noise is blank; a weak smooth texture (weaker than the noise per
    pixel, but correlated over pixels) is not, nor is a strong texture as fine as noise."""
    from stereo_gui.core.disparity import blank_mask

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
    from stereo_gui.core.disparity import sensor_noise

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
    from stereo_gui.core.disparity import nearest_source

    for small, big in (((160, 120), (320, 240)), ((111, 93), (222, 185)), ((80, 67), (443, 370))):
        src = np.arange(small[0] * small[1], dtype=np.float32).reshape(small[1], small[0])
        out = cv2.resize(src, big, interpolation=cv2.INTER_NEAREST)
        ys, xs = nearest_source(big[1], small[1]), nearest_source(big[0], small[0])
        assert np.array_equal(out, src[ys[:, None], xs[None, :]])


def test_agreement_keeps_the_mean_where_both_windows_match_and_agree():
    from stereo_gui.core.disparity import agreement

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
    from stereo_gui.core.disparity import occluded

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
    from stereo_gui.core.disparity import enlarge

    m = np.array([[10.0, 10.5, 30.0, np.nan]], np.float32).repeat(2, axis=0)
    big = enlarge(m, (8, 4), 1.0)
    assert big.shape == (4, 8)
    assert 10.0 < big[0, 2] < 10.5  # between two pixels of one surface: interpolated
    assert set(np.unique(big[:, 3:6][np.isfinite(big[:, 3:6])])) <= {10.5, 30.0}  # the edge
    assert np.isnan(big[:, 7]).all()  # the hole stays a hole
