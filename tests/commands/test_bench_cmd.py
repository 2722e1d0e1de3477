"""`stereo-gui bench`: numbers for every preset asked plus live and seed (no timing assertions)."""

import json

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.calibration_file import save_calibration


@pytest.fixture()
def files(tmp_path):
    rng = np.random.default_rng(1)
    img = cv2.GaussianBlur(rng.integers(0, 255, (96, 320, 3), np.uint8), (3, 3), 0)
    cv2.imwrite(str(tmp_path / "l.png"), img)
    cv2.imwrite(str(tmp_path / "r.png"), np.roll(img, -6, axis=1))
    save_calibration(StereoCalibration.identity((320, 96), 200.0, 100.0), tmp_path / "c.yaml")
    return tmp_path


def test_bench_times_the_preset_beside_the_reference_loop(files, capsys):
    assert main(["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"),
                 str(files / "r.png"), "--frames", "2", "--preset", "quality", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["presets"]) == {"quality"}  # only what was asked, beside the reference
    r = doc["presets"]["quality"]
    assert r["fps"] > 0 and r["stages_ms"]["total"] > 0
    assert {"rectify", "match", "colormap", "display"} <= set(r["stages_ms"])
    assert r["rss_end_mb"] > 0
    ref = doc["report"]
    assert doc["references"] == ["report", "plain"]
    assert ref["fps"] > 0 and len(ref["fps_runs"]) == 2
    assert doc["over_report"]["quality"] == pytest.approx(r["fps"] / ref["fps"])
    plain = doc["plain"]  # the plain OpenCV program, in the same run
    assert plain["fps"] > 0 and len(plain["fps_runs"]) == 2 and plain["valid_fraction"] > 0.5
    assert doc["over_plain"]["quality"] == pytest.approx(r["fps"] / plain["fps"])
    assert doc["size"] == [320, 96] and doc["frames"] == 2


def test_the_plain_program_measures_what_it_should(files, capsys):
    """The plain reference is a working stereo program, not a stand-in: on a pair shifted by
    6 px it finds 6 px (in full-size px) nearly everywhere; --reference picks one reference."""
    from stereo_gui.core.plain_loop import PlainLoop
    from stereo_gui.files.calibration_file import load_calibration

    loop = PlainLoop(load_calibration(files / "c.yaml"))
    out = loop.process(cv2.imread(str(files / "l.png")), cv2.imread(str(files / "r.png")))
    # (the left 64 columns of the halved images are outside the filter's region of interest)
    d = out.disparity_px[:, 70:-4]
    assert np.isfinite(d).mean() > 0.9
    assert np.nanmedian(d) == pytest.approx(6.0, abs=0.25)
    assert out.color.shape == (48, 160, 3)
    assert main(["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"),
                 str(files / "r.png"), "--frames", "1", "--reference", "plain"]) == 0
    text = capsys.readouterr().out
    assert "plain OpenCV program" in text and "x the plain" in text and "reference loop" not in text


