"""`stereo-gui calibrate` with other targets and lens models: --target, --board, --square-mm,
--marker-mm, --dict, --model, --fix-k3; the `uncertainty` object and the `warnings` list."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from stereo_gui.cli import main
from stereo_gui.core.board import BoardSpec
from stereo_gui.files.calibration_file import load_calibration
from stereo_gui.sources.sim import RigConfig, write_calibration_set

CHARUCO = BoardSpec(7, 5, 30.0, "charuco", 22.0, "DICT_4X4_50")


@pytest.fixture(scope="module")
def charuco_dir(tmp_path_factory) -> Path:
    return write_calibration_set(tmp_path_factory.mktemp("charuco"), n_pairs=12, seed=41,
                                 config=RigConfig(board=CHARUCO))


def _run(argv, capsys):
    code = main(["calibrate", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_charuco_json_has_uncertainty_and_warnings(charuco_dir, tmp_path, capsys):
    out_file = tmp_path / "c.yaml"
    code, out, err = _run([charuco_dir, "--target", "charuco", "--board", "7x5", "--square-mm",
                           "30", "--marker-mm", "22", "--dict", "DICT_4X4_50", "-o", out_file,
                           "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["pairs_used"] >= 10 and data["model"] == "pinhole"
    assert data["board"] == CHARUCO.to_json()
    u = data["uncertainty"]
    assert u["level"] == "1 sigma"
    for side in ("left", "right"):
        assert set(u[side]) >= {"fx", "fy", "cx", "cy", "dist"}
        assert len(u[side]["dist"]) == 5
        assert 0 < u[side]["fx"] < 0.01 * data[side]["fx"]
    assert u["baseline_mm"] > 0 and u["rotation_deg"] > 0
    assert isinstance(data["warnings"], list)
    assert all(set(w) >= {"code", "message"} for w in data["warnings"])
    assert data["baseline_mm"] == pytest.approx(110.0, rel=0.005)
    calib = load_calibration(out_file)
    assert calib.board == CHARUCO and calib.uncertainty is not None
    assert calib.uncertainty.sigma("left.fx") == pytest.approx(u["left"]["fx"])


def test_lens_model_and_fixed_k3(charuco_dir, tmp_path, capsys):
    code, out, err = _run([charuco_dir, "--target", "charuco", "--square-mm", "30",
                           "--marker-mm", "22", "--model", "rational", "--fix-k3", "-o",
                           tmp_path / "r.yaml", "--json"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["model"] == "rational" and len(data["left"]["dist"]) == 8
    assert data["left"]["dist"][4:] == [0.0, 0.0, 0.0, 0.0]  # k3 and higher held at zero
    assert data["distortion_names"] == ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    # the rational model's coefficients are not identifiable one by one: no sigma for them
    assert data["uncertainty"]["left"]["dist"] == [None] * 8
    assert load_calibration(tmp_path / "r.yaml").model == "rational"


def test_summary_states_one_sigma(charuco_dir, tmp_path, capsys):
    code, out, err = _run([charuco_dir, "--target", "charuco", "--square-mm", "30",
                           "--marker-mm", "22", "-o", tmp_path / "c.yaml"], capsys)
    assert code == 0, err
    assert "±" in out and "1 sigma" in out and "ChArUco 7x5" in out


def test_swapped_cameras_warn_swapped(charuco_dir, tmp_path, capsys):
    swapped = tmp_path / "swapped"
    swapped.mkdir()
    for f in charuco_dir.glob("chessboard-*.png"):
        other = f.name.replace("-L", "-X").replace("-R", "-L").replace("-X", "-R")
        shutil.copy(f, swapped / other)
    code, out, err = _run([swapped, "--target", "charuco", "--square-mm", "30", "--marker-mm",
                           "22", "-o", tmp_path / "s.yaml", "--json"], capsys)
    assert code == 0, err
    codes = [w["code"] for w in json.loads(out)["warnings"]]
    assert "swapped" in codes


@pytest.mark.parametrize("argv, words", [
    (["--target", "hexagons"], "invalid choice"),
    (["--target", "charuco", "--board", "2x2"], "at least 3x3"),
    (["--target", "charuco", "--marker-mm", "40", "--square-mm", "30"], "smaller than the squares"),
    (["--model", "kaleidoscope"], "invalid choice"),
])
def test_bad_target_or_model_exits_2(charuco_dir, tmp_path, capsys, argv, words):
    try:
        code = main(["calibrate", str(charuco_dir), "-o", str(tmp_path / "x.yaml"), *argv])
    except SystemExit as exc:  # argparse's own refusals
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) <= 2
