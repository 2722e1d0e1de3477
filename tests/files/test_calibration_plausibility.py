"""A loaded calibration is a camera pair that could exist, or it is refused naming the field.

The second fault probe found calibration files that loaded and then gave readings of 1e8 to
1e146 mm, or "no distance" at every click (an M2 read with `dt: c`, P2[2,2] = 2147483647). Here
hypothesis (seeded) damages a calibration file the way the probe did: one to three matrix
elements replaced by hostile values or scaled, or a matrix read with another element type. What
loads must hold up in a check independent of the loader's: points in front of the rig, seen by
both cameras through their own lenses (M, D) and placement (R, T), land on the same row of both
rectified images (R1/P1, R2/P2), and Q turns their disparity back into their distance.
"""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from factories import make_calibration

from stereo_gui.core.errors import CalibrationFileError, StereoGuiError
from stereo_gui.core.lens import project_points, undistort_points
from stereo_gui.core.plausibility import check_plausible
from stereo_gui.core.stereo_calibration import MATRIX_NAMES
from stereo_gui.files.calibration_file import calibration_text, load_calibration

GOOD = make_calibration()
HOSTILE = [0.0, -1.0, 1e-300, 1e308, 99999999999.0, 2147483647.0, 1e8, 1e-9, 5.0, 1e6, 0.001,
           -0.0, 127.0]
DTYPES = "cuswif"  # int8, uint8, int16, uint16, int32, float32: what `dt:` may say instead of d


def _geometry_holds(c) -> None:
    """Points 0.6 to 3 m in front of the rig across the left camera's view, seen by the right
    camera too: same rectified row in both images, and Q gives back their distance."""
    w, h = c.image_size
    g = np.linspace(0.1, 0.9, 7)
    u, v = np.meshgrid(g * w, g * h)
    px = np.stack([u.ravel(), v.ravel()], 1)
    rays = undistort_points(c.model, px, c.M1, c.D1)
    R, T = np.asarray(c.R, np.float64), np.asarray(c.T, np.float64).reshape(3)
    seen = 0
    for z in (600.0, 1500.0, 3000.0):
        left = np.hstack([rays * z, np.full((len(rays), 1), z)])
        right_cam = left @ R.T + T
        right_px = project_points(c.model, right_cam, np.zeros(3), np.zeros(3), c.M2, c.D2)
        inside = (np.all(np.isfinite(right_px), axis=1) & (right_px[:, 0] >= 0)
                  & (right_px[:, 0] <= w - 1) & (right_px[:, 1] >= 0) & (right_px[:, 1] <= h - 1)
                  & (right_cam[:, 2] > 0))
        if not inside.any():
            continue
        a = undistort_points(c.model, px[inside], c.M1, c.D1, R=c.R1, P=c.P1)
        b = undistort_points(c.model, right_px[inside], c.M2, c.D2, R=c.R2, P=c.P2)
        assert np.all(np.abs(a[:, 1] - b[:, 1]) < 0.5), "the rectified rows disagree"
        d = a[:, 0] - b[:, 0]
        hom = np.column_stack([a, d, np.ones(len(d))]) @ np.asarray(c.Q, np.float64).T
        z_q = hom[:, 2] / hom[:, 3]
        z_true = (left[inside] @ np.asarray(c.R1, np.float64).T)[:, 2]
        assert np.all(np.abs(z_q - z_true) <= 0.02 * z_true), \
            f"Q gives {z_q.max():.4g} mm for a point at {z_true.max():.4g} mm"
        seen += int(inside.sum())
    assert seen >= 20, "the cameras see almost nothing of what is in front of the rig"


def test_the_good_calibration_holds_up():
    _geometry_holds(GOOD)
    check_plausible(GOOD, "good")


def _with_matrices(text: str, arrays: dict[str, np.ndarray]) -> str:
    """A calibration file's `text` with the named matrices written in place of its own (values
    a StereoCalibration would refuse to hold)."""
    fs = cv2.FileStorage(".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY
                         | cv2.FILE_STORAGE_FORMAT_YAML)
    for name, m in arrays.items():
        fs.write(name, m)
    written = fs.releaseAndGetString()
    for name in arrays:
        block = re.compile(rf"^{name}: !!opencv-matrix\n(?:   .*\n)+", re.M)
        new = block.search(written).group(0)
        text = block.sub(lambda _found: new, text, count=1)
    return text


