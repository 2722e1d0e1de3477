"""A StereoCalibration and its pair errors check themselves when they are built: what no camera
has is refused with CalibrationValueError naming the field, real calibrations are accepted, and
what was accepted cannot be changed afterwards."""

from __future__ import annotations

import math

import numpy as np
import pytest
from factories import make_calibration

from stereo_gui.core.errors import CalibrationFileError, CalibrationValueError
from stereo_gui.core.stereo_calibration import PairError, StereoCalibration
from stereo_gui.core.uncertainty import CalibrationUncertainty, parameter_names
from stereo_gui.sources.sim import RigConfig, SimRig

GOOD = make_calibration()


def _with(name: str, index: tuple[int, ...], value: float) -> dict:
    m = np.array(GOOD.matrices()[name])
    m[index] = value
    return {name: m}


def _uncertainty(names: tuple[str, ...], model: str = "pinhole") -> CalibrationUncertainty:
    return CalibrationUncertainty(names, np.eye(len(names)) * 1e-6, 0.05, "jacobian", model)


@pytest.mark.parametrize("calib", [
    GOOD,
    make_calibration(1.0),
    SimRig(seed=0).true_calibration(),
    SimRig(RigConfig.fisheye(), seed=0).true_calibration(),
    StereoCalibration.identity((640, 480), 700.0, 110.0, doffs_px=12.5),
    GOOD.with_updates(rms_stereo=float("nan"), method="hartley", per_pair=()),
    GOOD.scaled_to((320, 240)),
], ids=["made-up", "alpha-1", "rig", "fisheye-rig", "identity", "hartley", "scaled"])
def test_real_calibrations_are_accepted_and_hold_read_only_float64_arrays(calib):
    for name, m in calib.matrices().items():
        assert m.dtype == np.float64, name
        with pytest.raises(ValueError):  # a value: its arrays cannot be changed in place
            m.flat[0] = 1.0
    assert calib.with_updates().matrices().keys() == calib.matrices().keys()


def test_the_arrays_are_copies_of_what_it_was_built_with():
    M1 = np.array(GOOD.M1)
    calib = GOOD.with_updates(M1=M1)
    M1[0, 0] = -1.0
    assert calib.M1[0, 0] == GOOD.M1[0, 0]


@pytest.mark.parametrize("changes, message", [
    # shapes
    ({"P1": np.eye(3)}, "matrix P1 should be 3x4, found 3x3"),
    ({"T": GOOD.T.reshape(3)}, "matrix T should be 3x1, found 3"),
    ({"Q": None}, "matrix Q is missing"),
    ({"D1": np.zeros((1, 3))}, "distortion D1 should have 4, 5, 8, 12 or 14 coefficients, found 3"),
    ({"optimal_M2": np.eye(4)}, "matrix optimal_M2 should be a finite 3x3"),
    # finite values
    (_with("M2", (0, 1), math.nan), "matrix M2 holds values that are not finite"),
    (_with("Q", (3, 3), math.inf), "matrix Q holds values that are not finite"),
    (_with("D2", (0, 0), math.nan), "distortion D2 holds values that are not finite"),
    ({"optimal_M1": np.full((3, 3), math.nan)}, "matrix optimal_M1 should be a finite 3x3"),
    ({"rms_left": math.inf}, "rms_left is inf; it must be a finite number of pixels >= 0"),
    ({"rms_stereo": math.nan}, "rms_stereo is not a number"),  # known: it has per-pair errors
    ({"alpha": math.nan}, "alpha must be a number from 0 to 1, not nan"),
    # positive focal lengths
    (_with("M1", (0, 0), 0.0), "matrix M1 has focal lengths 0, "),
    (_with("M2", (1, 1), -745.0), "matrix M2 has focal lengths 745.3, -745 px"),
    (_with("P1", (0, 0), 0.0), "matrix P1 has focal lengths 0, "),
    (_with("P2", (1, 1), -1.0), "matrix P2 has focal lengths"),
    # the rest of what no camera has
    (_with("M1", (2, 2), 2.0), "matrix M1 is not a camera matrix"),
    (_with("R", (0, 1), 0.5), "matrix R is not a rotation"),
    ({"T": np.zeros((3, 1))}, "T gives a baseline of 0 mm"),
    ({"R1": np.zeros((3, 3))}, "matrix R1 is singular"),
    (_with("P2", (0, 3), 0.0), "matrix P2 has no baseline term"),
    (_with("Q", (3, 2), 0.0), "matrix Q cannot turn disparities into distances"),
    (_with("D1", (0, 0), 2e6), "distortion D1 holds coefficients above 1e+06"),
    ({"image_size": (0, 480)}, "image size 0x480 is not valid"),
    ({"scaled_from": (1280, 720)}, "scaled_from size 1280x720 does not have the aspect ratio"),
    ({"method": "guess"}, "unknown method 'guess'"),
    ({"model": "kaleidoscope"}, "unknown lens model 'kaleidoscope'"),
    ({"model": "fisheye"}, "a fisheye calibration needs 4 distortion coefficients per camera"),
    ({"D2": np.zeros((1, 8))}, "distortion D1 has 5 coefficients and D2 8"),
    ({"alpha": 1.5}, "alpha must be a number from 0 to 1, not 1.5"),
    ({"alpha": -0.5}, "alpha must be a number from 0 to 1, not -0.5"),
    ({"epipolar_error_px": -0.1}, "epipolar_error_px is -0.1"),
])
def test_what_no_camera_has_is_refused_on_construction_naming_it(changes, message):
    with pytest.raises(CalibrationValueError) as caught:
        GOOD.with_updates(**changes)
    assert message in str(caught.value)
    assert isinstance(caught.value, CalibrationFileError)  # what callers already catch


