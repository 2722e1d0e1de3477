"""Kalibr's camchain.yaml and the EuRoC sensor.yaml pair: written from the simulated rig's truth
(by our writer, and by hand in each format's own layout), read back through
load_any_calibration, then used: rectified board pictures, distances to a wall; bad files give
a CalibrationFileError naming the file and the problem.

The default rig's lenses have a k3 term, which Kalibr's radtan (k1 k2 p1 p2) cannot hold (that
refusal is tested too): the round trips use the same rig with k3 = 0, and its fisheye twin.
"""

from __future__ import annotations

import re
import sys

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings

from stereo_gui.core.detect import detect_pair
from stereo_gui.core.errors import CalibrationFileError, InputError, StereoGuiError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.measure import measure_point
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.kalibr_calibration import (
    kalibr_camchain_text,
    read_euroc_pair,
    read_kalibr_camchain,
    write_kalibr_camchain,
)
from stereo_gui.files.presets import load_preset
from stereo_gui.sources.sim import CameraTruth, RigConfig, Scene, SimRig

WALL_MM = 1500.0
# rectified pixels over the whole frame (centre, corners' quarters, edges)
POINTS = ((320, 240), (200, 150), (450, 330), (560, 420), (100, 100), (560, 80), (80, 400))
VERTICAL_PX = 0.2


def _without_k3(cam: CameraTruth) -> CameraTruth:
    D = cam.D.copy()
    D[0, 4] = 0.0
    return CameraTruth(cam.M, D)


@pytest.fixture(scope="module")
def rig() -> SimRig:
    """SimRig(seed=0) with k3 = 0: lenses Kalibr's radtan and EuRoC's radial-tangential hold."""
    base = RigConfig()
    return SimRig(RigConfig(left=_without_k3(base.left), right=_without_k3(base.right)), seed=0)


@pytest.fixture(scope="module")
def fisheye_rig() -> SimRig:
    return SimRig(RigConfig.fisheye(), seed=0)


# ---- the formats' own layouts, written by hand ---------------------------------------------
def _flow(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in np.asarray(values).reshape(-1)) + "]"


def _T_c1_c0(truth) -> np.ndarray:
    """The 4x4 transform cam0 -> cam1 in metres."""
    m = np.eye(4)
    m[:3, :3] = truth.R
    m[:3, 3] = truth.T.reshape(3) / 1000.0
    return m


def _kalibr_camera(M, D, size, distortion="radtan") -> str:
    return (f"  camera_model: pinhole\n"
            f"  intrinsics: {_flow((M[0, 0], M[1, 1], M[0, 2], M[1, 2]))}\n"
            f"  distortion_model: {distortion}\n"
            f"  distortion_coeffs: {_flow(np.asarray(D).reshape(-1)[:4])}\n"
            f"  resolution: [{size[0]}, {size[1]}]\n")


def camchain_text(truth, distortion="radtan") -> str:
    """A camchain as kalibr_calibrate_cameras writes it (IMU fields as kalibr_calibrate_imu_camera
    adds them), from the rig's truth."""
    size = truth.image_size
    rows = "".join(f"  - {_flow(r)}\n" for r in _T_c1_c0(truth))
    return ("cam0:\n"
            "  T_cam_imu:\n"
            "  - [0.0, -1.0, 0.0, 0.02]\n  - [1.0, 0.0, 0.0, -0.06]\n"
            "  - [0.0, 0.0, 1.0, 0.01]\n  - [0.0, 0.0, 0.0, 1.0]\n"
            "  cam_overlaps: [1]\n"
            + _kalibr_camera(truth.M1, truth.D1, size, distortion)
            + "  rostopic: /cam0/image_raw\n"
            "  timeshift_cam_imu: -8.1e-05\n"
            "cam1:\n"
            "  T_cn_cnm1:\n" + rows
            + "  cam_overlaps: [0]\n"
            + _kalibr_camera(truth.M2, truth.D2, size, distortion)
            + "  rostopic: /cam1/image_raw\n")


# where the body (IMU) frame puts cam0: EuRoC's cameras look sideways from the body
T_BS0 = np.eye(4)
T_BS0[:3, :3] = cv2.Rodrigues(np.array([0.02, -0.01, 1.57]))[0]
T_BS0[:3, 3] = (-0.0216, -0.0647, 0.0098)


