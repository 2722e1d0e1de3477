"""`stereo-gui measure` on files written from the simulated rig; bad input exits 2 in one line."""

import json

import cv2
import pytest

from stereo_gui.cli import main
from stereo_gui.files.calibration_file import save_calibration

WALL_MM = 1500.0  # the wall of the `wall_files` fixture (tests/commands/conftest.py)


@pytest.fixture(scope="module")
def pair(wall_files):
    """calibration file, raw left and right images of a wall, the rig, the scene, the calibration."""
    d, rig, scene, calib = wall_files
    save_calibration(calib, d / "calib.yaml")
    return d, rig, scene, calib


def _args(d, *extra):
    return ["measure", "--calib", str(d / "calib.yaml"), str(d / "left.png"), str(d / "right.png"),
            *extra]


def test_measure_json(pair, capsys):
    d, rig, scene, calib = pair
    assert main(_args(d, "--at", "320,240", "--at", "400.5,300", "--json")) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["points"]) == 2
    keys = {"x", "y", "valid", "reason", "disparity_px", "X_mm", "Y_mm", "Z_mm", "range_mm",
            "valid_fraction", "expected_error_mm"}
    for p in doc["points"]:
        assert set(p) == keys
        assert p["valid"] and p["reason"] is None
        true = rig.true_point_rectified(calib, scene, p["x"], p["y"])
        assert p["Z_mm"] == pytest.approx(true[2], rel=0.01)
    assert doc["points"][1]["x"] == 400.5


def test_measure_text_with_preset_patch_mode_and_model(pair, capsys, tmp_path):
    from stereo_gui.core.regression import fit_inverse
    from stereo_gui.files.fit_file import save_fit

    d, rig, scene, calib = pair
    fb = calib.focal_px * calib.rectified_baseline_mm
    fit = save_fit(fit_inverse([(dd, fb / dd) for dd in (20.0, 40.0, 60.0, 80.0)]),
                   tmp_path / "fit.json")
    assert main(_args(d, "--at", "320,240", "--preset", "seed", "--patch", "5",
                      "--mode", "object", "--model", str(fit))) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("320,240: Z = ") and out.endswith("inverse")
    z = float(out.split("Z = ")[1].split()[0])
    assert z == pytest.approx(WALL_MM, rel=0.02)


@pytest.mark.parametrize("case,message", [
    ("unreadable", "cannot be read"),
    ("missing", "does not exist"),
    ("size", "calibration is for 640x480"),
    ("outside", "outside the 640x480 image"),
    ("corrupt", "c.yaml"),
    ("preset", "unknown preset"),
    ("point", "expected X,Y"),
    ("model", "fit"),
])
def test_bad_input_exits_2_with_one_line(pair, tmp_path, capsys, case, message):
    d = pair[0]
    args = _args(d, "--at", "320,240")
    if case == "unreadable":
        (tmp_path / "l.png").write_bytes(b"not an image")
        args[3] = str(tmp_path / "l.png")
    elif case == "missing":
        args[4] = str(tmp_path / "none.png")
    elif case == "size":
        small = cv2.resize(cv2.imread(str(d / "left.png")), (320, 240))
        cv2.imwrite(str(tmp_path / "small.png"), small)
        args[3] = str(tmp_path / "small.png")
    elif case == "outside":
        args[-1] = "640,10"
    elif case == "corrupt":
        (tmp_path / "c.yaml").write_text("%YAML:1.0\nM1: [oops\n")
        args[2] = str(tmp_path / "c.yaml")
    elif case == "preset":
        args += ["--preset", "nope"]
    elif case == "point":
        args[-1] = "12;4"
    elif case == "model":
        (tmp_path / "fit.json").write_text("[]")
        args += ["--model", str(tmp_path / "fit.json")]
    if case == "point":  # argparse's own usage error
        with pytest.raises(SystemExit) as exc:
            main(args)
        assert exc.value.code == 2
    else:
        assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert "Traceback" not in err