def test_bench_runs_a_parallel_preset_in_the_frame_lanes_and_restores_opencv(files, capsys):
    """As the Live tab runs it: `lanes` frames at once, OpenCV with the application's threads;
    the reference loop (and whatever runs next) keeps the thread count found."""
    import cv2

    from stereo_gui.files.presets import load_preset
    from stereo_gui.pipeline.concurrency import opencv_threads_beside_lanes
    from stereo_gui.pipeline.live import frame_lanes

    before = cv2.getNumThreads()
    assert main(["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"),
                 str(files / "r.png"), "--frames", "3", "--preset", "live", "--preset", "seed",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["presets"]["live"]["lanes"] == frame_lanes(load_preset("live"))
    assert doc["presets"]["seed"]["lanes"] == 1  # not a parallel preset
    assert doc["cv_threads"] == before
    assert doc["cv_threads_presets"] == opencv_threads_beside_lanes()
    assert cv2.getNumThreads() == before


@pytest.mark.slow
def test_bench_on_the_simulated_rig_prints_a_table(capsys):
    assert main(["bench", "--frames", "1"]) == 0
    out = capsys.readouterr().out
    assert "simulated rig" in out and "live" in out and "the reference loop" in out
    assert "seed" not in out and "quality" not in out  # --preset live is the default alone


def test_bench_at_another_rig_size(capsys):
    assert main(["bench", "--frames", "1", "--size", "320x240", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["size"] == [320, 240]


@pytest.mark.slow
def test_bench_accuracy_prints_the_whole_frame_tables(capsys):
    assert main(["bench", "--accuracy", "--calibration", "true", "--preset", "live",
                 "--seed", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    rows = doc["calibrations"]["true"]
    # the reference loop (named "report") and plain OpenCV beside the preset asked for
    assert {r["preset"] for r in rows} == {"report", "plain", "live"}
    assert {r["wall_mm"] for r in rows} == {500.0, 1000.0, 2000.0, 3000.0}
    assert {r["condition"] for r in rows} == {"rig"}  # the rig's usual texture by default
    live = [r for r in rows if r["preset"] == "live"]
    assert all(r["points"] == 63 and 0 < r["seen"] <= 63 for r in live)
    assert all(r["coverage"] > 0.95 and r["worst_pct"] < 1.5 for r in live)
    totals = {(t["condition"], t["preset"]): t for t in doc["totals"]["true"]}
    assert totals[("rig", "live")]["coverage"] > 0.95


@pytest.mark.slow
def test_bench_accuracy_renders_the_conditions_asked_for(capsys):
    assert main(["bench", "--accuracy", "--calibration", "true", "--preset", "live",
                 "--condition", "weak", "--condition", "webcams", "--seed", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["conditions"]) == {"weak", "webcams"}
    assert {r["condition"] for r in doc["calibrations"]["true"]} == {"weak", "webcams"}
    assert {(t["condition"], t["preset"]) for t in doc["totals"]["true"]} == {
        (c, p) for c in ("weak", "webcams") for p in ("report", "plain", "live")}


def test_accuracy_over_seeds_gives_the_mean_and_the_worst_seed():
    """The worst seed is the lowest reading share and +- coverage, the highest errors; a figure
    no seed has (the reference loop has no +-) has no worst seed."""
    from stereo_gui.commands.bench import accuracy_over_seeds

    nan = float("nan")

    def t(cov, worst, rms, covered):
        return {("webcams", "live"): {"coverage": cov, "worst_pct": worst, "rms_pct": rms,
                                      "covered_fraction": covered, "median_bound_pct": 0.5},
                ("webcams", "report"): {"coverage": 0.9, "worst_pct": 50.0, "rms_pct": 9.0,
                                        "covered_fraction": nan, "median_bound_pct": nan}}

    over = accuracy_over_seeds({11: t(0.95, 1.0, 0.2, 0.99), 12: t(0.83, 2.2, 0.45, 0.97),
                                13: t(0.91, 0.8, 0.5, 0.96)})
    live = over[("webcams", "live")]
    assert live["coverage"] == {"mean": pytest.approx(0.8966666), "worst": 0.83, "worst_seed": 12}
    assert live["worst_pct"]["worst"] == 2.2 and live["worst_pct"]["worst_seed"] == 12
    assert live["rms_pct"]["worst_seed"] == 13 and live["covered_fraction"]["worst_seed"] == 13
    assert over[("webcams", "report")]["covered_fraction"]["worst_seed"] is None


@pytest.mark.slow
def test_bench_accuracy_over_seeds(capsys):
    assert main(["bench", "--accuracy", "--calibration", "true", "--preset", "live",
                 "--condition", "weak", "--seed", "5", "--seeds", "2", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["seeds"] == [5, 6] and set(doc["per_seed"]["true"]) == {"5", "6"}
    rows = {(r["condition"], r["preset"]): r for r in doc["over_seeds"]["true"]}
    live = rows[("weak", "live")]
    per = [next(r for r in doc["per_seed"]["true"][s] if r["preset"] == "live")
           for s in ("5", "6")]
    assert live["coverage"]["worst"] == min(r["coverage"] for r in per)
    assert live["worst_pct"]["worst"] == max(r["worst_pct"] for r in per)


@pytest.mark.parametrize("args,message", [
    (["--calib", "c.yaml"], "together with LEFT and RIGHT"),
    (["--frames", "0"], "--frames"),
    (["--rounds", "0"], "--rounds"),
    (["--preset", "nope"], "unknown preset"),
    (["--size", "big"], "WxH"),
    (["--size", "10x10"], "between"),
    (["--accuracy", "--calib", "c.yaml"], "simulated rig"),
    (["--accuracy", "--condition", "foggy"], "unknown condition"),
])
def test_bench_bad_input(files, capsys, args, message):
    args = [a if a != "c.yaml" else str(files / a) for a in args]
    try:
        code = main(["bench", *args])
    except SystemExit as exc:  # refused by the option parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_images_too_narrow_for_the_range_are_an_input_error(files, capsys):
    small = cv2.imread(str(files / "l.png"))[:, :120]
    cv2.imwrite(str(files / "s.png"), small)
    save_calibration(StereoCalibration.identity((120, 96), 200.0, 100.0), files / "s.yaml")
    assert main(["bench", "--calib", str(files / "s.yaml"), str(files / "s.png"),
                 str(files / "s.png"), "--frames", "1", "--preset", "seed"]) == 2
    assert "too narrow" in capsys.readouterr().err


def test_bench_in_rounds_gives_each_rounds_ratio_and_the_median(files, capsys):
    """--rounds interleaves the reference loop (an eighth of the frames, at least 2) with the
    presets; each round's ratio is against the loop's runs on either side of it."""
    import statistics

    assert main(["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"),
                 str(files / "r.png"), "--frames", "4", "--rounds", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["rounds"] == 3 and doc["report_frames"] == 2
    refs = doc["report"]["fps_runs"]
    assert len(refs) == 4  # before, between and after the rounds
    live = doc["presets"]["live"]
    assert len(live["fps_runs"]) == 3
    assert live["fps"] == pytest.approx(3 / sum(1 / f for f in live["fps_runs"]))
    ratios = doc["rounds_over_report"]["live"]
    for i, (fps, ratio) in enumerate(zip(live["fps_runs"], ratios)):
        assert ratio == pytest.approx(fps * (1 / refs[i] + 1 / refs[i + 1]) / 2)
    assert doc["median_over_report"]["live"] == pytest.approx(statistics.median(ratios))
    assert main(["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"),
                 str(files / "r.png"), "--frames", "2", "--rounds", "2"]) == 0
    out = capsys.readouterr().out
    assert "in 2 rounds" in out and "median" in out


def test_a_preset_with_its_own_opencv_threads_has_them_in_every_round(files, tmp_path, capsys,
                                                                     monkeypatch):
    """A preset's `cv_threads` holds for each of its runs, not only its first (the runs start
    from the lanes' count); the line says so."""
    from stereo_gui.files.presets import load_preset, save_user_preset
    from stereo_gui.pipeline.concurrency import opencv_threads_beside_lanes

    monkeypatch.setenv("STEREO_GUI_CONFIG_DIR", str(tmp_path / "config"))
    own = opencv_threads_beside_lanes() + 1
    path = save_user_preset(load_preset("live").replace(parallel=False, cv_threads=own),
                            "own-threads")
    args = ["bench", "--calib", str(files / "c.yaml"), str(files / "l.png"), str(files / "r.png"),
            "--frames", "2", "--rounds", "3", "--reference", "plain", "--preset", "live",
            "--preset", str(path)]
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["presets"]["own-threads"]["cv_threads_runs"] == [own] * 3
    assert doc["presets"]["live"]["cv_threads_runs"] == [opencv_threads_beside_lanes()] * 3
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any("own-threads: " in ln and f"OpenCV threads {own}:" in ln for ln in lines)
    assert not any(ln.strip().startswith("live:") and "OpenCV threads" in ln for ln in lines)
