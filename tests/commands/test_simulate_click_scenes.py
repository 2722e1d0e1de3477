"""`stereo-gui simulate OUT_DIR --click-scenes`: rectified scenes of the simulated rig with their
true disparity, a mask and clicks.tsv, as files/scenes reads them; bad input exits 2, one line."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np
import pytest

import stereo_gui.commands.simulate as simulate
from stereo_gui.cli import main
from stereo_gui.files.rectified_calibration import parse_rectified_spec
from stereo_gui.files.scenes import load_scene, read_pfm, read_scene_list, read_seen_mask
from stereo_gui.sources.sim import SimRig
from stereo_gui.sources.sim.click_scenes import (CLICK_LIST, click_scene_names,
                                                 click_scene_plan, write_click_scenes)

SMALL = {"walls": (1000.0,), "conditions": ("rig",), "demo": False}


@pytest.fixture
def small_plan(monkeypatch):
    """The command with one wall under one condition per seed (the full plan is 15 scenes)."""
    for name, function in (("write_click_scenes", write_click_scenes),
                           ("click_scene_names", click_scene_names)):
        monkeypatch.setattr(simulate, name, functools.partial(function, **SMALL))


MEDIUM = {"walls": (500.0, 3000.0), "conditions": ("rig", "webcams"), "demo": True}


@pytest.fixture(scope="module")
def one_seed(tmp_path_factory):
    """Two walls and the demo scene under two conditions, seed 5, written by the command."""
    out = tmp_path_factory.mktemp("clicks")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(simulate, "write_click_scenes", functools.partial(write_click_scenes, **MEDIUM))
        mp.setattr(simulate, "click_scene_names", functools.partial(click_scene_names, **MEDIUM))
        assert main(["simulate", str(out), "--click-scenes", "--seeds", "1", "--seed", "5"]) == 0
    return out


def test_the_plan_of_a_seed():
    names = [s.name for s in click_scene_plan(4)]
    assert names == [f"s4-{c}-{w}" for c in ("rig", "quarter", "webcams")
                     for w in ("wall0.5m", "wall1m", "wall2m", "wall3m", "demo")]
    files = click_scene_names([4, 5])
    assert len(files) == 2 * 15 * 4 + 1 and files[-1] == CLICK_LIST


def _z(spec: str, d: float) -> float:
    r = parse_rectified_spec(spec)
    return r.focal_px * r.baseline_mm / (d + r.doffs_px)


@pytest.mark.slow
def test_list_names_every_scene_and_loads(one_seed):
    specs = read_scene_list(one_seed / CLICK_LIST)
    expected = [s.name for s in click_scene_plan(5, **MEDIUM)]
    assert [s.name for s in specs] == expected and len(expected) == 6
    lines = [ln for ln in (one_seed / CLICK_LIST).read_text().splitlines()
             if not ln.startswith("#")]
    assert all(len(ln.split("\t")) == 7 for ln in lines)
    for spec in specs:
        scene = load_scene(spec)
        assert scene.size == (640, 480) and spec.calib.startswith("rectified:")
        mask = read_seen_mask(spec)
        assert mask.shape == (480, 640) and mask[120:360, 160:480].mean() > 0.8
        if "wall" in spec.name:  # (the demo's centre lies in the panel's occlusion)
            assert mask[200:280, 280:360].all()  # 255 in the middle
        assert (scene.truth_px[mask] > 0).all()  # truth wherever both cameras see
    assert not [p for p in (one_seed / "click-scenes").iterdir() if p.name.startswith(".")]


@pytest.mark.slow
def test_truth_gives_the_wall_distance_through_the_calibration(one_seed):
    for spec in read_scene_list(one_seed / CLICK_LIST):
        truth = read_pfm(spec.truth)
        if "wall" not in spec.name:
            continue
        wall_mm = float(spec.name.rsplit("wall", 1)[1].rstrip("m")) * 1000.0
        z = _z(spec.calib, float(truth[240, 320]))
        assert z == pytest.approx(wall_mm, rel=1e-3), spec.name
        # the whole wall: Z within the rectified frame's small turn of the wall's plane
        known = np.isfinite(truth)
        assert known.mean() > 0.999
        zs = _z(spec.calib, truth[known].astype(np.float64))
        assert np.all(np.abs(zs / wall_mm - 1.0) < 0.02), spec.name


@pytest.mark.slow
def test_demo_truth_has_its_objects_and_an_occlusion(one_seed):
    spec = next(s for s in read_scene_list(one_seed / CLICK_LIST) if s.name == "s5-rig-demo")
    truth = read_pfm(spec.truth)
    mask = read_seen_mask(spec)
    zs = _z(spec.calib, truth[np.isfinite(truth)].astype(np.float64))
    # the background wall at 3 m and the box at 0.8 m (its front plane)
    assert zs.max() == pytest.approx(3000.0, rel=0.01)
    assert zs.min() == pytest.approx(800.0, rel=0.01)
    # pixels whose match lies inside the right image and which the right camera still does
    # not see: hidden behind an object (a wall alone has almost none)
    xs = np.arange(640)[None, :]
    inside = np.isfinite(truth) & (xs - truth >= 0)
    hidden = (inside & ~mask).sum()
    wall = next(s for s in read_scene_list(one_seed / CLICK_LIST) if s.name == "s5-rig-wall3m")
    wall_truth = read_pfm(wall.truth)
    wall_hidden = (np.isfinite(wall_truth) & (xs - wall_truth >= 0) & ~read_seen_mask(wall)).sum()
    assert hidden > 1000 > 10 * wall_hidden, (hidden, wall_hidden)


def test_truth_agrees_with_bench_accuracy_wall_truth(tmp_path):
    """Two separate paths to the truth: the rectified pixel's ray through R1 and P1 here, the
    pixel's raw image point undistorted and met with the wall in commands/accuracy.WallTruth."""
    from stereo_gui.commands.accuracy import WallTruth
    from stereo_gui.sources.sim.click_scenes import true_disparity

    rig = SimRig(seed=1)
    calib = rig.true_calibration(alpha=0.0)
    for cs in click_scene_plan(1, walls=(500.0, 3000.0), conditions=("rig",), demo=False):
        disparity, seen = true_disparity(rig, calib, cs.scene)
        wt = WallTruth(rig, calib, cs.distance_mm)
        f, b = calib.focal_px, calib.rectified_baseline_mm
        for y in range(8, 480, 47):
            for x in range(8, 640, 53):
                z, both = wt.point(x, y)
                assert f * b / (float(disparity[y, x]) + calib.disparity_offset_px) == \
                    pytest.approx(z, rel=1e-6)
                assert bool(seen[y, x]) == both, (x, y)


