"""`stereo-gui bench --clicks`: the double-click judged on scenes with truth, beside plain
OpenCV's patch median."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from cli_output import one_line

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"


def _write_pfm(path, image):
    h, w = image.shape
    with open(path, "wb") as fh:
        fh.write(f"Pf\n{w} {h}\n-1.0\n".encode())
        fh.write(np.ascontiguousarray(image[::-1], "<f4").tobytes())


def _scene(folder, name, shift, w=320, h=160, seed=0):
    """A textured plane `shift` px apart in the two images, its truth as a PFM (inf unknown in
    the first `shift` columns, which the right image does not hold)."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.integers(0, 256, (h, w + shift, 3), np.uint8), (3, 3), 0)
    cv2.imwrite(str(folder / f"{name}-l.png"), np.ascontiguousarray(big[:, :w]))
    cv2.imwrite(str(folder / f"{name}-r.png"), np.ascontiguousarray(big[:, shift:]))
    truth = np.full((h, w), float(shift), np.float32)
    truth[:, :shift] = np.inf
    _write_pfm(folder / f"{name}.pfm", truth)
    return truth


def _two_scenes_clicked(tmp_path, capsys, a_line, b_line):
    """Two textured planes (16 and 24 px) listed with these lines, clicked with quality: the
    JSON."""
    _scene(tmp_path, "a", 16)
    _scene(tmp_path, "b", 24, seed=1)
    (tmp_path / "c.tsv").write_text(
        f"# name\tleft\tright\ttruth\tdiv\tcalib\n{a_line}\n{b_line}\n")
    assert main(["bench", "--clicks", str(tmp_path / "c.tsv"), "--preset", "quality",
                 "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_click_bench_reads_a_plain_scene_right_beside_plain_opencv(tmp_path, capsys):
    doc = _two_scenes_clicked(tmp_path, capsys, "a\ta-l.png\ta-r.png\ta.pfm\t1\trectified:800,120",
                              "b\tb-l.png\tb-r.png\tb.pfm\t1")
    assert [s["name"] for s in doc["scenes"]] == ["a", "b"]
    assert doc["scenes"][0]["calibration"] == "rectified:800,120"
    assert doc["scenes"][1]["calibration"].startswith("assumed")
    for scene in doc["scenes"]:
        assert scene["truth_step_px"] == 0.0  # one value throughout: no step to be seen
        assert scene["points"] > 60  # most of the 11x8 grid: all but the columns unseen
        for method in ("quality", "plain"):
            s = scene["methods"][method]
            assert s["points"] == scene["points"]
            assert s["read"] > 0.9 and s["within_2pct"] > 0.9 and s["worst"] < 0.02
    assert doc["total"]["quality"]["covers"] > 0.9
    assert doc["total"]["quality"]["covers_within_5pct"] >= doc["total"]["quality"]["covers"]
    # the sums over the scenes whose errors are of a real Z: those with a calibration of their own
    own = doc["own_calibration"]
    assert own["plain"]["points"] == doc["scenes"][0]["points"]
    assert doc["total"]["plain"]["points"] == sum(s["points"] for s in doc["scenes"])
    assert main(["bench", "--clicks", str(tmp_path / "c.tsv"), "--preset", "quality"]) == 0
    text = capsys.readouterr().out
    assert "quality:" in text and "plain:" in text and "+- covers" in text
    assert "% of the readings within 5 %)" in text
    assert "assumed calibration" in text and "b" in text.splitlines()[-1]
    assert "the scenes with a calibration of their own:" in text


def test_click_bench_refuses_what_it_cannot_do(tmp_path, capsys):
    _scene(tmp_path, "a", 16)
    (tmp_path / "c.tsv").write_text("a\ta-l.png\ta-r.png\ta.pfm\t1\trectified:800,120,-3\n")
    code = main(["bench", "--clicks", str(tmp_path / "c.tsv"), "--accuracy"])
    one_line(capsys.readouterr().err, code, "--clicks")
    code = main(["bench", "--clicks", str(tmp_path / "nope.tsv")])
    one_line(capsys.readouterr().err, code, "nope.tsv")
    (tmp_path / "d.tsv").write_text("a\ta-l.png\ta-r.png\ta.pfm\t1\tmissing.txt\n")
    code = main(["bench", "--clicks", str(tmp_path / "d.tsv")])
    one_line(capsys.readouterr().err, code, "missing.txt")


@pytest.mark.skipif(not (SHARED / "middlebury2014" / "Adirondack" / "calib.txt").is_file(),
                    reason="the shared Middlebury 2014 scenes are not here")
def test_a_middlebury_scene_is_clicked_through_its_own_calibration_and_mask(tmp_path, capsys):
    root = SHARED / "middlebury2014" / "Adirondack"
    (tmp_path / "m.tsv").write_text(
        f"Adirondack\t{root / 'im0.png'}\t{root / 'im1.png'}\t{root / 'disp0GT.pfm'}\t1\n")
    assert main(["bench", "--clicks", str(tmp_path / "m.tsv"), "--preset", "live",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    scene = doc["scenes"][0]
    assert scene["calibration"].endswith("calib.txt") and 50 <= scene["points"] <= 88
    assert scene["methods"]["plain"]["within_2pct"] > 0.8


def test_the_rigs_click_scenes_are_summed_per_seed_with_the_worst_seed(tmp_path, capsys):
    """Scenes named as `simulate --click-scenes` names them (s<seed>-...) are summed per seed:
    the mean over the seeds and the worst seed, which a threshold is judged by."""
    doc = _two_scenes_clicked(
        tmp_path, capsys, "s7-rig-wall1m\ta-l.png\ta-r.png\ta.pfm\t1\trectified:800,120",
        "s9-rig-wall1m\tb-l.png\tb-r.png\tb.pfm\t1\trectified:800,120")
    over = doc["over_seeds"]
    assert over["seeds"] == [7, 9] and set(over["methods"]) == {"quality", "plain"}
    per = {s["name"]: s["methods"]["quality"] for s in doc["scenes"]}
    read = over["methods"]["quality"]["read"]
    assert read["mean"] == pytest.approx((per["s7-rig-wall1m"]["read"]
                                          + per["s9-rig-wall1m"]["read"]) / 2)
    worst_seed = 7 if per["s7-rig-wall1m"]["read"] <= per["s9-rig-wall1m"]["read"] else 9
    assert read["worst_seed"] == worst_seed
    assert over["methods"]["plain"]["covers"]["mean"] is None  # plain prints no +-
    assert main(["bench", "--clicks", str(tmp_path / "c.tsv"), "--preset", "quality"]) == 0
    text = capsys.readouterr().out
    assert "over 2 seeds (7-9): mean / worst seed (which)" in text
    # a list of other scenes has no such rows
    (tmp_path / "d.tsv").write_text("a\ta-l.png\ta-r.png\ta.pfm\t1\trectified:800,120\n")
    assert main(["bench", "--clicks", str(tmp_path / "d.tsv"), "--preset", "quality",
                 "--json"]) == 0
    assert "over_seeds" not in json.loads(capsys.readouterr().out)


def test_over_seeds_takes_the_lowest_shares_and_the_highest_error_as_the_worst_seed():
    from stereo_gui.commands.clicks import over_seeds
    per_seed = {
        1: {"live": {"read": 0.9, "within_2pct": 0.8, "covers": 0.97, "worst": 0.02,
                     "covers_within_5pct": 0.98}},
        2: {"live": {"read": 0.8, "within_2pct": 0.85, "covers": 0.99, "worst": 0.50,
                     "covers_within_5pct": 0.94}},
        3: {"live": {"read": 0.95, "within_2pct": 0.9, "covers": 0.91, "worst": 0.01,
                     "covers_within_5pct": 0.96}}}
    row = over_seeds(per_seed)["methods"]["live"]
    assert row["read"] == {"mean": pytest.approx(2.65 / 3), "worst": 0.8, "worst_seed": 2}
    assert row["within_2pct"]["worst_seed"] == 1
    assert row["covers"] == {"mean": pytest.approx(0.9566667), "worst": 0.91, "worst_seed": 3}
    assert row["covers_within_5pct"] == {"mean": pytest.approx(0.96), "worst": 0.94,
                                         "worst_seed": 2}
    assert row["worst"] == {"mean": pytest.approx(0.53 / 3), "worst": 0.50, "worst_seed": 2}


def test_plain_opencv_is_judged_by_a_stepped_truths_span_as_the_presets_are():
    """A truth stored in whole pixels: plain's patch median of 4.7 px where the truth says 5 px
    lies inside the step's span (4.5..5.5 px), no error, as a preset's reading there is."""
    from stereo_gui.commands.clicks import click_plain
    from stereo_gui.core.click_score import true_z_mm, true_z_span_mm
    from stereo_gui.core.stereo_calibration import StereoCalibration

    calib = StereoCalibration.identity((40, 20), 1000.0, 100.0)
    z = true_z_mm(calib, 20, 10, 5.0)
    stepped = [(20, 10, 5.0, z, true_z_span_mm(calib, 20, 10, 5.0, 1.0))]
    exact = [(20, 10, 5.0, z, None)]
    disparity = np.full((20, 40), 4.7, np.float32)
    assert click_plain(disparity, calib, stepped)[0].error_share == 0.0
    assert click_plain(disparity, calib, exact)[0].error_share == pytest.approx(5.0 / 4.7 - 1.0)