def _euroc_sensor(M, D, size, T_BS, comment) -> str:
    data = ",\n         ".join(", ".join(repr(float(v)) for v in row) for row in T_BS)
    return ("# General sensor definitions.\n"
            "sensor_type: camera\n"
            f"comment: {comment}\n\n"
            "# Sensor extrinsics wrt. the body-frame.\n"
            "T_BS:\n  cols: 4\n  rows: 4\n"
            f"  data: [{data}]\n\n"
            "# Camera specific definitions.\n"
            "rate_hz: 20\n"
            f"resolution: [{size[0]}, {size[1]}]\n"
            "camera_model: pinhole\n"
            f"intrinsics: {_flow((M[0, 0], M[1, 1], M[0, 2], M[1, 2]))} #fu, fv, cu, cv\n"
            "distortion_model: radial-tangential\n"
            f"distortion_coefficients: {_flow(np.asarray(D).reshape(-1)[:4])}\n")


def write_euroc(folder, truth):
    """mav0/cam0/sensor.yaml and mav0/cam1/sensor.yaml of the rig: T_BS1 puts cam1 where the
    truth's R, T say (T_BS1 = T_BS0 inv(T_c1_c0))."""
    T_BS1 = T_BS0 @ np.linalg.inv(_T_c1_c0(truth))
    paths = []
    for k, (M, D, T_BS) in enumerate(((truth.M1, truth.D1, T_BS0), (truth.M2, truth.D2, T_BS1))):
        (folder / "mav0" / f"cam{k}").mkdir(parents=True, exist_ok=True)
        path = folder / "mav0" / f"cam{k}" / "sensor.yaml"
        path.write_text(_euroc_sensor(M, D, truth.image_size, T_BS, f"simulated cam{k}"))
        paths.append(path)
    return paths


def _assert_truth(calib, truth, rtol=1e-9):
    for name in ("M1", "D1", "M2", "D2", "R", "T"):
        np.testing.assert_allclose(getattr(calib, name), np.asarray(getattr(truth, name)).reshape(
            getattr(calib, name).shape), rtol=rtol, atol=1e-12, err_msg=name)
    assert calib.image_size == tuple(truth.image_size)
    assert calib.model == truth.model


@pytest.fixture(scope="module")
def loaded(rig, tmp_path_factory):
    """The rig's truth written by hand as a camchain and as a EuRoC pair, loaded."""
    d = tmp_path_factory.mktemp("robotics")
    chain = d / "camchain.yaml"
    chain.write_text(camchain_text(rig.truth))
    cam0, _ = write_euroc(d, rig.truth)
    return {"kalibr": load_any_calibration(chain), "euroc": load_any_calibration(cam0)}


