"""`--calib` with other tools' calibrations: OpenCV's stereo sample files (both forms, YAML and
XML), a ROS camera_info pair, and rectified pairs with a principal point offset (doffs), given as
rectified:F,B,DOFFS and as a Middlebury calib.txt, each measured on rendered pairs whose true
distance is known."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.files.calibration_file import export_ros

AT = ("320,240", "250,200", "420,300")


@pytest.fixture(scope="module")
def rig_pair(wall_files):
    """Raw left/right images of a wall from the simulated rig, the rig, scene and calibration."""
    return wall_files


def _measure(capsys, calib_spec, left, right, at=AT) -> list[dict]:
    args = ["measure", "--calib", str(calib_spec), str(left), str(right), "--json"]
    for a in at:
        args += ["--at", a]
    assert main(args) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)["points"]


def _write(path, values: dict, names) -> None:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for name in names:
        fs.write(name, np.asarray(values[name], np.float64))
    fs.release()


def _sample_values(calib, size):
    """What stereo_calib.cpp computes: stereoRectify with CALIB_ZERO_DISPARITY and alpha 1."""
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(calib.M1, calib.D1, calib.M2, calib.D2, size,
                                                calib.R, calib.T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=1)
    return {"M1": calib.M1, "D1": calib.D1, "M2": calib.M2, "D2": calib.D2, "R": calib.R,
            "T": calib.T, "R1": R1, "R2": R2, "P1": P1, "P2": P2, "Q": Q}


def _check_against_truth(points, rig, scene, calib):
    for p in points:
        assert p["valid"], p
        true = rig.true_point_rectified(calib, scene, p["x"], p["y"])
        assert p["Z_mm"] == pytest.approx(true[2], rel=0.01)


@pytest.mark.parametrize("suffix", [".yml", ".xml"])
@pytest.mark.parametrize("form", ["pair", "one_file"])
def test_measure_with_opencv_sample_files(rig_pair, tmp_path, capsys, suffix, form):
    d, rig, scene, calib = rig_pair
    values = _sample_values(calib, calib.image_size)
    if form == "pair":
        _write(tmp_path / f"intrinsics{suffix}", values, ("M1", "D1", "M2", "D2"))
        _write(tmp_path / f"extrinsics{suffix}", values, ("R", "T", "R1", "R2", "P1", "P2", "Q"))
        spec = tmp_path / f"extrinsics{suffix}"
    else:  # one file, only what stereoCalibrate gives: the rest is computed
        _write(tmp_path / f"stereo{suffix}", values, ("M1", "D1", "M2", "D2", "R", "T"))
        spec = tmp_path / f"stereo{suffix}"
    points = _measure(capsys, spec, d / "left.png", d / "right.png")
    from stereo_gui.commands.disparity import load_calibration

    used = load_calibration(str(spec), str(d / "left.png"))  # the size came from LEFT
    assert used.image_size == calib.image_size
    _check_against_truth(points, rig, scene, used)


@pytest.mark.parametrize("given", ["left.yaml", "right.yaml"])
def test_measure_with_a_ros_camera_info_pair(rig_pair, tmp_path, capsys, given):
    d, rig, scene, calib = rig_pair
    export_ros(calib, tmp_path)
    points = _measure(capsys, tmp_path / given, d / "left.png", d / "right.png")
    _check_against_truth(points, rig, scene, calib)


def test_a_lone_ros_file_names_its_missing_partner(rig_pair, tmp_path, capsys):
    d, _, _, calib = rig_pair
    export_ros(calib, tmp_path)
    (tmp_path / "right.yaml").unlink()
    args = ["measure", "--calib", str(tmp_path / "left.yaml"), str(d / "left.png"),
            str(d / "right.png"), "--at", "320,240"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "left.yaml" in err and "other camera" in err


@pytest.fixture(scope="module")
def shifted_pair(rig_pair, tmp_path_factory):
    """An already rectified pair whose right principal point lies DOFFS px right of the left one:
    the rig's pair rectified with its true calibration, the right image shifted DOFFS px to the
    right (so every disparity shrinks by DOFFS while Z stays)."""
    d0, rig, scene, calib = rig_pair
    d = tmp_path_factory.mktemp("shifted")
    doffs = 24
    maps = calib.rectify_maps()
    left = cv2.imread(str(d0 / "left.png"))
    right = cv2.imread(str(d0 / "right.png"))
    rl = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
    rr = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
    shifted = np.zeros_like(rr)
    shifted[:, doffs:] = rr[:, :-doffs]
    cv2.imwrite(str(d / "left.png"), rl)
    cv2.imwrite(str(d / "right.png"), shifted)
    return d, rig, scene, calib, doffs


def test_rectified_spec_with_doffs_measures_its_own_triangulation(shifted_pair, capsys):
    d, rig, scene, calib, doffs = shifted_pair
    f, b = calib.focal_px, calib.rectified_baseline_mm
    spec = f"rectified:{f!r},{b!r},{doffs}"
    points = _measure(capsys, spec, d / "left.png", d / "right.png")
    for p in points:
        assert p["valid"]
        # its own triangulation: Z = f B / (d + doffs), the disparity being that of the pair
        assert p["Z_mm"] == pytest.approx(f * b / (p["disparity_px"] + doffs), rel=1e-6)
        assert p["disparity_px"] == pytest.approx(f * b / p["Z_mm"] - doffs, rel=1e-6)
    _check_against_truth(points, rig, scene, calib)
    # without DOFFS the same pair reads far too far: the offset matters
    wrong = _measure(capsys, f"rectified:{f!r},{b!r}", d / "left.png", d / "right.png")
    assert all(w["Z_mm"] > 1.3 * p["Z_mm"] for w, p in zip(wrong, points, strict=True))


def test_middlebury_calib_txt_with_doffs(shifted_pair, tmp_path, capsys):
    d, rig, scene, calib, doffs = shifted_pair
    f, cx, cy = calib.P1[0, 0], calib.P1[0, 2], calib.P1[1, 2]
    w, h = calib.image_size
    (tmp_path / "calib.txt").write_text(
        f"cam0=[{f} 0 {cx}; 0 {f} {cy}; 0 0 1]\ncam1=[{f} 0 {cx + doffs}; 0 {f} {cy}; 0 0 1]\n"
        f"doffs={doffs}\nbaseline={calib.rectified_baseline_mm}\nwidth={w}\nheight={h}\n"
        "ndisp=128\nisint=0\nvmin=10\nvmax=100\ndyavg=0\ndymax=0\n")
    points = _measure(capsys, tmp_path / "calib.txt", d / "left.png", d / "right.png")
    _check_against_truth(points, rig, scene, calib)


@pytest.mark.parametrize("spec,message", [
    ("rectified:500", "rectified:F,B or rectified:F,B,DOFFS"),
    ("rectified:500,abc", "must be numbers"),
    ("rectified:1e308,1e308", "focal length F"),
])
def test_malformed_rectified_specs_exit_2_saying_the_form(rig_pair, capsys, spec, message):
    d = rig_pair[0]
    for cmd in ("measure", "disparity"):
        args = [cmd, "--calib", spec, str(d / "left.png"), str(d / "right.png")]
        args += ["--at", "1,1"] if cmd == "measure" else ["-o", str(d / "out.png")]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.startswith("stereo-gui") and message in err and err.count("\n") == 1
