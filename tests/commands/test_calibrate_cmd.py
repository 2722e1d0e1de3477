"""`stereo-gui calibrate`: JSON and summary output on rig data, and every bad input exits 2."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.files.calibration_file import load_calibration
from stereo_gui.sources.sim import write_calibration_set

N_PAIRS = 10

ISSUE_FIELDS = {"pairs_found", "pairs_used", "pairs_rejected", "image_size", "rms_left",
                "rms_right", "rms_stereo", "epipolar_error_px", "baseline_mm", "left", "right",
                "per_pair"}


@pytest.fixture(scope="module")
def rig_dir(tmp_path_factory) -> Path:
    return write_calibration_set(tmp_path_factory.mktemp("rig"), n_pairs=N_PAIRS, seed=31)


def _run(argv, capsys):
    try:
        code = main(["calibrate", *map(str, argv)])
    except SystemExit as exc:  # refused by the option parser
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_json_output(rig_dir, tmp_path, capsys):
    out_file = tmp_path / "calib.yaml"
    code, out, err = _run([rig_dir, "--board", "9x6", "--square-mm", "25", "-o", out_file,
                           "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)  # stdout is exactly one JSON object
    assert ISSUE_FIELDS <= set(data)
    assert data["pairs_found"] == N_PAIRS
    assert data["pairs_used"] + len(data["pairs_rejected"]) == N_PAIRS
    assert all(set(r) == {"name", "reason"} for r in data["pairs_rejected"])
    assert data["image_size"] == [640, 480]
    for side in ("left", "right"):
        cam = data[side]
        assert set(cam) == {"fx", "fy", "cx", "cy", "dist"} and len(cam["dist"]) == 5
        assert 700 < cam["fx"] < 800
    assert data["baseline_mm"] == pytest.approx(110.0, rel=0.01)
    assert data["rms_stereo"] < 0.3 and data["epipolar_error_px"] < 0.3
    assert len(data["per_pair"]) == data["pairs_used"]
    assert set(data["per_pair"][0]) == {"name", "error_left", "error_right"}
    assert data["per_pair"][0]["name"] == "chessboard-1"
    calib = load_calibration(out_file)
    assert calib.M1[0, 0] == data["left"]["fx"]
    assert calib.baseline_mm == pytest.approx(data["baseline_mm"])


def test_summary_progress_and_ros_export(rig_dir, tmp_path, capsys):
    ros = tmp_path / "ros"
    ros.mkdir()
    code, out, err = _run([rig_dir, "--square-mm", "25", "-o", tmp_path / "c.yaml", "--alpha",
                           "0.5", "--ros-dir", ros, "--progress"], capsys)
    assert code == 0, err
    assert f"calibrated from {N_PAIRS} of {N_PAIRS} pairs" in out
    assert "RMS reprojection error" in out and "epipolar error" in out and "baseline" in out
    assert "optimal new camera matrix" in out
    assert "detecting chessboards: 10/10" in err
    # each step in its own words, not one "calibrating" for all
    assert "calibrating the left camera: 0/8" in err and "calibrating the pair: 2/8" in err
    assert "rectifying: 6/8" in err
    assert (ros / "left.yaml").exists() and (ros / "right.yaml").exists()
    assert load_calibration(tmp_path / "c.yaml").alpha == 0.5


def test_hartley_method_says_it_is_not_metric(rig_dir, tmp_path, capsys):
    code, out, err = _run([rig_dir, "-o", tmp_path / "h.yaml", "--method", "hartley", "--json"],
                          capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["method"] == "hartley" and data["baseline_mm"] is None
    assert any("NOT in millimetres" in n for n in data["notes"])


def test_pairs_excluded_in_a_capture_session_are_left_out(rig_dir, tmp_path, capsys):
    """A session folder calibrates as the Calibration tab would: without its excluded pairs."""
    from stereo_gui.files.session import CaptureSession

    folder = tmp_path / "session"
    shutil.copytree(rig_dir, folder)
    session = CaptureSession.open(folder)
    session.set_excluded("chessboard-3", True)
    session.set_excluded("chessboard-7", True)
    code, out, err = _run([folder, "--board", "9x6", "--square-mm", "25", "-o",
                           tmp_path / "c.yaml", "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["pairs_found"] == N_PAIRS and data["pairs_used"] == N_PAIRS - 2
    excluded = {r["name"]: r["reason"] for r in data["pairs_rejected"]}
    assert excluded == {"chessboard-3": "excluded in the capture session",
                        "chessboard-7": "excluded in the capture session"}
    assert {p["name"] for p in data["per_pair"]}.isdisjoint(excluded)


def test_a_session_entry_pointing_outside_keeps_the_other_exclusions(rig_dir, tmp_path, capsys,
                                                                     caplog):
    """The probe: one manifest entry pointing outside the folder made the whole manifest
    unreadable, and calibrate took the pair the person had excluded."""
    from stereo_gui.files.session import MANIFEST, CaptureSession

    folder = tmp_path / "session"
    shutil.copytree(rig_dir, folder)
    CaptureSession.open(folder).set_excluded("chessboard-3", True)
    doc = json.loads((folder / MANIFEST).read_text())
    doc["pairs"][9]["left"] = "../elsewhere.png"
    (folder / MANIFEST).write_text(json.dumps(doc))
    code, out, err = _run([folder, "--board", "9x6", "--square-mm", "25", "-o",
                           tmp_path / "c.yaml", "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert [r["name"] for r in data["pairs_rejected"]] == ["chessboard-3"]
    assert data["pairs_used"] == N_PAIRS - 1
    said = [r.getMessage() for r in caplog.records if "left out" in r.getMessage()]
    assert len(said) == 1 and "'../elsewhere.png'" in said[0]  # said once, naming the entry


def _assert_one_error_line(code, out, err, *fragments):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("stereo-gui: error:")
    for f in fragments:
        assert f in lines[0], lines[0]
    assert "Traceback" not in err and out == ""


def _img(path: Path, size=(64, 48), value=None):
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(abs(hash(path.name)) % 2**32)
    img = rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8) if value is None else \
        np.full((size[1], size[0], 3), value, np.uint8)
    assert cv2.imwrite(str(path), img)
    return path


def test_missing_folder(tmp_path, capsys):
    _assert_one_error_line(*_run([tmp_path / "nope", "-o", tmp_path / "c.yaml"], capsys),
                           "does not exist", "nope")


def test_empty_folder(tmp_path, capsys):
    d = tmp_path / "empty"
    d.mkdir()
    _assert_one_error_line(*_run([d, "-o", tmp_path / "c.yaml"], capsys), "no images")


def test_unpaired_files_only(tmp_path, capsys):
    _img(tmp_path / "in" / "left1.png")
    _img(tmp_path / "in" / "right2.png")
    _assert_one_error_line(*_run([tmp_path / "in", "-o", tmp_path / "c.yaml"], capsys),
                           "no image pairs", "left1.png (no right image 1)",
                           "right2.png (no left image 2)")


def test_images_of_different_sizes_in_a_pair(tmp_path, capsys):
    _img(tmp_path / "in" / "left1.png", (64, 48))
    _img(tmp_path / "in" / "right1.png", (32, 24))
    _assert_one_error_line(*_run([tmp_path / "in", "-o", tmp_path / "c.yaml"], capsys),
                           "different sizes", "left1.png is 64x48", "right1.png is 32x24")


def test_pairs_of_different_sizes(tmp_path, capsys):
    for n in (1, 2, 3):
        _img(tmp_path / "in" / f"left{n}.png", (64, 48))
        _img(tmp_path / "in" / f"right{n}.png", (64, 48))
    _img(tmp_path / "in" / "left4.png", (32, 24))
    _img(tmp_path / "in" / "right4.png", (32, 24))
    _assert_one_error_line(*_run([tmp_path / "in", "-o", tmp_path / "c.yaml"], capsys),
                           "different sizes", "left4.png is 32x24 but the others are 64x48")


def test_corrupt_image_is_named(tmp_path, capsys):
    _img(tmp_path / "in" / "left1.png")
    _img(tmp_path / "in" / "right1.png")
    _img(tmp_path / "in" / "left2.png")
    (tmp_path / "in" / "right2.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    _assert_one_error_line(*_run([tmp_path / "in", "-o", tmp_path / "c.yaml"], capsys),
                           "right2.png", "corrupt")


def test_no_board_found_anywhere(tmp_path, capsys):
    for n in (1, 2, 3):
        _img(tmp_path / "in" / f"left{n}.png")
        _img(tmp_path / "in" / f"right{n}.png")
    _assert_one_error_line(*_run([tmp_path / "in", "-o", tmp_path / "c.yaml"], capsys),
                           "no chessboard (9x6 inner corners) found in any of 3 pairs")
    assert not (tmp_path / "c.yaml").exists()


def test_fewer_usable_pairs_than_the_minimum(rig_dir, tmp_path, capsys):
    d = tmp_path / "few"
    d.mkdir()
    for n in (1, 2, 3):
        for side in "LR":
            shutil.copy(rig_dir / f"chessboard-{side}{n}.png", d)
    _assert_one_error_line(*_run([d, "-o", tmp_path / "c.yaml"], capsys),
                           "only 3 usable pairs", "at least 5 are needed")
    _assert_one_error_line(*_run([rig_dir, "-o", tmp_path / "c.yaml", "--min-pairs", "50"], capsys),
                           f"only {N_PAIRS} usable pairs", "at least 50 are needed")


def test_board_size_that_does_not_parse(rig_dir, tmp_path, capsys):
    _assert_one_error_line(*_run([rig_dir, "--board", "nine-by-six", "-o", tmp_path / "c.yaml"],
                                 capsys), "board size 'nine-by-six' does not parse")


def test_other_bad_options(rig_dir, tmp_path, capsys):
    _assert_one_error_line(*_run([rig_dir, "-o", tmp_path / "no" / "c.yaml"], capsys),
                           "does not exist")
    _assert_one_error_line(*_run([rig_dir, "-o", tmp_path / "c.yaml", "--alpha", "3"], capsys),
                           "--alpha")
    _assert_one_error_line(*_run([rig_dir, "-o", tmp_path / "c.yaml", "--square-mm", "-2"],
                                 capsys), "--square-mm: a number from 0.01 to 10000 mm, not -2")


def test_subprocess_exit_status_and_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "calibrate", str(tmp_path / "nope"),
                           "-o", str(tmp_path / "c.yaml")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"stereo-gui: error: folder {tmp_path / 'nope'} does not exist"]
    assert proc.stdout == ""


def test_real_webcam_folder(shared_data, tmp_path, capsys):
    folder = shared_data / "real-webcam-9x6-30mm"
    if not folder.is_dir():
        pytest.skip("real-webcam-9x6-30mm is not present")
    code, out, err = _run([folder, "--square-mm", "30", "-o", tmp_path / "c.yaml", "--json"],
                          capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["pairs_found"] == 14 and data["pairs_used"] == 13
    assert data["pairs_rejected"][0]["name"] == "09"
    assert "right09.jpg" in data["pairs_rejected"][0]["reason"]
    assert data["rms_stereo"] < 0.7


@pytest.mark.slow
def test_hartley_without_a_board_uses_scene_features(tmp_path, capsys):
    from stereo_gui.sources.sim import Scene, SimRig

    left, right = SimRig(seed=4).render_scene(Scene.demo())
    d = tmp_path / "scene"
    d.mkdir()
    cv2.imwrite(str(d / "left1.png"), left)
    cv2.imwrite(str(d / "right1.png"), right)
    code, out, err = _run([d, "-o", tmp_path / "h.yaml", "--method", "hartley"], capsys)
    assert code == 0, err
    assert "no chessboard found; rectifying from matched scene features" in err
    assert "NOT in millimetres" in out and "RMS reprojection error: left n/a" in out
    calib = load_calibration(tmp_path / "h.yaml")
    assert calib.method == "hartley" and calib.board is None
    assert calib.epipolar_error_px < 1.0
    # the same folder with the default (metric) method has no board to work with
    _assert_one_error_line(*_run([d, "-o", tmp_path / "b.yaml"], capsys), "no chessboard")


def test_lens_shading_is_measured_and_kept_with_the_calibration(tmp_path, capsys):
    from dataclasses import replace as _replace

    from stereo_gui.sources.sim import RigConfig

    (tmp_path / "dark-corners").mkdir()
    folder = write_calibration_set(tmp_path / "dark-corners", n_pairs=N_PAIRS, seed=31,
                                   config=_replace(RigConfig(), vignetting=0.3))
    out_file = tmp_path / "calib.yaml"
    code, out, err = _run([folder, "--board", "9x6", "--square-mm", "25", "-o", out_file,
                           "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)
    for side in ("left", "right"):
        assert data["lens_shading"][side]["corner_loss"] == pytest.approx(0.3, abs=0.04)
    assert load_calibration(out_file).lens_shading.left.corner_loss == pytest.approx(
        data["lens_shading"]["left"]["corner_loss"])
    code, out, err = _run([folder, "--board", "9x6", "--square-mm", "25", "-o", out_file],
                          capsys)
    assert code == 0 and "lens shading: corners 3" in out and "undone before matching" in out


def test_a_rig_without_dark_corners_says_so(rig_dir, tmp_path, capsys):
    code, out, err = _run([rig_dir, "--board", "9x6", "--square-mm", "25", "-o",
                           tmp_path / "c.yaml"], capsys)
    assert code == 0 and "lens shading: none worth undoing" in out


@pytest.mark.parametrize("json_out", [False, True])
def test_a_calibration_that_cannot_be_written_is_printed_with_the_remedy(rig_dir, tmp_path,
                                                                         capsys, monkeypatch,
                                                                         json_out):
    """The minute of work is not lost when the file is refused (a check at save, or the disk):
    the result is printed all the same, nothing is written, and the error names the remedy."""
    import stereo_gui.files.calibration_file as calibration_file
    from stereo_gui.core.errors import CalibrationFileError

    def refuse(calib, where):
        raise CalibrationFileError(f"{where}: distortion D2 does not describe camera 2's lens")

    monkeypatch.setattr(calibration_file, "check_plausible", refuse)
    out_file = tmp_path / "calib.yaml"
    args = [rig_dir, "--board", "9x6", "--square-mm", "25", "-o", out_file]
    code, out, err = _run(args + (["--json"] if json_out else []), capsys)
    assert code == 2 and not out_file.exists()
    assert "does not describe camera 2's lens" in err and "computed but not written" in err
    assert "leave out the worst pairs" in err
    if json_out:
        data = json.loads(out)
        assert "output" not in data and data["baseline_mm"] == pytest.approx(110.0, rel=0.01)
    else:
        assert "baseline 1" in out and "worst pairs:" in out and "NOT WRITTEN" in out

    def full_disk(calib, where):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(calibration_file, "check_plausible", full_disk)
    code, out, err = _run(args, capsys)
    assert code == 2 and "No space left" in err and "free space on the disk" in err
    assert "NOT WRITTEN" in out and not out_file.exists()