# ---- round trips -----------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["pinhole", "fisheye"])
def test_the_rigs_truth_round_trips_through_a_camchain(tmp_path, rig, fisheye_rig, which):
    true = (rig if which == "pinhole" else fisheye_rig).true_calibration()
    path = write_kalibr_camchain(tmp_path / "camchain.yaml", true)
    doc = yaml.safe_load(path.read_text())
    assert doc["cam0"]["distortion_model"] == ("radtan" if which == "pinhole" else "equidistant")
    assert doc["cam1"]["T_cn_cnm1"][0][3] == pytest.approx(true.T[0, 0] / 1000.0)  # metres
    got = load_any_calibration(path)
    assert got.kind == "kalibr" and got.files == (path,) and "camchain.yaml" in got.description
    back = got.calibration
    for name in ("M1", "D1", "M2", "D2", "R", "T"):
        np.testing.assert_allclose(getattr(back, name), getattr(true, name), rtol=1e-9,
                                   atol=0, err_msg=name)
    assert back.model == true.model and back.image_size == true.image_size
    a, b = back.rectify_maps(), true.rectify_maps()
    for name in ("left_x", "left_y", "right_x", "right_y"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_the_written_numbers_are_floats_for_every_yaml_reader(tmp_path, rig):
    """PyYAML (Kalibr's reader) takes 1e-05 for a string; the writer puts 1.0e-05."""
    true = rig.true_calibration()
    D1 = true.D1.copy()
    D1[0, 3] = 1e-05
    text = kalibr_camchain_text(true.with_updates(D1=D1))
    assert "1.0e-05" in text
    assert yaml.safe_load(text)["cam0"]["distortion_coeffs"][3] == 1e-05


def test_the_default_rigs_k3_is_refused_and_nothing_is_written(tmp_path):
    target = tmp_path / "camchain.yaml"
    with pytest.raises(CalibrationFileError, match=r"D1 .*k3 = -0\.012"):
        write_kalibr_camchain(target, SimRig(seed=0).true_calibration())
    assert not target.exists()


def test_a_rational_model_goes_as_radtan_only_without_its_higher_terms(tmp_path, rig):
    true = rig.true_calibration()
    D1 = np.hstack([true.D1, np.zeros((1, 3))])
    D2 = np.hstack([true.D2, np.zeros((1, 3))])
    rational = true.with_updates(D1=D1, D2=D2, model="rational")
    back = read_kalibr_camchain(write_kalibr_camchain(tmp_path / "c.yaml", rational))
    np.testing.assert_array_equal(back.calibration.D1, true.D1)
    D2[0, 6] = 0.3  # k5
    with pytest.raises(CalibrationFileError, match=r"D2 .*rational model's k5 = 0\.3"):
        kalibr_camchain_text(rational.with_updates(D2=D2))


def test_a_hartley_calibration_is_refused(rig):
    with pytest.raises(CalibrationFileError, match="Hartley.*metres"):
        kalibr_camchain_text(rig.true_calibration().with_updates(method="hartley"))


def test_a_skewed_camera_is_refused(rig):
    true = rig.true_calibration()
    M2 = true.M2.copy()
    M2[0, 1] = 0.5
    with pytest.raises(CalibrationFileError, match="M2 has a skew"):
        kalibr_camchain_text(true.with_updates(M2=M2))


@pytest.mark.parametrize("step", ["open", "write", "short", "fsync", "close", "replace"])
def test_a_failing_disk_keeps_the_old_camchain(tmp_path, monkeypatch, rig, step):
    from disk_faults import install

    target = tmp_path / "camchain.yaml"
    target.write_bytes(b"the good old camchain")
    disk = install(monkeypatch, step)
    with pytest.raises(InputError, match="cannot write"):
        write_kalibr_camchain(target, rig.true_calibration())
    assert disk.failed
    assert target.read_bytes() == b"the good old camchain"
    assert [p.name for p in tmp_path.iterdir()] == ["camchain.yaml"]


def test_a_camchain_that_does_not_read_back_is_not_kept(tmp_path, monkeypatch, rig):
    from stereo_gui.files import kalibr_calibration as kc

    target = tmp_path / "camchain.yaml"
    real = kc.kalibr_camchain_text
    monkeypatch.setattr(kc, "kalibr_camchain_text",
                        lambda c: real(c).replace("752.0", "751.0", 1))
    with pytest.raises(InputError, match="does not read back.*M1"):
        kc.write_kalibr_camchain(target, rig.true_calibration())
    assert not target.exists()


# ---- files written by hand in the formats' layouts -----------------------------------------
def test_a_hand_written_camchain_loads(rig, loaded):
    got = loaded["kalibr"]
    assert got.kind == "kalibr"
    assert got.description.startswith("Kalibr camchain camchain.yaml (pinhole-radtan")
    _assert_truth(got.calibration, rig.truth)
    assert got.calibration.baseline_mm == pytest.approx(110.0)


def test_a_hand_written_euroc_pair_loads_from_either_file(tmp_path, rig, loaded):
    got = loaded["euroc"]
    cam0, cam1 = got.files
    assert got.kind == "euroc" and cam0.parent.name == "cam0" and cam1.parent.name == "cam1"
    assert "EuRoC cam0/sensor.yaml + cam1/sensor.yaml (pinhole-radial-tangential" in \
        got.description
    _assert_truth(got.calibration, rig.truth)
    again = load_any_calibration(cam1)
    assert again.files == got.files and again.path == cam1
    np.testing.assert_array_equal(again.calibration.P2, got.calibration.P2)


def test_euroc_files_with_opencvs_yaml_directive_load(tmp_path, rig):
    cam0, cam1 = write_euroc(tmp_path, rig.truth)
    for p in (cam0, cam1):
        p.write_text("%YAML:1.0\n" + p.read_text())
    _assert_truth(read_euroc_pair(cam0).calibration, rig.truth)


def test_numbers_without_a_dot_load(tmp_path, rig):
    """A hand-written 1e-05 is a string to PyYAML; it is read as the number it means."""
    text = camchain_text(rig.truth).replace("0.0011,", "1.1e-3,", 1)
    assert "1.1e-3" in text
    (tmp_path / "c.yaml").write_text(text)
    assert read_kalibr_camchain(tmp_path / "c.yaml").calibration.D1[0, 2] == 1.1e-3


# ---- the loaded calibrations at work ---------------------------------------------------------
def _vertical_px(calib, pairs, board) -> np.ndarray:
    """|y_left - y_right| of the board's corners found in the rectified pictures, px."""
    maps = calib.rectify_maps()
    out = []
    for i, (left, right) in enumerate(pairs):
        rl = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
        rr = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
        det = detect_pair(str(i), rl, rr, board)
        if det.found:
            _, a, b = det.common()
            out.append(np.abs(a[:, 1] - b[:, 1]))
    assert len(out) >= 4, "the board was found in too few rectified pairs"
    return np.concatenate(out)


@pytest.mark.parametrize("kind", ["kalibr", "euroc"])
def test_rectified_board_pictures_have_no_vertical_error(rig, loaded, kind):
    dy = _vertical_px(loaded[kind].calibration, rig.calibration_set(6), rig.truth.board)
    assert float(np.mean(dy)) < VERTICAL_PX, f"mean {np.mean(dy):.3f} px, max {dy.max():.3f}"


def test_rectified_fisheye_board_pictures_have_no_vertical_error(tmp_path, fisheye_rig):
    path = write_kalibr_camchain(tmp_path / "camchain.yaml", fisheye_rig.true_calibration())
    calib = load_any_calibration(path).calibration
    dy = _vertical_px(calib, fisheye_rig.calibration_set(6), fisheye_rig.truth.board)
    assert float(np.mean(dy)) < VERTICAL_PX, f"mean {np.mean(dy):.3f} px, max {dy.max():.3f}"


@pytest.fixture(scope="module")
def wall(rig):
    scene = Scene.wall(WALL_MM)
    return scene, rig.render_scene(scene, np.random.default_rng(0))


@pytest.mark.parametrize("kind", ["kalibr", "euroc"])
def test_a_wall_reads_its_true_distance_within_the_stated_error(rig, loaded, wall, kind):
    calib = loaded[kind].calibration
    scene, (left, right) = wall
    result = StereoPipeline(calib, load_preset("quality")).process(left, right)
    for x, y in POINTS:
        m = measure_point(result, x, y)
        assert m.valid, (x, y, m.reason)
        true_z = rig.true_point_rectified(calib, scene, x, y)[2]
        assert abs(m.Z_mm - true_z) <= m.expected_error_mm, (x, y, m.Z_mm, true_z,
                                                             m.expected_error_mm)


# ---- bad files -------------------------------------------------------------------------------
def _drop_lines(text: str, start: str, count: int) -> str:
    lines = text.splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.startswith(start))
    return "".join(lines[:i] + lines[i + count:])


