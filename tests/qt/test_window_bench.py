"""`stereo-gui bench --window`: the real window timed on the simulated rig, offscreen without a
display, on settings of its own (the user's never touched); the options that do not go with it
are refused in one line before Qt starts."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import pytest

from stereo_gui.cli import main
from stereo_gui.commands.bench_window import WindowBenchResult
from stereo_gui.qt.preflight import offscreen_without_display
from stereo_gui.qt.window_bench import temporary_settings_dirs

NUMBERS = ("shown_fps", "processing_fps", "camera_fps", "cpu_percent", "latency_median_ms",
           "latency_p95_ms", "latency_intervals", "latency_p95_intervals")


@pytest.mark.slow
def test_bench_window_prints_the_rates_cpu_and_latency_as_json(tmp_path):
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    user = tmp_path / "user-config"  # the user's settings: read by nobody, left as they were
    user.mkdir()
    settings = user / "settings.json"
    settings.write_text(json.dumps({"preset": "quality", "visible_views": ["wls"]}))
    before = settings.read_bytes()
    env["STEREO_GUI_CONFIG_DIR"] = str(user)
    env["STEREO_GUI_DATA_DIR"] = str(tmp_path / "user-data")
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "bench", "--window", "2",
                           "--json"], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    for key in NUMBERS:
        assert isinstance(doc[key], float) and math.isfinite(doc[key]), key
    assert doc["shown_fps"] > 0 and doc["processing_fps"] > 0 and doc["camera_fps"] > 0
    assert doc["latency_median_ms"] > 0 and doc["latency_p95_ms"] >= doc["latency_median_ms"]
    assert doc["latency_intervals"] == pytest.approx(
        doc["latency_median_ms"] * doc["camera_fps"] / 1000.0)
    assert 0 <= doc["cpu_percent"] and doc["cores"] >= 1
    assert doc["frames_shown"] > 0 and isinstance(doc["frames_shown"], int)
    assert doc["seconds"] == pytest.approx(2.0, abs=0.5)
    assert doc["platform"] == "offscreen"  # no display: offscreen, set by the command itself
    assert doc["source"] == "sim" and doc["size"] == [640, 480] and doc["preset"] == "live"
    assert sorted(doc["views"]) == ["depth", "left"]
    assert doc["errors"] == []
    assert settings.read_bytes() == before and sorted(p.name for p in user.iterdir()) == [
        "settings.json"]
    assert not (tmp_path / "user-data").exists()


@pytest.mark.parametrize("args,message", [
    (["--scenes", "x.tsv"], "does not go with --scenes"),
    (["--clicks", "x.tsv"], "does not go with --clicks"),
    (["--accuracy"], "does not go with --accuracy"),
    (["--calib", "c.yaml", "l.png", "r.png"], "does not go with images"),
    (["--frames", "5"], "does not go with --frames"),
    (["--preset", "live", "--preset", "quality"], "give --preset once"),
    (["--preset", "nope"], "unknown preset"),
    (["--source", "."], "needs --calib FILE"),
    (["--source", ".", "--calib", "c.yaml", "--size", "320x240"], "plays at its own size"),
    (["--size", "10x10"], "between"),
])
def test_options_that_do_not_go_with_the_window_are_refused_in_one_line(capsys, args, message):
    assert main(["bench", "--window", "2", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_source_without_the_window_is_refused(capsys):
    assert main(["bench", "--source", "sim"]) == 2
    assert "--source goes with --window" in capsys.readouterr().err


def test_offscreen_only_without_a_display():
    env: dict[str, str] = {}
    assert offscreen_without_display(env) and env["QT_QPA_PLATFORM"] == "offscreen"
    for given in ({"DISPLAY": ":0"}, {"WAYLAND_DISPLAY": "wayland-0"},
                  {"QT_QPA_PLATFORM": "xcb"}):
        env = dict(given)
        assert not offscreen_without_display(env) and env == given


def test_the_settings_folders_are_temporary_and_put_back(monkeypatch, tmp_path):
    monkeypatch.setenv("STEREO_GUI_CONFIG_DIR", str(tmp_path / "mine"))
    monkeypatch.delenv("STEREO_GUI_DATA_DIR")
    with temporary_settings_dirs() as tmp:
        assert os.environ["STEREO_GUI_CONFIG_DIR"] == str(tmp / "config")
        assert os.environ["STEREO_GUI_DATA_DIR"] == str(tmp / "data")
        assert (tmp / "config").is_dir()
    assert not tmp.exists()
    assert os.environ["STEREO_GUI_CONFIG_DIR"] == str(tmp_path / "mine")
    assert "STEREO_GUI_DATA_DIR" not in os.environ


def _result(**changes):
    values = dict(shown_fps=29.84, processing_fps=30.0, camera_fps=30.0, cpu_percent=47.2,
                  cores=2, latency_median_ms=41.3, latency_p95_ms=58.0, latency_intervals=1.239,
                  latency_p95_intervals=1.74, frames_shown=149, frames_processed=150,
                  frames_read=150, seconds=5.0, warmup_s=2.0, source="sim", size=(640, 480),
                  preset="live", views=("depth", "left"), window_px=(1366, 736),
                  platform="offscreen", load_average=0.5, source_cpu_percent=21.4)
    values.update(changes)
    return WindowBenchResult(**values)


def test_the_line_and_the_json_say_the_same():
    r = _result()
    line = r.line()
    assert line.startswith("window bench: shown 29.8 fps, processing 30.0 fps, camera 30.0 fps, "
                           "CPU 47 % of 2 cores (the source's reads 21 %), latency 41 / 58 "
                           "ms (median / p95) = 1.24 / "
                           "1.74 frame intervals; sim 640x480, preset live, views depth+left")
    assert "\n" not in line
    doc = json.loads(json.dumps(r.to_dict()))
    assert doc["shown_fps"] == 29.84 and doc["size"] == [640, 480] and doc["errors"] == []
    assert doc["source_cpu_percent"] == 21.4
    none = _result(latency_median_ms=math.nan, latency_p95_ms=math.nan,
                   latency_intervals=math.nan, latency_p95_intervals=math.nan)
    assert "latency - / - ms" in none.line()
    assert none.to_dict()["latency_median_ms"] is None  # JSON has no NaN


def test_the_preset_asked_for_reaches_the_temporary_settings(monkeypatch, tmp_path):
    """A built-in by name, a file by its full path, the user's own preset copied over (the
    window reads presets from the temporary folder, not the user's)."""
    from stereo_gui.commands.bench_window import WindowBench
    from stereo_gui.files.presets import load_preset, save_user_preset, user_preset_dir
    from stereo_gui.qt.window_bench import _preset_setting

    monkeypatch.setenv("STEREO_GUI_CONFIG_DIR", str(tmp_path / "mine"))
    mine = load_preset("quality").replace(name="mine")
    save_user_preset(mine, "mine")
    file = tmp_path / "p.json"
    file.write_bytes((user_preset_dir() / "mine.json").read_bytes())

    def asked(name):
        return WindowBench(1.0, "sim", name, load_preset(name), (640, 480), None)

    request = asked("mine")  # (the options are checked before the folders change)
    with temporary_settings_dirs():
        assert _preset_setting(asked("live")) == "live"
        assert _preset_setting(asked(str(file))) == str(file.resolve())
        assert _preset_setting(request) == "mine"
        assert load_preset("mine") == mine  # read from the temporary folder


def test_the_bench_moves_through_its_phases_in_order_only():
    """Counting follows warming follows the first frame; any phase may end; nothing follows the
    end but the end (a late failure or signal)."""
    from stereo_gui.core.states import TransitionError
    from stereo_gui.qt.window_bench import BENCH_MOVES, BenchPhase

    order = [BenchPhase.STARTING, BenchPhase.WARMING, BenchPhase.COUNTING, BenchPhase.DONE]
    for a, b in zip(order, order[1:]):
        assert BENCH_MOVES.check(a, b) is b
    for a in order:
        assert BENCH_MOVES.allows(a, BenchPhase.DONE)
    for a, b in ((BenchPhase.STARTING, BenchPhase.COUNTING), (BenchPhase.COUNTING,
                                                            BenchPhase.WARMING),
                 (BenchPhase.DONE, BenchPhase.STARTING)):
        with pytest.raises(TransitionError):
            BENCH_MOVES.check(a, b)