def test_unknown_quality_figures_are_allowed_where_a_calibration_has_none():
    imported = GOOD.with_updates(per_pair=(), rms_left=math.nan, rms_right=math.nan,
                                 rms_stereo=math.nan, epipolar_error_px=math.nan)
    assert math.isnan(imported.rms_left)
    hartley = GOOD.with_updates(method="hartley", rms_stereo=math.nan)
    assert hartley.per_pair and math.isnan(hartley.rms_stereo)


def test_an_uncertainty_over_parameters_this_calibration_does_not_have_is_refused():
    names = parameter_names("pinhole", 5)
    assert GOOD.with_updates(uncertainty=_uncertainty(names)).uncertainty.names == names
    # a parameter of pinhole lenses, but not of a calibration with 5 coefficients per camera
    with pytest.raises(CalibrationValueError, match=r"'left\.k6', which is not a parameter of "
                                                    r"this calibration \(pinhole lenses, 5"):
        GOOD.with_updates(uncertainty=_uncertainty((*names, "left.k6")))
    with pytest.raises(CalibrationValueError, match="uncertainty is of fisheye lenses"):
        GOOD.with_updates(uncertainty=_uncertainty(("left.fx", "T.x"), "fisheye"))


def test_a_pair_error_is_a_finite_number_of_pixels():
    assert PairError("07", 0.0, 2 / 7).error_right == 2 / 7
    for left, right, words in ((math.nan, 0.1, "error_left is nan"),
                               (0.1, -0.5, "error_right is -0.5"),
                               (0.1, math.inf, "error_right is inf"),
                               ("not a number", 0.1, "error_left is nan")):
        with pytest.raises(CalibrationValueError, match=f"pair 07: {words}"):
            PairError("07", left, right)


def test_a_rotation_written_to_four_decimals_is_still_a_rotation():
    """Calibrations written by hand or by other tools round R; to four decimals R^T R leaves
    the identity by up to about 1e-4, which is no reason to refuse the file."""
    import cv2

    R = cv2.Rodrigues(np.array([[0.013], [-0.021], [0.007]]))[0]
    rounded = np.round(R, 4)
    assert not np.allclose(rounded.T @ rounded, np.eye(3), atol=1e-5)
    assert GOOD.with_updates(R=rounded).R == pytest.approx(rounded)
    with pytest.raises(CalibrationValueError, match="matrix R is not a rotation"):
        GOOD.with_updates(R=R * 1.005)  # R^T R 1 % off the identity


def test_opencvs_default_alpha_is_kept_from_files_made_elsewhere():
    """OpenCV's samples rectify with alpha -1 (stereoRectify's own choice) and write it: such a
    calibration loads, as it did."""
    assert GOOD.with_updates(alpha=-1.0).alpha == -1.0