def _edit_cam1(text: str, old: str, new: str) -> str:
    head, tail = text.split("cam1:\n")
    assert old in tail, old
    return head + "cam1:\n" + tail.replace(old, new, 1)


def _translation(text: str, metres) -> str:
    """`text` with cam1's T_cn_cnm1 translation set to `metres`."""
    head, tail = text.split("cam1:\n")
    rows = tail.splitlines(keepends=True)  # T_cn_cnm1:, then its rows
    for i, t in zip((1, 2, 3), metres):
        rows[i] = re.sub(r", [^,]+\]\n$", f", {t!r}]\n", rows[i])
    return head + "cam1:\n" + "".join(rows)


KALIBR_CASES = {
    "omni": (lambda t: t.replace("camera_model: pinhole", "camera_model: omni", 1),
             "cam0: camera_model 'omni' is not supported"),
    "ds": (lambda t: _edit_cam1(t, "camera_model: pinhole", "camera_model: ds"),
           "cam1: camera_model 'ds' is not supported"),
    "one camera": (lambda t: t.split("cam1:")[0], "holds one camera (cam0)"),
    "no cam0": (lambda t: t.replace("cam0:", "camA:", 1), "cam0 is missing"),
    "no T_cn_cnm1": (lambda t: _drop_lines(t, "  T_cn_cnm1:", 5), "cam1 has no T_cn_cnm1"),
    "T 3 rows": (lambda t: _edit_cam1(t, "  - [0.0, 0.0, 0.0, 1.0]\n", ""),
                 "cam1: T_cn_cnm1 should be a 4x4 matrix"),
    "T 3 columns": (lambda t: _edit_cam1(t, "  - [0.0, 0.0, 0.0, 1.0]", "  - [0.0, 0.0, 1.0]"),
                    "T_cn_cnm1 should hold 4 numbers, found 3"),
    "T last row": (lambda t: _edit_cam1(t, "  - [0.0, 0.0, 0.0, 1.0]", "  - [0.0, 0.0, 0.0, 2.0]"),
                   "T_cn_cnm1's last row should be 0 0 0 1"),
    "T far away": (lambda t: _translation(t, (5000.0, 0.0, 0.0)),
                   "T_cn_cnm1 has a translation of 5e+03 m"),
    "T no rotation": (lambda t: _edit_cam1(t, "  - [0.99", "  - [1.99"),
                      "T_cn_cnm1's upper-left 3x3 block is not a rotation"),
    "no intrinsics": (lambda t: _drop_lines(t, "  intrinsics:", 1), "cam0: intrinsics is missing"),
    "3 intrinsics": (lambda t: t.replace("intrinsics: [752.0, ", "intrinsics: [", 1),
                     "cam0: intrinsics should hold 4 numbers, found 3"),
    "text intrinsics": (lambda t: t.replace("intrinsics: [752.0", "intrinsics: [abc", 1),
                        "intrinsics should be a list of finite numbers"),
    "nan intrinsics": (lambda t: t.replace("intrinsics: [752.0", "intrinsics: [.nan", 1),
                       "intrinsics should be a list of finite numbers"),
    "negative focal": (lambda t: t.replace("intrinsics: [752.0", "intrinsics: [-752.0", 1),
                       "cam0: intrinsics have no positive focal length"),
    "fov": (lambda t: t.replace("distortion_model: radtan", "distortion_model: fov", 1),
            "cam0: distortion_model 'fov' is not supported"),
    "5 coefficients": (lambda t: t.replace("distortion_coeffs: [", "distortion_coeffs: [0.0, ", 1),
                       "distortion_coeffs should hold 4 numbers, found 5"),
    "no coefficients": (lambda t: _drop_lines(t, "  distortion_coeffs:", 1),
                        "cam0: distortion_coeffs is missing"),
    "mixed lenses": (lambda t: _edit_cam1(t, "radtan", "equidistant"),
                     "cam0 is radtan but cam1 is equidistant"),
    "sizes differ": (lambda t: _edit_cam1(t, "resolution: [640, 480]", "resolution: [320, 240]"),
                     "cam0 is 640x480 but cam1 is 320x240"),
    "no resolution": (lambda t: _drop_lines(t, "  resolution:", 1), "resolution is missing"),
    "odd resolution": (lambda t: t.replace("resolution: [640, 480]", "resolution: [640.5, 480]", 1),
                       "resolution should be two positive whole numbers"),
    "no baseline": (lambda t: _translation(t, (0.0, 0.0, 0.0)),
                    "translation from cam0 to cam1 is zero"),
    "centre outside": (lambda t: t.replace("323.6, 237.2]", "923.6, 237.2]", 1),
                       "outside the 640x480 image"),
    "not yaml": (lambda t: t.replace("cam1:\n", "cam1: [\n", 1), "is not readable YAML"),
    "not a mapping": (lambda t: t.split("cam1:")[0] + "cam1: 7\n",
                      "cam1 is not a mapping of camera fields"),
}