def test_images_agree_with_the_truth(tmp_path, small_plan):
    """The right image shifted by the true disparity matches the left one best with no extra
    shift (a tenth of a pixel either way is worse)."""
    assert main(["simulate", str(tmp_path), "--click-scenes", "--seeds", "1"]) == 0
    spec = read_scene_list(tmp_path / CLICK_LIST)[0]
    scene = load_scene(spec)
    mask = cv2.erode(read_seen_mask(spec).astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    gl, gr = (cv2.cvtColor(i, cv2.COLOR_BGR2GRAY).astype(np.float32)
              for i in (scene.left, scene.right))
    ys, xs = np.mgrid[0:480, 0:640].astype(np.float32)

    def residual(extra: float) -> float:
        warped = cv2.remap(gr, xs - scene.truth_px - extra, ys, cv2.INTER_CUBIC)
        return float(np.mean(((warped - gl) ** 2)[mask]))

    assert residual(0.0) < min(residual(-0.1), residual(0.1))


@pytest.mark.slow
def test_second_run_needs_overwrite_and_replaces_cleanly(tmp_path, small_plan, capsys):
    out = tmp_path / "o"
    assert main(["simulate", str(out), "--click-scenes", "--seeds", "2"]) == 0
    printed = capsys.readouterr().out
    assert "wrote 2 click scenes" in printed and "rectified:" in printed
    assert main(["simulate", str(out), "--click-scenes", "--seeds", "1"]) == 2
    err = capsys.readouterr().err
    assert "--overwrite" in err and len(err.strip().splitlines()) == 1
    (out / "notes.txt").write_text("mine")
    assert main(["simulate", str(out), "--click-scenes", "--seeds", "1", "--seed", "7",
                 "--overwrite"]) == 0
    assert "removed 8 files" in capsys.readouterr().out
    assert [s.name for s in read_scene_list(out / CLICK_LIST)] == ["s7-rig-wall1m"]
    assert sorted(p.name for p in (out / "click-scenes").iterdir()) == sorted(
        f"s7-rig-wall1m{s}" for s in ("-L.png", "-R.png", "-truth.pfm", "-mask.png"))
    assert (out / "notes.txt").read_text() == "mine"
    # a calibration set in the same folder is another set: neither refuses the other
    assert main(["simulate", str(out), "--pairs", "1"]) == 0
    assert (out / CLICK_LIST).is_file()


@pytest.mark.parametrize("argv, words", [
    (["--click-scenes", "--pairs", "3"], "--pairs does not go with --click-scenes"),
    (["--click-scenes", "--scene"], "--scene does not go with --click-scenes"),
    (["--click-scenes", "--board", "7x5"], "--board does not go with --click-scenes"),
    (["--seeds", "2"], "--seeds goes with --click-scenes"),
    (["--click-scenes", "--seed", str(2**32 - 1), "--seeds", "2"], "largest seed"),
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys, argv, words):
    assert main(["simulate", str(tmp_path / "x"), *argv]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("seeds", ["0", "1001", "many"])
def test_bad_seed_count_is_refused_by_the_parser(tmp_path, capsys, seeds):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "x"), "--click-scenes", "--seeds", seeds])
    assert exc.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) <= 2  # argparse's usage + one line
    assert not (tmp_path / "x").exists()


def test_folder_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["simulate", str(f), "--click-scenes"]) == 2
    assert "is a file" in capsys.readouterr().err


@pytest.mark.slow
def test_centre_z_matches_the_wall_to_a_thousandth():
    from stereo_gui.sources.sim.click_scenes import centre_check, true_disparity

    rig = SimRig(seed=0)
    calib = rig.true_calibration(alpha=0.0)
    for cs in click_scene_plan(0, conditions=("rig",), demo=False):
        disparity, _ = true_disparity(rig, calib, cs.scene)
        assert math.isclose(centre_check(calib, disparity), cs.distance_mm, rel_tol=1e-3)
