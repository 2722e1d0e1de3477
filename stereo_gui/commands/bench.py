"""`stereo-gui bench`: frames per second and per-stage milliseconds of the pipeline per preset.

Runs on a given raw pair (--calib C LEFT RIGHT) or on the simulated rig's demo scene, the same
pair over and over (what is measured is processing, not the source). `live` and `seed` always
run, so their speed ratio is measured in the same run. Resident memory is reported at the start
and end of each preset's run (it should stay flat).
"""

from __future__ import annotations

import argparse
import json
import os
import time

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline


def rss_mb() -> float:
    """Current resident set size of this process, MiB (Linux /proc; NaN elsewhere)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return float("nan")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--calib", metavar="C", help="calibration (with LEFT RIGHT): a file "
                        "of ours, OpenCV's, ROS's or Middlebury's, or rectified:F,B[,DOFFS] for "
                        "an already rectified pair (focal px, baseline mm, cx_right - cx_left px)")
    parser.add_argument("left", nargs="?", metavar="LEFT",
                        help="left raw image (without LEFT RIGHT: the simulated rig)")
    parser.add_argument("right", nargs="?", metavar="RIGHT", help="right raw image")
    parser.add_argument("--frames", type=int, default=30, metavar="N",
                        help="frames per preset (default 30)")
    parser.add_argument("--preset", action="append", metavar="P",
                        help="preset to time (repeatable; default live, seed, quality)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")


def _input(args):
    if args.calib or args.left or args.right:
        if not (args.calib and args.left and args.right):
            raise InputError("bench needs --calib C together with LEFT and RIGHT (or none of them "
                             "for the simulated rig)")
        from stereo_gui.commands.disparity import load_calibration, read_pair

        calib = load_calibration(args.calib, args.left)
        left, right = read_pair(args.left, args.right, calib)
        return "files", calib, left, right
    from stereo_gui.sources.sim import Scene, SimRig

    rig = SimRig(seed=0)
    calib = rig.true_calibration(alpha=0.0)
    left, right = rig.render_scene(Scene.demo())
    return "simulated rig, demo scene", calib, left, right


def bench_preset(calib, params, left, right, frames: int, warmup: int = 2) -> dict:
    """Time `frames` frames of one preset; returns fps, mean ms per stage and RSS."""
    with StereoPipeline(calib, params) as pipe:
        for _ in range(warmup):
            pipe.process(left, right)
        rss0 = rss_mb()
        sums: dict[str, float] = {}
        cpu0 = time.process_time()
        t0 = time.perf_counter()
        for _ in range(frames):
            r = pipe.process(left, right)
            for k, v in r.timings_ms.items():
                sums[k] = sums.get(k, 0.0) + v
        elapsed = time.perf_counter() - t0
        cpu = time.process_time() - cpu0
        rss1 = rss_mb()
    return {
        "fps": frames / elapsed if elapsed > 0 else float("inf"),
        "ms_per_frame": 1000.0 * elapsed / frames,
        "stages_ms": {k: v / frames for k, v in sums.items()},
        # CPU time of all threads per frame: what the frame costs, whatever else the machine runs
        "cpu_ms_per_frame": 1000.0 * cpu / frames,
        "rss_start_mb": rss0,
        "rss_end_mb": rss1,
        "valid_fraction": float(r.valid.mean()),
    }


def run_bench(args) -> dict:
    from stereo_gui.files.presets import load_preset

    if args.frames < 1:
        raise InputError(f"--frames must be at least 1, not {args.frames}")
    names = list(dict.fromkeys(args.preset or ["live", "seed", "quality"]))
    params = {n: load_preset(n) for n in names}  # unknown names fail before any work
    for n in ("live", "seed"):
        if n not in params:
            params[n] = load_preset(n)
    source, calib, left, right = _input(args)
    out = {"source": source, "size": list(calib.image_size), "frames": args.frames,
           "cv_threads": None, "presets": {}}
    import cv2

    out["cv_threads"] = cv2.getNumThreads()
    for name, p in params.items():
        out["presets"][name] = bench_preset(calib, p, left, right, args.frames)
    out["live_over_seed"] = out["presets"]["live"]["fps"] / out["presets"]["seed"]["fps"]
    return out


def run(args) -> int:
    res = run_bench(args)
    if args.json:
        print(json.dumps(res, indent=2))
        return 0
    w, h = res["size"]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{res['source']}, {w}x{h}, {res['frames']} frames per preset, "
          f"OpenCV threads {res['cv_threads']}, load average {load:.1f} on {os.cpu_count()} CPUs")
    for name, r in res["presets"].items():
        stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages_ms"].items() if k != "total")
        print(f"{name:>10}: {r['fps']:6.1f} fps ({r['ms_per_frame']:.1f} ms/frame, CPU "
              f"{r['cpu_ms_per_frame']:.1f} ms/frame; {stages} ms); "
              f"RSS {r['rss_start_mb']:.0f} -> {r['rss_end_mb']:.0f} MiB")
    print(f"live is {res['live_over_seed']:.1f}x as fast as seed")
    return 0
