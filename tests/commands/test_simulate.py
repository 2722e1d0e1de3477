"""`stereo-gui simulate`: writes a calibration set with its truth; bad input exits 2, one line."""

from __future__ import annotations

import json
import os

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.core.stereo_calibration import StereoCalibration  # noqa: F401 - import check
from stereo_gui.sources.sim import RigTruth


def test_simulate_writes_pairs_and_truth(tmp_path, capsys):
    out = tmp_path / "new" / "set"
    assert main(["simulate", str(out), "--pairs", "3", "--seed", "7"]) == 0
    printed = capsys.readouterr().out
    assert "3 chessboard pairs" in printed and "truth.json" in printed
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted([f"chessboard-{s}{n}.png" for n in (1, 2, 3) for s in "LR"] + ["truth.json"])
    data = json.loads((out / "truth.json").read_text())
    assert data["seed"] == 7 and len(data["pairs"]) == 3 and "scenes" not in data
    assert RigTruth.from_json(data).baseline_mm == pytest.approx(110.0)
    img = cv2.imread(str(out / "chessboard-R3.png"))
    assert img is not None and img.shape == (480, 640, 3)
    ok, _ = cv2.findChessboardCorners(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), (9, 6))
    assert ok
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_simulate_same_seed_same_images(tmp_path):
    assert main(["simulate", str(tmp_path / "a"), "--pairs", "1", "--seed", "2"]) == 0
    assert main(["simulate", str(tmp_path / "b"), "--pairs", "1", "--seed", "2"]) == 0
    assert main(["simulate", str(tmp_path / "c"), "--pairs", "1", "--seed", "3"]) == 0
    a = cv2.imread(str(tmp_path / "a" / "chessboard-L1.png"))
    b = cv2.imread(str(tmp_path / "b" / "chessboard-L1.png"))
    c = cv2.imread(str(tmp_path / "c" / "chessboard-L1.png"))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.slow
def test_simulate_scene(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["simulate", str(out), "--pairs", "1", "--scene"]) == 0
    assert "6 scene pairs" in capsys.readouterr().out
    data = json.loads((out / "truth.json").read_text())
    scenes = data["scenes"]
    assert [s.get("distance_mm") for s in scenes[:5]] == [500.0, 1000.0, 1500.0, 2000.0, 3000.0]
    assert scenes[5]["name"] == "demo" and len(scenes[5]["objects"]) == 4
    for s in scenes:
        assert (out / s["left"]).is_file() and (out / s["right"]).is_file()
    # the scene pairs sit apart, so calibrating OUT_DIR sees only the board pairs
    from stereo_gui.files.pairs import discover_pairs

    assert [p.name for p in discover_pairs(out).pairs] == ["chessboard-1"]


def test_overwrite_replaces_and_removes_stale_pairs(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["simulate", str(out), "--pairs", "3"]) == 0
    assert main(["simulate", str(out), "--pairs", "1"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    (out / "notes.txt").write_text("mine")
    assert main(["simulate", str(out), "--pairs", "1", "--overwrite"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["chessboard-L1.png", "chessboard-R1.png", "notes.txt", "truth.json"]


def test_bad_pair_count(tmp_path, capsys):
    for count in ("0", "10001", "many"):
        with pytest.raises(SystemExit) as exc:
            main(["simulate", str(tmp_path / "x"), "--pairs", count])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "--pairs: a whole number from 1 to 10000" in err
        assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_out_dir_is_a_file(tmp_path, capsys):
    f = tmp_path / "file.png"
    f.write_bytes(b"x")
    assert main(["simulate", str(f)]) == 2
    err = capsys.readouterr().err
    assert "is a file" in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs a non-root POSIX user")
def test_out_dir_unwritable(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert main(["simulate", str(ro)]) == 2
        assert main(["simulate", str(ro / "sub")]) == 2
    finally:
        ro.chmod(0o700)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("cannot" in line for line in err)


def test_out_dir_unwritable_reported(tmp_path, capsys, monkeypatch):
    """Whatever the user running the tests, a folder without write permission gives one line."""
    import stereo_gui.commands.simulate as simulate

    monkeypatch.setattr(simulate.os, "access", lambda path, mode: False)
    assert main(["simulate", str(tmp_path / "ro")]) == 2
    err = capsys.readouterr().err
    assert "cannot write into folder" in err and len(err.strip().splitlines()) == 1


def test_full_disk_leaves_no_partial_file(tmp_path, capsys, monkeypatch):
    import errno

    import stereo_gui.files.atomic as atomic

    def disk_full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.syscalls, "fsync", disk_full)
    assert main(["simulate", str(tmp_path / "w"), "--pairs", "1"]) == 2
    err = capsys.readouterr().err
    assert "cannot write" in err and "No space left" in err and len(err.strip().splitlines()) == 1
    assert list((tmp_path / "w").iterdir()) == []


def test_simulate_time_offset_says_the_board_moved_and_is_bounded(tmp_path, capsys):
    out = tmp_path / "late"
    assert main(["simulate", str(out), "--pairs", "1", "--time-offset", "0.05"]) == 0
    assert "the right camera 50 ms late, the board moving" in capsys.readouterr().out
    assert json.loads((out / "truth.json").read_text())["time_offset_s"] == 0.05
    with pytest.raises(SystemExit) as ended:
        main(["simulate", str(tmp_path / "x"), "--time-offset", "0.6"])
    assert ended.value.code == 2
    assert "--time-offset: a number from 0 to 0.5 s, not 0.6" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "y"), "--click-scenes", "--time-offset", "0.05"]) == 2
    assert "--time-offset does not go with --click-scenes" in capsys.readouterr().err
