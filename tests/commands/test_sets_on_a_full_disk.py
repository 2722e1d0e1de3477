"""Commands that write a set of files write all of it or leave every earlier file as it was
(the probe: `simulate --overwrite` on a filling disk replaced 12 of 13 images while truth.json
still described the old set; `disparity` left half old and half new outputs)."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "files"))
from disk_faults import install  # noqa: E402

from stereo_gui.cli import main  # noqa: E402


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _one_line(capsys, code, *words):
    out, err = capsys.readouterr()
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]
    return out


@pytest.fixture(scope="module")
def old_set(tmp_path_factory):
    """A simulated set of 6 pairs and the bytes of its 13 files."""
    out = tmp_path_factory.mktemp("set") / "sim"
    assert main(["simulate", str(out), "--pairs", "6", "--seed", "1"]) == 0
    return out, _snapshot(out)


def _fresh_copy(old_set, tmp_path) -> Path:
    out, files = old_set
    copy = tmp_path / "sim"
    copy.mkdir()
    for name, data in files.items():
        (copy / name).write_bytes(data)
    return copy


@pytest.mark.parametrize("step, nth, rename", [("write", 12, None), ("open", 13, None),
                                               ("replace", 13, 7)])
def test_simulate_overwrite_keeps_the_earlier_set_whole(old_set, tmp_path, monkeypatch, capsys,
                                                        step, nth, rename):
    out = _fresh_copy(old_set, tmp_path)
    before = _snapshot(out)
    assert len(before) == 13
    install(monkeypatch, step, nth, rename)
    code = main(["simulate", str(out), "--pairs", "6", "--seed", "2", "--overwrite"])
    stdout = _one_line(capsys, code, "No space left", f"the new simulated set in {out} was not "
                       "written: every file it would have replaced is as it was")
    monkeypatch.undo()
    assert _snapshot(out) == before  # truth.json still describes the images beside it
    assert [p.name for p in out.rglob(".*")] == []  # no temporary file left
    assert "wrote" not in stdout


def test_simulate_a_new_set_with_scenes_leaves_nothing_on_failure(tmp_path, monkeypatch, capsys):
    install(monkeypatch, "write", 5)
    code = main(["simulate", str(tmp_path / "new"), "--pairs", "2", "--scene"])
    _one_line(capsys, code, "was not written")
    monkeypatch.undo()
    assert list((tmp_path / "new").iterdir()) == []  # not even the scenes folder


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    left = np.random.default_rng(1).integers(0, 255, (60, 80, 3), np.uint8)
    cv2.imwrite(str(d / "l.png"), left)
    cv2.imwrite(str(d / "r.png"), np.roll(left, -8, axis=1))
    return d / "l.png", d / "r.png"


@pytest.mark.parametrize("step, nth, rename", [("write", 3, None), ("fsync", 4, None),
                                               ("replace", 5, 3)])
def test_disparity_writes_all_its_outputs_or_none(pair, tmp_path, monkeypatch, capsys, step, nth,
                                                  rename):
    outs = [tmp_path / "v.png", tmp_path / "d.npy", tmp_path / "d16.png", tmp_path / "z.png",
            tmp_path / "c.ply"]
    for p in outs[:4]:  # the cloud is new: it must not stay behind either
        p.write_bytes(b"old " + p.name.encode())
    before = _snapshot(tmp_path)
    install(monkeypatch, step, nth, rename)
    code = main(["disparity", "--calib", "rectified:300,100", str(pair[0]), str(pair[1]),
                 "-o", str(outs[0]), "--npy", str(outs[1]), "--png16", str(outs[2]),
                 "--depth-png", str(outs[3]), "--ply", str(outs[4])])
    _one_line(capsys, code, "the set of outputs was not written")
    monkeypatch.undo()
    assert _snapshot(tmp_path) == before


def test_disparity_with_every_output_writes_them_all(pair, tmp_path, capsys):
    outs = [tmp_path / "v.png", tmp_path / "d.npy", tmp_path / "d16.png", tmp_path / "z.png",
            tmp_path / "c.ply"]
    assert main(["disparity", "--calib", "rectified:300,100", str(pair[0]), str(pair[1]),
                 "-o", str(outs[0]), "--npy", str(outs[1]), "--png16", str(outs[2]),
                 "--depth-png", str(outs[3]), "--ply", str(outs[4])]) == 0
    assert all(p.stat().st_size > 0 for p in outs)
    assert np.load(outs[1]).shape == (60, 80)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in outs)
