"""Calibration files: exact FileStorage round trip, precise load errors, scaling (ROS
camera_info: test_ros_camera_info.py)."""

from __future__ import annotations

import math
import re

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationError, CalibrationFileError
from stereo_gui.core.stereo_calibration import MATRIX_NAMES, StereoCalibration, q_from_projections
from stereo_gui.files.calibration_file import (
    load_calibration,
    load_calibration_for_size,
    save_calibration,
)
from stereo_gui.files.ros_camera_info import export_ros, import_ros

from factories import make_calibration


def test_round_trip_is_exact(tmp_path):
    c = make_calibration()
    path = save_calibration(c, tmp_path / "calib.yaml")
    back = load_calibration(path)
    for name in MATRIX_NAMES:
        a, b = getattr(c, name), getattr(back, name)
        assert a.shape == b.shape and np.array_equal(a, b), name
    assert np.array_equal(back.optimal_M1, c.optimal_M1) and back.optimal_M2 is None
    assert back.image_size == c.image_size and back.board == c.board
    for f in ("rms_left", "rms_right", "rms_stereo", "epipolar_error_px", "alpha"):
        assert getattr(back, f) == getattr(c, f), f
    assert back.per_pair == c.per_pair
    assert back.method == c.method and back.created == c.created
    assert back.scaled_from is None


def test_nan_figures_round_trip(tmp_path):
    c = make_calibration().with_updates(rms_stereo=float("nan"), method="hartley", per_pair=())
    back = load_calibration(save_calibration(c, tmp_path / "h.yaml"))
    assert math.isnan(back.rms_stereo) and back.method == "hartley" and back.per_pair == ()


def test_file_opens_with_cv2_filestorage(tmp_path):
    c = make_calibration()
    path = save_calibration(c, tmp_path / "calib.yaml")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    assert fs.getNode("format_version").real() == 1
    for name in MATRIX_NAMES:
        assert np.array_equal(fs.getNode(name).mat(), getattr(c, name)), name
    assert int(fs.getNode("image_width").real()) == 640
    assert int(fs.getNode("image_height").real()) == 480
    assert int(fs.getNode("board_cols").real()) == 9 and int(fs.getNode("board_rows").real()) == 6
    assert fs.getNode("square_mm").real() == 24.5
    assert fs.getNode("method").string() == "bouguet"
    assert fs.getNode("created").string() == c.created
    pp = fs.getNode("per_pair")
    assert pp.isSeq() and pp.size() == 2
    assert pp.at(1).getNode("name").string() == "07"
    assert pp.at(1).getNode("error_right").real() == 2 / 7
    fs.release()


def test_save_is_atomic_and_leaves_no_temporary_files(tmp_path, monkeypatch):
    target = tmp_path / "calib.yaml"
    save_calibration(make_calibration(), target)
    before = target.read_bytes()
    good = make_calibration()
    broken = good.with_updates(E=good.E.T)  # no longer follows from R and T: refused
    with pytest.raises(CalibrationFileError, match="matrix E does not follow"):
        save_calibration(broken, target)
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calib.yaml"]


def _rewrite(tmp_path, **changes):
    """Save a calibration, then rewrite some keys in a FileStorage copy of it."""
    src = save_calibration(make_calibration(), tmp_path / "src.yaml")
    fs = cv2.FileStorage(str(src), cv2.FILE_STORAGE_READ)
    out = tmp_path / "bad.yaml"
    ws = cv2.FileStorage(str(out), cv2.FILE_STORAGE_WRITE)
    for key in fs.root().keys():
        if key in changes:
            if changes[key] is not None:
                ws.write(key, changes[key])
            continue
        node = fs.getNode(key)
        if node.isInt():
            ws.write(key, int(node.real()))
        elif node.isReal():
            ws.write(key, node.real())
        elif node.isString():
            ws.write(key, node.string())
        elif node.isMap():
            ws.write(key, node.mat())
    ws.release()
    fs.release()
    return out


