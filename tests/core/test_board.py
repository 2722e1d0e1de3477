"""Calibration targets: chessboards, circle grids and ChArUco boards, their points and limits."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec, parse_board
from stereo_gui.core.errors import InputError


def test_chessboard_is_the_default_and_unchanged():
    b = BoardSpec()
    assert (b.cols, b.rows, b.square_mm, b.target) == (9, 6, 25.0, "chessboard")
    assert b == BoardSpec(9, 6, 25.0) and b.point_count == 54 and not b.partial
    pts = b.object_points_mm()
    assert pts.shape == (54, 3) and pts.dtype == np.float32
    np.testing.assert_allclose(pts[1], [25, 0, 0])
    np.testing.assert_allclose(pts[9], [0, 25, 0])
    assert b.label() == "9x6, 25 mm"


def test_symmetric_circle_grid_points():
    b = BoardSpec(7, 6, 20.0, "circles")
    assert b.marker_mm == 10.0  # default diameter: half the spacing
    pts = b.object_points_mm()
    assert pts.shape == (42, 3)
    np.testing.assert_allclose(pts[6], [120, 0, 0])
    np.testing.assert_allclose(pts[7], [0, 20, 0])


def test_asymmetric_circle_grid_points_follow_opencv():
    """OpenCV's asymmetric grid: ((2 j + i % 2) s, i s) for row i, column j."""
    b = BoardSpec(4, 11, 20.0, "acircles")
    pts = b.object_points_mm()
    assert pts.shape == (44, 3)
    np.testing.assert_allclose(pts[:5, :2], [[0, 0], [40, 0], [80, 0], [120, 0], [20, 20]])


def test_charuco_board_counts_squares_and_numbers_its_corners():
    b = BoardSpec(7, 5, 30.0, "charuco", 22.0, "DICT_5X5_100")
    assert b.partial and b.grid_shape == (4, 6) and b.point_count == 24
    pts = b.object_points_mm()
    np.testing.assert_allclose(pts[0], [30, 30, 0])  # the first inner corner, by id
    np.testing.assert_allclose(pts[6], [30, 60, 0])
    assert b.aruco_board().getChessboardSize() == (7, 5)
    assert "DICT_5X5_100" in b.label() and "22" in b.label()
    # default marker size
    assert BoardSpec(7, 5, 40.0, "charuco").marker_mm == 30.0


@pytest.mark.parametrize("kwargs, words", [
    (dict(target="hexagons"), "target must be one of chessboard, "),
    (dict(cols=1), "cols must be a whole number from 2 to 100, not 1"),
    (dict(cols=2), "a chessboard needs at least 3x3 inner corners, not 2x6"),
    (dict(target="charuco", cols=2, rows=5), "at least 3x3"),
    (dict(target="charuco", marker_mm=30.0, square_mm=30.0), "smaller than the squares"),
    (dict(target="charuco", dictionary="DICT_9X9_1"), "dictionary must be one of DICT_4X4_50"),
    (dict(target="charuco", cols=12, rows=10, dictionary="DICT_4X4_50"), "needs 60 markers"),
    (dict(target="circles", marker_mm=30.0), "overlap"),
    (dict(square_mm=-1.0), "square_mm must be a number from 0.01 to 10000 mm, not -1.0"),
    (dict(square_mm=float("nan")), "square_mm must be a number from 0.01 to 10000 mm, not nan"),
    (dict(cols=101), "cols must be a whole number from 2 to 100, not 101"),
    (dict(target="charuco", marker_mm=-1.0), "marker_mm must be a number from 0 to 10000 mm"),
])
def test_impossible_targets_are_refused(kwargs, words):
    args = dict(cols=9, rows=6, square_mm=25.0) | kwargs
    with pytest.raises(InputError, match=words):
        BoardSpec(**args)


def test_json_round_trip_and_old_records():
    for b in (BoardSpec(), BoardSpec(4, 11, 15.0, "acircles"),
              BoardSpec(8, 6, 25.0, "charuco", 18.0, "DICT_6X6_250")):
        assert BoardSpec.from_json(b.to_json()) == b
    assert BoardSpec.from_json({"cols": 9, "rows": 6, "square_mm": 30}) == BoardSpec(9, 6, 30.0)


def test_parse_board_names_the_unit_of_the_target():
    assert parse_board("7x5", 30, "charuco", 22) == BoardSpec(7, 5, 30.0, "charuco", 22.0)
    with pytest.raises(InputError, match="squares as COLSxROWS"):
        parse_board("seven", 30, "charuco")
    with pytest.raises(InputError, match="inner corners"):
        parse_board("9-6")


def test_outline_holds_every_point_with_a_white_border():
    for b in (BoardSpec(), BoardSpec(7, 6, 20.0, "circles"), BoardSpec(4, 11, 20.0, "acircles"),
              BoardSpec(7, 5, 30.0, "charuco", 22.0)):
        a0, b0, a1, b1 = b.outline_mm()
        pts = b.object_points_mm()
        assert pts[:, 0].min() - a0 >= 0.5 * b.square_mm - 1e-6
        assert a1 - pts[:, 0].max() >= 0.5 * b.square_mm - 1e-6
        assert pts[:, 1].min() - b0 >= 0.5 * b.square_mm - 1e-6
        assert b1 - pts[:, 1].max() >= 0.5 * b.square_mm - 1e-6