@pytest.mark.parametrize("case", list(KALIBR_CASES))
def test_a_bad_camchain_says_what_is_wrong(tmp_path, rig, case):
    edit, message = KALIBR_CASES[case]
    good = camchain_text(rig.truth)
    bad = edit(good)
    assert bad != good
    path = tmp_path / "camchain.yaml"
    path.write_text(bad)
    with pytest.raises(CalibrationFileError) as info:
        load_any_calibration(path)
    assert str(path) in str(info.value) and message in str(info.value), str(info.value)


def _euroc_edit(cam: int, old: str, new: str):
    def edit(paths):
        text = paths[cam].read_text()
        assert old in text, old
        paths[cam].write_text(text.replace(old, new, 1))
    return edit


def _remove(cam: int):
    return lambda paths: paths[cam].unlink()


def _move_out(paths):
    for p in paths:
        p.rename(p.parent.parent / f"{p.parent.name}.yaml")


EUROC_CASES = {
    "no cam1": (0, _remove(1), "the other camera's file"),
    "no cam0": (1, _remove(0), "cam0/sensor.yaml was not found"),
    "no camera folder": (None, _move_out, "outside a cam0 or cam1 folder"),
    "17 numbers": (0, _euroc_edit(1, "  data: [", "  data: [0.0, "),
                   "T_BS: data should hold 16 numbers, found 17"),
    "3 rows": (0, _euroc_edit(0, "rows: 4", "rows: 3"), "T_BS should have rows: 4 and cols: 4"),
    "no T_BS": (0, lambda p: p[0].write_text(_drop_lines(p[0].read_text(), "T_BS:", 7)),
                "T_BS is missing"),
    "imu": (0, _euroc_edit(0, "sensor_type: camera", "sensor_type: imu"),
            "describes a sensor of type 'imu', not a camera"),
    "omni": (0, _euroc_edit(1, "camera_model: pinhole", "camera_model: omni"),
             "camera_model 'omni' is not supported"),
    "no coefficients": (0, _euroc_edit(1, "distortion_coefficients:", "#"),
                        "distortion_coefficients is missing"),
    "plumb_bob": (0, _euroc_edit(0, "radial-tangential", "plumb_bob"),
                  "distortion_model 'plumb_bob' is not supported"),
}