@st.composite
def damaged_file(draw) -> str:
    arrays = {n: np.array(m) for n, m in GOOD.matrices().items()}
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from(MATRIX_NAMES))
        m = arrays[name].reshape(-1)
        i = draw(st.integers(0, m.size - 1))
        how = draw(st.sampled_from(["hostile", "scale", "any"]))
        if how == "hostile":
            m[i] = draw(st.sampled_from(HOSTILE))
        elif how == "scale":
            m[i] *= draw(st.sampled_from([-1.0, 0.5, 0.9, 0.999, 1.001, 1.01, 2.0, 10.0]))
        else:
            m[i] = draw(st.floats(-1e6, 1e6, allow_nan=False))
    text = _with_matrices(calibration_text(GOOD), arrays)
    if draw(st.booleans()):  # a matrix read with another element type (the probe's `dt: c`)
        name = draw(st.sampled_from(MATRIX_NAMES))
        text = re.sub(rf"(^{name}: !!opencv-matrix\n(?:   .*\n)*?   dt: )d",
                      lambda found: found.group(1) + draw(st.sampled_from(DTYPES)), text,
                      count=1, flags=re.M)
    return text


@settings(max_examples=200, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=damaged_file())
def test_a_damaged_calibration_is_refused_or_a_rig_that_could_exist(tmp_path, text):
    path = tmp_path / "calib.yaml"
    path.write_text(text)
    try:
        calib = load_calibration(path)
    except StereoGuiError:
        return
    _geometry_holds(calib)


def _damaged(**changes):
    return GOOD.with_updates(**changes)


def _with(name, index, value):
    m = np.array(getattr(GOOD, name), np.float64)
    m[index] = value
    return _damaged(**{name: m})


@pytest.mark.parametrize("calib, field", [
    # the probe's: readings of 1e8 to 1e146 mm
    (_with("Q", (3, 2), 1e-11), "Q"),
    (_with("Q", (2, 3), 99999999999.0), "Q"),
    (_with("P2", (0, 3), -1e12), "P2"),
    # the probe's: loaded, then "no distance" at every click
    (_with("P2", (2, 2), 2147483647.0), "P2"),
    (_damaged(M2=np.array([[127.0, 0, 127], [0, 127, 127], [0, 0, 1]])), "M2"),  # dt: c
    # the list: focal lengths, principal points, baseline, R, P1/P2/Q consistency
    (_with("M1", (0, 0), 1.0), "M1"),
    (_with("M1", (0, 2), 5000.0), "M1"),
    (_damaged(T=GOOD.T * 1e-3), "baseline"),
    (_damaged(T=GOOD.T * 1e4), "baseline"),
    (_with("R1", (0, 1), 0.2), "R1"),
    (_with("P1", (1, 2), 300.0), "P1"),
    (_with("D2", (0, 2), -1.0), "D2"),
    (_with("D2", (0, 4), 1e6), "D2"),
    (_with("E", (0, 1), 5.0), "E"),
])
def test_the_probes_calibrations_are_refused_naming_the_field(calib, field):
    with pytest.raises(CalibrationFileError, match=field):
        check_plausible(calib, "calib.yaml")


def test_a_dt_c_matrix_in_a_file_is_refused(tmp_path):
    text = calibration_text(GOOD)
    text = re.sub(r"(^M2: !!opencv-matrix\n(?:   .*\n)*?   dt: )d", r"\1c", text, count=1,
                  flags=re.M)
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(CalibrationFileError, match="M2"):
        load_calibration(tmp_path / "c.yaml")


@pytest.mark.parametrize("model, alphas", [("pinhole", (0.0, 1.0)), ("rational", (0.0,)),
                                           ("fisheye", (0.0, 1.0))])
@pytest.mark.slow
def test_calibrations_made_here_are_plausible(model, alphas):
    """What the application computes passes (its calibrations are saved through these
    checks): each lens model (fisheye on a fisheye rig), and scaled to another size."""
    from stereo_gui.core.board import BoardSpec
    from stereo_gui.core.calibrate import calibrate_stereo
    from stereo_gui.core.detect import detect_pairs
    from stereo_gui.sources.sim import RigConfig, SimRig

    board = BoardSpec()
    rig = SimRig(RigConfig.fisheye(board=board) if model == "fisheye" else RigConfig(board=board),
                 seed=911)
    images = rig.calibration_set(16)
    dets = detect_pairs([(f"{i + 1}", a, b) for i, (a, b) in enumerate(images)], board)
    for alpha in alphas:
        calib = calibrate_stereo(dets, board, alpha=alpha, model=model).calibration
        check_plausible(calib, model)
        check_plausible(calib.scaled_to((320, 240)), f"{model} scaled")
        _geometry_holds(calib)


def test_an_already_rectified_pair_is_plausible():
    from stereo_gui.core.stereo_calibration import StereoCalibration

    calib = StereoCalibration.identity((640, 480), 700.0, 110.0, doffs_px=12.5)
    check_plausible(calib, "rectified:700,110,12.5")
    _geometry_holds(calib)
