"""Depth exports read back with their readers: cv2 (16-bit PNG), numpy (.npy), a PLY parser."""

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import MatcherParams
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files import depth_export

W, H, SHIFT, F, B = 200, 120, 10, 300.0, 100.0


@pytest.fixture(scope="module")
def result():
    rng = np.random.default_rng(4)
    big = cv2.GaussianBlur(rng.random((H, W + SHIFT)).astype(np.float32), (0, 0), 1.0)
    big = cv2.normalize(big, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    left = cv2.cvtColor(big[:, :W], cv2.COLOR_GRAY2BGR)
    right = cv2.cvtColor(big[:, SHIFT:SHIFT + W], cv2.COLOR_GRAY2BGR)
    left[..., 2] = 200  # a colour, so that channel order is checked
    calib = StereoCalibration.identity((W, H), F, B)
    r = StereoPipeline(calib, MatcherParams(min_disparity=0, num_disparities=32, block_size=5)
                       ).process(left, right)
    assert r.valid.any() and not r.valid.all()
    return calib, r


def read_ply(path):
    """A small binary PLY reader: header lines, then the vertex records."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[0] == "ply" and header[1] == "format binary_little_endian 1.0"
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    types = {"float": "<f4", "uchar": "u1"}
    fields = [(line.split()[2], types[line.split()[1]]) for line in header
              if line.startswith("property")]
    vertices = np.frombuffer(data[end:], dtype=fields)
    assert vertices.size == count
    return vertices


def test_disparity_png16_is_x16_fixed_point(tmp_path, result):
    _, r = result
    path = depth_export.write_disparity_png16(tmp_path / "d.png", r.final_px)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert back.dtype == np.uint16 and back.shape == (H, W)
    ok = r.valid & (r.final_px > 0)
    np.testing.assert_allclose(back[ok] / 16.0, r.final_px[ok], atol=1 / 32 + 1e-6)
    assert (back[~r.valid] == 0).all()


def test_disparity_npy_is_float32_with_nan(tmp_path, result):
    _, r = result
    path = depth_export.write_disparity_npy(tmp_path / "d.npy", r.final_px)
    back = np.load(path)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, r.final_px)  # NaN positions included


def test_depth_png16_is_millimetres(tmp_path, result):
    calib, r = result
    path = depth_export.write_depth_png16(tmp_path / "z.png", r.final_px, calib)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert back.dtype == np.uint16
    ok = r.valid & (r.final_px > 0)
    expected = F * B / r.final_px[ok]
    fits = expected <= 65535
    np.testing.assert_allclose(back[ok][fits], expected[fits], atol=0.5 + 1e-3)
    assert (back[~r.valid] == 0).all()


def test_ply_holds_the_valid_points_with_colours(tmp_path, result):
    calib, r = result
    n = depth_export.write_ply(tmp_path / "c.ply", r.final_px, r.rectified_left, calib)
    v = read_ply(tmp_path / "c.ply")
    ok = r.valid & (r.final_px > 0)
    assert n == v.size == int(ok.sum())
    ys, xs = np.nonzero(ok)
    d = r.final_px[ok]
    z = F * B / d
    np.testing.assert_allclose(v["z"], z, rtol=1e-5)
    np.testing.assert_allclose(v["x"], (xs - (W - 1) / 2.0) * z / F, rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(v["y"], (ys - (H - 1) / 2.0) * z / F, rtol=1e-4, atol=1e-3)
    assert (v["red"] == 200).all()
    np.testing.assert_array_equal(v["blue"], r.rectified_left[ok][:, 0])


def test_errors_and_atomic_writes(tmp_path, result, monkeypatch):
    calib, r = result
    with pytest.raises(InputError, match="png"):
        depth_export.write_disparity_png16(tmp_path / "d.jpg", r.final_px)
    with pytest.raises(InputError, match="calibration"):
        depth_export.write_depth_png16(tmp_path / "z.png", r.final_px[:, :-1], calib)
    target = tmp_path / "keep.npy"
    target.write_bytes(b"old")

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    from stereo_gui.files import atomic

    monkeypatch.setattr(atomic.syscalls, "write", boom)
    with pytest.raises(InputError, match="(?i)no space"):
        depth_export.write_disparity_npy(target, r.final_px)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.npy"]


def test_depth_and_clouds_refuse_a_calibration_without_metric_scale(tmp_path, result):
    calib, r = result
    hartley = calib.with_updates(method="hartley")
    with pytest.raises(InputError, match="no metric scale"):
        depth_export.write_depth_png16(tmp_path / "d.png", r.final_px, hartley)
    with pytest.raises(InputError, match="no metric scale"):
        depth_export.write_ply(tmp_path / "c.ply", r.final_px, r.rectified_left, hartley)
    assert not (tmp_path / "d.png").exists() and not (tmp_path / "c.ply").exists()
    # the disparity itself has no unit problem
    depth_export.write_disparity_png16(tmp_path / "x16.png", r.final_px)
