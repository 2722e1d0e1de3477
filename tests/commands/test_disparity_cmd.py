"""`stereo-gui disparity`: colour view and exports of a pair; identity calibrations; bad input."""

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.calibration_file import save_calibration
from stereo_gui.files.presets import load_preset

W, H, SHIFT = 200, 120, 10


@pytest.fixture(scope="module")
def rectified_pair(tmp_path_factory):
    """An already rectified pair (a benchmark's, say) with an identity calibration file."""
    d = tmp_path_factory.mktemp("disparity")
    rng = np.random.default_rng(8)
    big = cv2.GaussianBlur(rng.random((H, W + SHIFT)).astype(np.float32), (0, 0), 1.0)
    big = cv2.normalize(big, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    left = cv2.cvtColor(big[:, :W], cv2.COLOR_GRAY2BGR)
    right = cv2.cvtColor(big[:, SHIFT:SHIFT + W], cv2.COLOR_GRAY2BGR)
    cv2.imwrite(str(d / "l.png"), left)
    cv2.imwrite(str(d / "r.png"), right)
    calib = StereoCalibration.identity((W, H), 300.0, 100.0)
    save_calibration(calib, d / "id.yaml")
    return d, calib, left, right


def test_all_outputs_match_the_pipeline(rectified_pair, tmp_path, capsys):
    d, calib, left, right = rectified_pair
    out = tmp_path
    args = ["disparity", "--calib", str(d / "id.yaml"), str(d / "l.png"), str(d / "r.png"),
            "-o", str(out / "view.png"), "--npy", str(out / "d.npy"), "--png16", str(out / "d16.png"),
            "--depth-png", str(out / "z.png"), "--ply", str(out / "c.ply"), "--preset", "seed"]
    assert main(args) == 0
    assert "wrote" in capsys.readouterr().out
    expected = StereoPipeline(calib, load_preset("seed")).process(left, right)
    np.testing.assert_array_equal(np.load(out / "d.npy"), expected.final_px)
    np.testing.assert_array_equal(cv2.imread(str(out / "view.png")), expected.color_bgr)
    d16 = cv2.imread(str(out / "d16.png"), cv2.IMREAD_UNCHANGED)
    ok = expected.valid
    np.testing.assert_allclose(d16[ok] / 16.0, expected.final_px[ok], atol=1 / 32 + 1e-6)
    z = cv2.imread(str(out / "z.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_allclose(z[ok], 300.0 * 100.0 / expected.final_px[ok], atol=0.5 + 1e-3)
    data = (out / "c.ply").read_bytes()
    header = data[:data.index(b"end_header\n")].decode()
    n = int(header.split("element vertex ")[1].split()[0])
    assert n == int(ok.sum())
    # the interior of the plane is at its constant disparity
    assert np.nanmedian(expected.final_px[20:-20, 150:-20]) == pytest.approx(SHIFT, abs=0.25)


def test_bad_input(rectified_pair, tmp_path, capsys):
    d = rectified_pair[0]
    base = ["disparity", "--calib", str(d / "id.yaml"), str(d / "l.png"), str(d / "r.png")]
    assert main(base + ["-o", str(tmp_path / "view.txt")]) == 2
    assert "image suffix" in capsys.readouterr().err
    assert main(base + ["-o", str(tmp_path / "no" / "view.png")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["disparity", "--calib", str(tmp_path / "none.yaml"), str(d / "l.png"),
                 str(d / "r.png"), "-o", str(tmp_path / "v.png")]) == 2
    err = capsys.readouterr().err
    assert "none.yaml" in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_an_already_rectified_pair_needs_no_calibration_file(rectified_pair, tmp_path, capsys):
    """--calib rectified:F,B is the identity calibration at the size of LEFT."""
    d, calib, left, right = rectified_pair
    assert main(["disparity", "--calib", "rectified:300,100", str(d / "l.png"), str(d / "r.png"),
                 "-o", str(tmp_path / "v.png"), "--npy", str(tmp_path / "d.npy")]) == 0
    expected = StereoPipeline(calib, load_preset("live")).process(left, right)
    np.testing.assert_array_equal(np.load(tmp_path / "d.npy"), expected.final_px)
    capsys.readouterr()
    for bad in ("rectified:300", "rectified:-3,100", "rectified:f,b"):
        assert main(["disparity", "--calib", bad, str(d / "l.png"), str(d / "r.png"),
                     "-o", str(tmp_path / "w.png")]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
