"""`stereo-gui bench --scenes`: the presets beside plain OpenCV on scenes with ground truth."""

import json

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.resources import resource_path


def _scene(folder, name, shift, w=240, h=120, seed=0):
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.integers(0, 256, (h, w + shift, 3), np.uint8), (3, 3), 0)
    cv2.imwrite(str(folder / f"{name}-l.png"), np.ascontiguousarray(big[:, :w]))
    cv2.imwrite(str(folder / f"{name}-r.png"), np.ascontiguousarray(big[:, shift:]))
    cv2.imwrite(str(folder / f"{name}-gt.png"), np.full((h, w), shift * 4, np.uint8))
    return f"{name}\t{name}-l.png\t{name}-r.png\t{name}-gt.png\t4\n"


def test_scene_bench_scores_every_preset_beside_the_baselines(tmp_path, capsys):
    (tmp_path / "s.tsv").write_text("# name\tleft\tright\ttruth\tdiv\n"
                                    + _scene(tmp_path, "a", 12) + _scene(tmp_path, "b", 20, seed=1))
    assert main(["bench", "--scenes", str(tmp_path / "s.tsv"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [s["name"] for s in doc["scenes"]] == ["a", "b"]
    assert doc["baseline_of"] == {"live": "plain@live", "quality": "plain"}
    for scene in doc["scenes"]:
        methods = scene["methods"]
        assert set(methods) == {"plain", "plain@live", "live", "quality"}
        for m in methods.values():
            assert {"bad1", "bad2", "bad4", "density", "median_error_px", "ms"} <= set(m)
            assert 0.0 <= m["density"] <= 1.0 and m["ms"] > 0
        # a shifted texture: every method finds the shift where it has a value
        assert methods["quality"]["bad2"] < 0.05 and methods["quality"]["density"] > 0.7
    assert set(doc["verdict"]) == {"live", "quality"}
    # the table a person reads names every method and gives each preset's verdict
    assert main(["bench", "--scenes", str(tmp_path / "s.tsv"), "--preset", "quality"]) == 0
    text = capsys.readouterr().out
    assert "plain" in text and "quality: within the margins of plain on" in text
    assert "live" not in text.replace("plain@live", "")


def test_a_preset_matching_some_scenes_reduced_is_held_to_each_scenes_baseline(tmp_path,
                                                                                capsys):
    """A preset with a largest matching width (quality at most 300 px wide) matches a 240 px
    scene at full size and a 400 px one reduced: each scene holds it to plain OpenCV at that
    size (each scene's own baseline, not the last scene's looked up on every one)."""
    preset = json.loads(resource_path("presets", "quality.json").read_text())
    preset["name"] = "q300"
    preset["params"]["max_match_width"] = 300
    (tmp_path / "q300.json").write_text(json.dumps(preset))
    (tmp_path / "s.tsv").write_text(_scene(tmp_path, "narrow", 12)
                                    + _scene(tmp_path, "wide", 20, w=400, seed=1))
    assert main(["bench", "--scenes", str(tmp_path / "s.tsv"), "--preset",
                 str(tmp_path / "q300.json"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [s["baseline_of"]["q300"] for s in doc["scenes"]] == ["plain", "plain@q300"]
    assert doc["baseline_of"]["q300"] == "plain at q300's matching size"
    wide = doc["scenes"][1]["methods"]
    assert {"plain", "plain@q300", "q300"} <= set(wide)
    assert doc["verdict"]["q300"]["scenes"] == 2
    assert main(["bench", "--scenes", str(tmp_path / "s.tsv"), "--preset",
                 str(tmp_path / "q300.json")]) == 0
    assert "q300: within the margins of plain at q300's matching size" in capsys.readouterr().out


@pytest.mark.parametrize("extra, message", [
    (["--accuracy"], "no --accuracy"),
    (["--frames", "0"], "--frames"),
])
def test_scene_bench_refuses_what_it_cannot_do(tmp_path, capsys, extra, message):
    (tmp_path / "s.tsv").write_text(_scene(tmp_path, "a", 12))
    try:
        code = main(["bench", "--scenes", str(tmp_path / "s.tsv"), *extra])
    except SystemExit as exc:  # refused by the option parser
        code = exc.code
    assert code == 2
    assert message in capsys.readouterr().err


def test_a_missing_scene_list_is_one_clear_line(tmp_path, capsys):
    assert main(["bench", "--scenes", str(tmp_path / "nope.tsv")]) == 2
    err = capsys.readouterr().err
    assert "nope.tsv" in err and "Traceback" not in err


@pytest.mark.slow
def test_presets_hold_beside_plain_opencv_on_real_scenes(shared_data, tmp_path, capsys):
    """A regression check on scenes nobody tuned on (a slanted, smooth one with a lampshade, a
    2014 scene with a PFM truth): both presets within the margins of their baselines. On a room
    whose pale wall is too faint for the small windows, quality is within them too: its fill
    on a quarter of the full size brings it within the density margin (live is not, yet)."""
    lines = [line for line in (shared_data / "scenes.tsv").read_text().splitlines()
             if line.split("\t")[0] in ("Lampshade1", "Adirondack", "Midd1")]
    assert len(lines) == 3
    rows = []
    for line in lines:
        name, *paths, div = line.split("\t")
        rows.append("\t".join([name, *(str(shared_data / p) for p in paths), div]))
    (tmp_path / "three.tsv").write_text("\n".join(rows) + "\n")
    assert main(["bench", "--scenes", str(tmp_path / "three.tsv"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    for scene in doc["scenes"]:
        if scene["name"] == "Midd1":
            assert scene["within_margins"]["quality"], scene
            continue
        assert scene["within_margins"] == {"live": True, "quality": True}, scene
        q, plain = scene["methods"]["quality"], scene["methods"]["plain"]
        assert q["bad2"] < plain["bad2"], scene["name"]
