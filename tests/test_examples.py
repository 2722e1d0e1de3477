"""The example programs run as the guide says, and the Foxglove layout names our topics."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from stereo_gui.pipeline.stream import TOPICS
from stereo_gui.resources import resource_path

ROOT = Path(__file__).resolve().parent.parent


def test_the_robot_example_reads_the_simulated_wall():
    run = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_reader.py"),
                          "--frames", "2"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0].startswith("opened simulated rig")
    # the wall is at 1.5 m; which frames are read depends on the machine's load (newer frames
    # win), and a frame's noise may read 1.499 m: within its +-, not a string "1.5"
    import re

    readings = [re.search(r"centre \(320, 240\): ([0-9.]+) m \+- ([0-9.]+) mm", line)
                for line in lines]
    readings = [(float(m.group(1)), float(m.group(2))) for m in readings if m]
    assert len(readings) == 2, run.stdout
    assert all(abs(z - 1.5) * 1000 <= max(bound, 5.0) for z, bound in readings), run.stdout


def test_the_robot_example_says_what_is_wrong_in_one_line(tmp_path):
    run = subprocess.run([sys.executable, str(ROOT / "examples" / "robot_reader.py"),
                          "--calib", str(tmp_path / "none.yaml"), "--frames", "1"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert run.stderr.startswith("robot_reader: ") and len(run.stderr.strip().splitlines()) == 1


def _strings(node):
    if isinstance(node, dict):
        for v in node.values():
            yield from _strings(v)
        for k in node:
            yield k
    elif isinstance(node, list):
        for v in node:
            yield from _strings(v)
    elif isinstance(node, str):
        yield node


def test_the_foxglove_layout_shows_our_topics():
    layout = json.loads(resource_path("foxglove-layout.json").read_text())
    panels = set(layout["configById"])
    placed = {s for s in _strings(layout["layout"]) if "!" in s}
    assert placed == panels  # every panel configured is placed, and no other
    named = {s.split(".")[0] for s in _strings(layout["configById"]) if s.startswith("/")}
    assert named <= set(TOPICS.values())
    for key in ("depth", "left", "points", "region", "health", "readings"):
        assert TOPICS[key] in named, key
