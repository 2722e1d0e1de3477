"""The Live tab's readout line and distance labels, without Qt."""

import math

import numpy as np

from stereo_gui.core.matching import MatcherParams, StereoPipeline
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.readout import disparity_of_view, format_distance, pointer_readout


def test_format_distance():
    assert format_distance(999.94) == "999.9 mm"
    assert format_distance(1500.0) == "1.500 m"
    assert format_distance(math.nan) == "–"


def test_pointer_readout_on_a_plane():
    w, h, shift = 160, 120, 10
    rng = np.random.default_rng(1)
    big = (rng.random((h, w + shift, 3)) * 200 + 20).astype(np.uint8)
    left, right = np.ascontiguousarray(big[:, :w]), np.ascontiguousarray(big[:, shift:shift + w])
    calib = StereoCalibration.identity((w, h), 300.0, 100.0)  # Z = 30000 / d mm
    pipeline = StereoPipeline(calib, MatcherParams(num_disparities=32, block_size=5, wls=False))
    try:
        r = pipeline.process(left, right)
    finally:
        pipeline.close()
    assert pointer_readout(None, "wls", 10, 10) == "no frame yet"
    assert "outside the image" in pointer_readout(r, "wls", w + 5, 10)
    assert "right image" in pointer_readout(r, "right", 80, 60)
    assert "no match" in pointer_readout(r, "raw", 0, 60)  # the left border cannot match
    text = pointer_readout(r, "closed", 100, 60)
    assert "valid" in text and "distance (Z) 3.000 m" in text, text
    assert disparity_of_view(r, "raw") is r.disparity_px
    assert disparity_of_view(r, "left") is r.final_px
