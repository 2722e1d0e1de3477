#!/usr/bin/env python3
"""Benchmark and accuracy report of the pipeline presets (a script, not a test).

    python scripts/bench_pipeline.py                    # speed of live/seed/quality (stereo-gui bench)
    python scripts/bench_pipeline.py --memory 3000      # + RSS over 3000 live frames (flat?)
    python scripts/bench_pipeline.py --accuracy         # + walls at 0.5..3 m on the simulated rig
    python scripts/bench_pipeline.py --middlebury DIR   # + bad 2.0 per preset (DIR/teddy, DIR/tsukuba)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.commands.bench import rss_mb, run as bench_run
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.measure import measure_point
from stereo_gui.core.stereo_calibration import StereoCalibration
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


def accuracy() -> None:
    from stereo_gui.sources.sim import Scene, SimRig

    rig = SimRig(seed=7)
    calib = rig.true_calibration()
    points = ((320, 240), (200, 150), (450, 330), (560, 420))
    print("accuracy: wall distance, preset, worst |error| over 4 points (refined; matcher's own "
          "subpixel estimate in brackets)")
    for z in (500.0, 1000.0, 1500.0, 2000.0, 3000.0):
        scene = Scene.wall(z, seed=int(z))
        left, right = rig.render_scene(scene, np.random.default_rng(int(z)))
        cells = []
        for name in PRESETS:
            result = StereoPipeline(calib, load_preset(name)).process(left, right)
            errs, raw_errs, bad = [], [], []
            for x, y in points:
                true = rig.true_point_rectified(calib, scene, x, y)[2]
                m = measure_point(result, x, y)
                if not m.valid:
                    bad.append(m.reason)
                    continue
                errs.append(abs(m.Z_mm - true) / true)
                fb = calib.focal_px * calib.rectified_baseline_mm
                raw_errs.append(abs(fb / m.raw_disparity_px - true) / true)
            cell = (f"{name} {100 * max(errs):.2f}% [{100 * max(raw_errs):.2f}%]" if errs else name)
            if bad:
                cell += f" ({len(bad)} invalid: {', '.join(sorted(set(bad)))})"
            cells.append(cell)
        print(f"  {z / 1000:.1f} m: " + " | ".join(cells))


def middlebury(folder: Path) -> None:
    sets = {"teddy": ("im2.png", "im6.png", "disp2.png", 4.0, 64),
            "tsukuba": ("im3.png", "im4.png", "disp3.pgm", 16.0, 32)}
    print("middlebury bad 2.0 (share of known pixels with a valid final disparity off by > 2 px; "
          "coverage = known pixels with a valid disparity). Presets other than seed use the "
          "benchmark's disparity range 0..num")
    for name in PRESETS:
        cells = []
        for key, (a, b, g, div, num) in sets.items():
            left, right = cv2.imread(str(folder / key / a)), cv2.imread(str(folder / key / b))
            if left is None:
                continue
            truth = cv2.imread(str(folder / key / g), cv2.IMREAD_GRAYSCALE).astype(np.float32) / div
            p = load_preset(name)
            if name != "seed":
                p = p.replace(z_min_mm=None, min_disparity=0, num_disparities=num)
            calib = StereoCalibration.identity((left.shape[1], left.shape[0]), 500.0, 100.0)
            r = StereoPipeline(calib, p).process(left, right)
            known = truth > 0
            for label, m in (("raw", r.disparity_px), ("final", r.final_px)):
                ok = known & np.isfinite(m)
                bad = float((np.abs(m - truth)[ok] > 2.0).mean())
                cells.append(f"{key} {label} {100 * bad:.1f}% (cov {100 * ok.sum() / known.sum():.0f}%)")
        print(f"  {name:>8}: " + " | ".join(cells))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--memory", type=int, default=0, metavar="N", help="live frames for the RSS check")
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--middlebury", type=Path, metavar="DIR")
    args = ap.parse_args()
    bench_run(argparse.Namespace(calib=None, left=None, right=None, frames=args.frames,
                                 preset=list(PRESETS), json=False))
    if args.memory:
        memory(args.memory)
    if args.accuracy:
        accuracy()
    if args.middlebury:
        middlebury(args.middlebury)
    return 0


if __name__ == "__main__":
    sys.exit(main())