@pytest.mark.parametrize("case", list(EUROC_CASES))
def test_a_bad_euroc_pair_says_what_is_wrong(tmp_path, rig, case):
    given, edit, message = EUROC_CASES[case]
    paths = write_euroc(tmp_path, rig.truth)
    edit(paths)
    path = paths[given] if given is not None else tmp_path / "mav0" / "cam0.yaml"
    with pytest.raises(CalibrationFileError) as info:
        load_any_calibration(path)
    text = str(info.value)
    assert str(path) in text or str(paths[0]) in text or str(paths[1]) in text, text
    assert message in text, text


def test_without_pyyaml_the_message_says_what_to_install(tmp_path, rig, monkeypatch):
    path = tmp_path / "camchain.yaml"
    path.write_text(camchain_text(rig.truth))
    monkeypatch.setitem(sys.modules, "yaml", None)
    with pytest.raises(CalibrationFileError, match="needs PyYAML"):
        load_any_calibration(path)


# ---- damaged files ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["kalibr", "euroc"])
def test_damaged_files_give_a_clean_error_or_a_valid_calibration(tmp_path, rig, kind):
    from mutations import damaged_bytes

    if kind == "kalibr":
        path = tmp_path / "camchain.yaml"
        path.write_text(camchain_text(rig.truth))
    else:
        path = write_euroc(tmp_path, rig.truth)[1]
    valid = path.read_bytes()
    loaded: list[bool] = []

    @settings(max_examples=100, derandomize=True, database=None, deadline=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(data=damaged_bytes(valid))
    def refused_or_valid(data: bytes) -> None:
        path.write_bytes(data)
        try:
            load_any_calibration(path, (640, 480))
        except StereoGuiError:
            loaded.append(False)
            return
        loaded.append(True)

    refused_or_valid()
    assert not all(loaded)