@pytest.mark.parametrize("changes, message", [
    ({"P1": np.eye(3)}, "matrix P1 should be 3x4, found 3x3"),
    ({"Q": None}, "matrix Q is missing"),
    ({"M2": np.array([[np.nan, 0, 1], [0, 1, 1], [0, 0, 1]])}, "matrix M2 holds values that are not finite"),
    ({"D1": np.zeros((1, 3))}, "distortion D1 should have 4, 5, 8, 12 or 14 coefficients, found 3"),
    ({"format_version": 2}, "unsupported format_version 2"),
    ({"format_version": None}, "format_version is missing"),
    ({"image_width": None}, "image_width is missing"),
])
def test_load_says_exactly_what_is_wrong(tmp_path, changes, message):
    bad = _rewrite(tmp_path, **changes)
    with pytest.raises(CalibrationFileError, match=message):
        load_calibration(bad)


def test_missing_and_foreign_files(tmp_path):
    with pytest.raises(CalibrationFileError, match="does not exist"):
        load_calibration(tmp_path / "nope.yaml")
    junk = tmp_path / "junk.yaml"
    junk.write_text("hello: [1, \n")
    with pytest.raises(CalibrationFileError, match="not an OpenCV FileStorage file"):
        load_calibration(junk)
    binary = tmp_path / "image.yaml"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(CalibrationFileError):
        load_calibration(binary)


def test_q_from_projections_matches_opencv():
    c = make_calibration()
    assert np.allclose(q_from_projections(c.P1, c.P2), c.Q, atol=1e-12)
    c1 = make_calibration(alpha=1.0)
    assert np.allclose(q_from_projections(c1.P1, c1.P2), c1.Q, atol=1e-12)


def _project(M, D, X):
    p, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), M, D)
    return p.reshape(-1, 2)


def test_scaling_to_the_same_aspect_ratio():
    c = make_calibration()
    s = c.scaled_to((1280, 960))
    assert s.image_size == (1280, 960) and s.scaled_from == (640, 480)
    X = np.array([[100.0, -50.0, 900.0], [-300.0, 200.0, 1500.0], [0.0, 0.0, 700.0]])
    for M, D, Ms in ((c.M1, c.D1, s.M1), (c.M2, c.D2, s.M2)):
        # a pixel at c in the small image is at (c + 0.5) * 2 - 0.5 in the large one
        assert np.allclose(_project(Ms, D, X), (_project(M, D, X) + 0.5) * 2 - 0.5, atol=1e-9)
    # rectified projections and Q agree: a point's disparity triangulates back to it
    Xl = (c.R1 @ X.T).T  # the point in the left rectified frame
    for cal in (c, s):
        xl = (cal.P1 @ np.c_[Xl, np.ones(3)].T)
        xr = (cal.P2 @ np.c_[Xl, np.ones(3)].T)
        xl, xr = xl[:2] / xl[2], xr[:2] / xr[2]
        d = xl[0] - xr[0]
        h = cal.Q @ np.vstack([xl, d, np.ones(3)])
        assert np.allclose((h[:3] / h[3]).T, Xl, atol=1e-6)
    # unchanged parts, and a round trip back to the original size
    for name in ("R", "T", "E", "R1", "R2", "D1", "D2"):
        assert np.array_equal(getattr(s, name), getattr(c, name))
    back = s.scaled_to((640, 480))
    assert back.scaled_from is None
    for name in ("M1", "M2", "P1", "P2", "Q", "optimal_M1"):
        assert np.allclose(getattr(back, name), getattr(c, name), atol=1e-9), name
    # the fundamental matrix still relates corresponding scaled pixels
    x1 = _project(s.M1, s.D1 * 0, X)
    x2 = _project(s.M2, s.D2 * 0, (c.R @ X.T + c.T).T)
    r = [np.r_[b, 1] @ s.F @ np.r_[a, 1] for a, b in zip(x1, x2)]
    assert np.allclose(r, 0, atol=1e-6)
    assert c.scaled_to((640, 480)) is c


