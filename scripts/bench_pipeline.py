#!/usr/bin/env python3
"""Benchmark and accuracy report of the pipeline presets (a script, not a test).

    python scripts/bench_pipeline.py                    # speed of live/seed/quality beside the report's loop
    python scripts/bench_pipeline.py --memory 3000      # + RSS over 3000 live frames (flat?)
    python scripts/bench_pipeline.py --accuracy         # + the whole-frame accuracy tables (bench --accuracy)
    python scripts/bench_pipeline.py --middlebury DIR   # + bad 2.0 and density per preset (DIR/teddy, DIR/tsukuba)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from stereo_gui.commands.bench import rss_mb
from stereo_gui.commands.bench import run as bench_run
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.files.presets import load_preset

PRESETS = ("seed", "live", "quality")


def memory(frames: int) -> None:
    from stereo_gui.sources.sim import Scene, SimRig

    rig = SimRig(seed=0)
    calib = rig.true_calibration()
    left, right = rig.render_scene(Scene.demo())
    with StereoPipeline(calib, load_preset("live")) as pipe:
        for _ in range(20):
            pipe.process(left, right)
        start = rss_mb()
        t0 = time.perf_counter()
        for i in range(1, frames + 1):
            pipe.process(left, right)
            if i % max(1, frames // 6) == 0:
                print(f"  frame {i:5d}: RSS {rss_mb():.1f} MiB")
        fps = frames / (time.perf_counter() - t0)
    print(f"memory: live, {frames} frames at {fps:.1f} fps, RSS {start:.1f} -> {rss_mb():.1f} MiB")


def middlebury(folder: Path) -> None:
    from stereo_gui.commands.accuracy import middlebury_scores

    print("middlebury: bad 2.0 = share of known pixels with a disparity that is off by > 2 px; "
          "density = known pixels with a disparity. Presets other than seed search the "
          "benchmark's range 0..N")
    for s in middlebury_scores(folder, PRESETS):
        print(f"  {s.pair:8s} {s.preset:8s} {s.stage:6s} bad {100 * s.bad:5.1f} %  "
              f"density {100 * s.density:5.1f} %")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--memory", type=int, default=0, metavar="N", help="live frames for the RSS check")
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--middlebury", type=Path, metavar="DIR")
    args = ap.parse_args()
    bench_run(argparse.Namespace(calib=None, left=None, right=None, frames=args.frames,
                                 preset=list(PRESETS), json=False, accuracy=False, size=None))
    if args.memory:
        memory(args.memory)
    if args.accuracy:
        bench_run(argparse.Namespace(calib=None, left=None, right=None, size=None, accuracy=True,
                                     preset=None, calibration="both", seed=None, json=False))
    if args.middlebury:
        middlebury(args.middlebury)
    return 0


if __name__ == "__main__":
    sys.exit(main())
