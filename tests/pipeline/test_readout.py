"""The Live tab's pointer reading and distance labels, without Qt."""

import math

import numpy as np
import pytest

from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.measure import Reason, measure_point
from stereo_gui.core.preset import MatcherParams
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.readout import (
    disparity_of_view,
    format_distance,
    format_error,
    read_pointer,
    readout_line,
)


def test_one_unit_rule_distances_in_metres_errors_in_millimetres():
    assert format_distance(999.94) == "1.000 m"
    assert format_distance(812.0) == "0.812 m"
    assert format_distance(1500.0) == "1.500 m"
    assert format_distance(math.nan) == "–"
    assert format_error(4.06) == "± 4.1 mm"
    assert format_error(math.inf) == "± ∞"


def _plane_result():
    w, h, shift = 160, 120, 10
    rng = np.random.default_rng(1)
    big = (rng.random((h, w + shift, 3)) * 200 + 20).astype(np.uint8)
    left, right = np.ascontiguousarray(big[:, :w]), np.ascontiguousarray(big[:, shift:shift + w])
    calib = StereoCalibration.identity((w, h), 300.0, 100.0)  # Z = 30000 / d mm
    pipeline = StereoPipeline(calib, MatcherParams(num_disparities=32, block_size=5, wls=False))
    try:
        return pipeline.process(left, right)
    finally:
        pipeline.close()


def test_pointer_reading_is_the_click_measurement():
    r = _plane_result()
    assert readout_line(read_pointer(None, "wls", 10, 10, 9)).endswith("no frame yet")
    assert "outside the image" in readout_line(read_pointer(r, "wls", 165, 10, 9))
    right = read_pointer(r, "right", 80, 60, 9)
    assert right.measurement is None and "right image" in readout_line(right)
    reading = read_pointer(r, "closed", 100.3, 60.0, 9)
    click = measure_point(r, 100.3, 60.0, patch=9)
    assert reading.measurement == click  # every field: distance, bound, reason
    line = readout_line(reading)
    assert "Z 3.000 m" in line and "± " in line and "mm" in line, line
    # at the left border the right camera cannot see the point: the click's reason
    edge = read_pointer(r, "wls", 2, 60, 9)
    assert not edge.measurement.valid
    assert edge.measurement.reason in readout_line(edge)
    assert disparity_of_view(r, "raw") is r.disparity_px
    assert disparity_of_view(r, "left") is r.final_px


class _Truth:
    """Ground truth of a frame that knows the scene (as the simulated rig's frames do)."""

    def point_rectified(self, calib, x, y):
        return np.array([0.0, 0.0, 3000.0])


def test_true_distance_is_shown_and_labelled_when_the_frame_carries_truth():
    r = _plane_result()
    reading = read_pointer(r, "wls", 100, 60, 9, truth=_Truth())
    assert reading.true_z_mm == pytest.approx(3000.0)
    assert "TRUE (simulated scene): Z 3.000 m" in readout_line(reading)
    assert read_pointer(r, "wls", 100, 60, 9, truth=None).true_z_mm is None


def test_the_line_says_why_the_reading_and_the_map_under_it_differ():
    """A click reads its patch, aligned with the right image; the map under the pointer is one
    pixel's value. Where they differ by more than the reading's bound the line says both."""
    from dataclasses import replace

    r = _plane_result()
    reading = read_pointer(r, "depth", 100, 60, 9)
    assert reading.measurement.valid and np.isfinite(reading.map_px)
    assert "the map" not in readout_line(reading)  # a plane: one number for the pixel
    m = reading.measurement
    apart = replace(reading, map_px=m.disparity_px + 5 * m.disparity_bound_px + 0.1)
    assert f"the map says {apart.map_px:.2f} px at this pixel" in readout_line(apart)
    hole = replace(reading, map_px=float("nan"))
    assert "the map has no value at this pixel" in readout_line(hole)
    # a refusal where the depth view shows a value says so: the two differ, and why is shown
    refused = replace(reading, measurement=replace(m, valid=False, reason=Reason.AMBIGUOUS))
    line = readout_line(refused)
    assert "no distance: ambiguous match" in line
    assert f"the map says {refused.map_px:.2f} px at this pixel: the click does not take" in line
    assert "the map" not in readout_line(replace(refused, map_px=float("nan")))