def test_scaling_to_another_aspect_ratio_is_refused(tmp_path):
    c = make_calibration()
    with pytest.raises(CalibrationError, match=r"made at 640x480 and cannot be used at 1280x720: "
                                               r"the aspect ratios differ"):
        c.scaled_to((1280, 720))
    path = save_calibration(c.scaled_to((320, 240)), tmp_path / "small.yaml")
    loaded = load_calibration(path)
    assert loaded.scaled_from == (640, 480) and loaded.image_size == (320, 240)
    big = load_calibration_for_size(path, (1280, 960))
    assert big.scaled_from == (640, 480)
    assert np.allclose(big.M1, c.scaled_to((1280, 960)).M1)


def test_unparsable_file_names_the_parse_error_not_the_binding(tmp_path):
    """OpenCV's Python binding wraps the parse error in a SystemError that only names the
    binding; the message must carry the parser's line and reason instead."""
    junk = tmp_path / "junk.yaml"
    junk.write_text("M1: [1, 2\n  foo: {")
    with pytest.raises(CalibrationFileError) as caught:
        load_calibration(junk)
    message = str(caught.value)
    assert "exception set" not in message and "cv2.FileStorage" not in message
    assert re.search(r"\(line \d+: \w", message), message


def test_the_pairs_left_out_are_kept_in_the_file(tmp_path):
    """A calibration records the pairs it was not made from (rejected, or excluded by the
    technician) and reads them back; an entry that cannot be read is skipped."""
    c = StereoCalibration.identity((640, 480), 700.0, 110.0).with_updates(
        left_out=(("chessboard-4", "excluded by you"),
                  ("chessboard-9", "chessboard not found in the right image")))
    path = tmp_path / "c.yaml"
    save_calibration(c, path)
    assert load_calibration(path).left_out == c.left_out
    text = path.read_text().replace("name: chessboard-9", "name: 9")
    path.write_text(text)
    assert load_calibration(path).left_out == (("chessboard-4", "excluded by you"),)


def test_lens_shading_round_trips_and_a_damaged_one_is_dropped_with_a_warning(tmp_path, caplog):
    from stereo_gui.core.shading import LensShading, PairShading

    shading = PairShading(LensShading(-0.3371234567891, -0.0193), LensShading(-0.318, 0.0041, 12.5),
                          samples=800, images=40)
    c = make_calibration().with_updates(lens_shading=shading)
    path = save_calibration(c, tmp_path / "calib.yaml")
    assert load_calibration(path).lens_shading == shading
    assert load_calibration(save_calibration(make_calibration(), tmp_path / "plain.yaml")
                            ).lens_shading is None  # older files have none
    text = path.read_text()
    for bad in ("-8.0", ".Nan"):  # corners 800 % darker; not a number (and a black level below)
        damaged = tmp_path / "damaged.yaml"
        damaged.write_text(re.sub(r"k1: [-0-9.e]+", f"k1: {bad}", text, count=1))
        caplog.clear()
        back = load_calibration(damaged)
        assert back.lens_shading is None and back.M1 is not None
        assert "lens shading of this calibration is not used" in caplog.text
    damaged.write_text(text.replace("black: 12.5", "black: 300."))
    caplog.clear()
    assert load_calibration(damaged).lens_shading is None
    assert "black should be from" in caplog.text


def test_a_value_the_calibration_refuses_is_said_with_the_files_name_in_front(tmp_path):
    """The type says what is wrong (a focal length that is not positive, an R that is not a
    rotation); the loader says in which file."""
    M1 = make_calibration().M1.copy()
    M1[0, 0] = -750.0
    bad = _rewrite(tmp_path, M1=M1)
    with pytest.raises(CalibrationFileError) as caught:
        load_calibration(bad)
    assert str(caught.value).startswith(f"{bad}: matrix M1 has focal lengths -750, 748.5 px")
    lp, rp = export_ros(make_calibration(), tmp_path)
    lp.write_text(lp.read_text().replace("data: [752.123456789,", "data: [0.0,", 1))
    with pytest.raises(CalibrationFileError) as caught:
        import_ros(lp, rp)
    assert str(caught.value).startswith(f"{lp}: matrix camera_matrix has focal lengths 0, 748.5")
