"""`stereo-gui bench`: the speed of a preset side by side with the reference loop, or
(`--accuracy`) the accuracy of the presets over the whole frame on the simulated rig.

Speed runs on a given raw pair (--calib C LEFT RIGHT) or on the simulated rig's demo scene, the
same pair over and over (what is measured is processing, not the source). Each preset is timed
end to end as the Live tab runs it (rectify, match, filter, colour map, and the conversion of
every view for display), as many frames at once as its lanes, OpenCV with the threads the
application gives it. The reference is the reference loop (`--reference report`: the live loop
of the program of the report the project grew from, its own code, core.reference_loop), as it
runs: one frame after the other, OpenCV's thread count left as it was. It is timed in the
same run, so the ratio holds whatever else the machine is doing. Resident memory is reported
at the start and end of each run (it should stay flat).

On a shared machine the speed moves with the host's load within seconds, and the presets (two
cores) feel it more than the reference loop (one). `--rounds R` interleaves them in short turns,
the reference loop on an eighth of the frames before, between and after the presets' runs, and
gives each round's ratio against the reference loop's runs on either side of it, with the
median.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import cv2
import numpy as np

from stereo_gui.commands import options
from stereo_gui.commands.accuracy import (
    BENCH_SEED,
    PLAIN,
    condition_totals,
    format_table,
    run_accuracy,
)
from stereo_gui.commands.clicks import format_clicks, run_clicks
from stereo_gui.commands.disparity import load_calibration, read_pair
from stereo_gui.commands.scenes import format_scenes, over_seeds_figure, run_scenes
from stereo_gui.core import plain_loop, reference_loop
from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.presets import load_presets
from stereo_gui.pipeline.concurrency import (
    opencv_threads_beside_lanes,
    opencv_threads_for_lanes,
    use_preset_threads,
)
from stereo_gui.pipeline.live import DEFAULT_VIEWS, LiveProcessor
from stereo_gui.sources.base import StereoFrame
from stereo_gui.sources.sim import RigConfig, Scene, SimRig
from stereo_gui.sources.sim.conditions import CONDITIONS

MAX_FRAMES = 10_000  # a preset at 2 frames per second: over an hour

# the reference loop (named "report" on the command line and in JSON, as scripts know it); a
# plain OpenCV program set up with care
REFERENCES = ("report", "plain")

# one timed call: (each stage's time in ms, or None; the share of valid pixels)
Step = Callable[[], tuple[dict[str, float] | None, float]]


def rss_mb() -> float:
    """Current resident set size of this process, MiB (Linux /proc; NaN elsewhere)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return float("nan")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--calib", metavar="C", help="calibration (with LEFT RIGHT, or the "
                        "window's with --window): a file of ours, OpenCV's, ROS's or "
                        "Middlebury's, or rectified:F,B[,DOFFS] for an already rectified pair "
                        "(focal px, baseline mm, cx_right - cx_left px)")
    parser.add_argument("left", nargs="?", metavar="LEFT",
                        help="left raw image (without LEFT RIGHT: the simulated rig)")
    parser.add_argument("right", nargs="?", metavar="RIGHT", help="right raw image")
    parser.add_argument("--frames", type=options.whole(1, MAX_FRAMES), default=None, metavar="N",
                        help="frames per preset (default 30; with --scenes: frames timed per "
                        "scene and method, default 1)")
    parser.add_argument("--preset", action="append", metavar="P",
                        help="preset to time beside the reference loop (repeatable; default live)")
    parser.add_argument("--reference", choices=(*REFERENCES, "both"), default="both",
                        help="what the presets' speed is put beside: report, the reference loop "
                        "(the program of the report the project grew from), plain, a plain "
                        "OpenCV program set up with care (half-size 3-way SGBM of 64 disparities, "
                        "its right matcher and WLS; core.plain_loop), or both (default)")
    parser.add_argument("--rounds", type=options.whole(1, 1000), default=1, metavar="R",
                        help="interleave R rounds: the reference loop on N/8 frames (at least 2) "
                        "between the presets' runs of N frames; each round's ratio and the median "
                        "(default 1: the reference loop on N frames before and after)")
    parser.add_argument("--size", metavar="WxH",
                        help="simulated rig's frame size (default 640x480; without LEFT RIGHT)")
    _add_accuracy_arguments(parser)
    parser.add_argument("--scenes", metavar="FILE",
                        help="instead of speed: the presets' final maps beside plain OpenCV SGBM "
                        "on every scene of FILE (tab-separated: name, left, right, ground truth, "
                        "divide by; e.g. shared/data/scenes.tsv): bad-1/2/4, density, median "
                        "error and time per frame (default presets live and quality)")
    parser.add_argument("--clicks", metavar="FILE",
                        help="instead of speed: the double-click of the presets beside plain "
                        "OpenCV's patch median on an 11x8 grid of every scene of FILE (the "
                        "--scenes format, a metric calibration per scene or a calib.txt beside "
                        "its images): read, right within 1 and 2 %%, worst error, how often the "
                        "+- covers the truth, and why clicks were refused (default presets live "
                        "and quality)")
    parser.add_argument("--window", type=options.number(0.5, 3600.0, "s"), default=None,
                        metavar="SECONDS",
                        help="instead of the pipeline alone: the application's window (offscreen "
                        "without a display) on the simulated rig with its true calibration, the "
                        "Live tab showing the Depth and Left views; after a 2 s warm-up, SECONDS "
                        "counted: frames shown, processed and read per second, the process's "
                        "CPU share of all cores, the latency from the source's delivery to the "
                        "views (median, 95th percentile, in frame intervals). With --preset "
                        "(one), --size, --source, --calib; settings go to a temporary folder")
    parser.add_argument("--source", metavar="SPEC",
                        help="with --window: the source as the window's --source takes it "
                        "(default sim): e.g. a recording's folder, with --calib FILE")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")


def _add_accuracy_arguments(parser: argparse.ArgumentParser) -> None:
    """--accuracy and its options."""
    parser.add_argument("--accuracy", action="store_true",
                        help="instead of speed: accuracy of the presets over a 9x7 grid of the "
                        "whole frame on simulated walls at 0.5, 1, 2 and 3 m")
    parser.add_argument("--calibration", choices=("true", "computed", "both"), default="both",
                        help="with --accuracy: the rig's true calibration, one computed from 20 "
                        "rendered board pairs, or both (default)")
    parser.add_argument("--seed", type=options.seed, default=None, metavar="S",
                        help="with --accuracy: the simulated rig's seed (default: the benchmark's)")
    parser.add_argument("--seeds", type=options.whole(1, 1000), default=None, metavar="N",
                        help="with --accuracy: N rigs, seeds S, S+1, ... S+N-1 (S from --seed): "
                        "each seed's whole-grid row, then the mean and the worst seed of each "
                        "condition and preset")
    parser.add_argument("--condition", action="append", metavar="C",
                        help="with --accuracy: how the walls are rendered (repeatable): rig (the "
                        "rig's usual texture), weak (a smooth painted wall), half, quarter (its "
                        "contrast halved, quartered), webcams (half contrast with the right "
                        "camera's own gain and black level, MJPG, darker corners), exposure, "
                        "vignetting, mjpg (each of those alone at half contrast), or all "
                        "(default rig)")


def rig_size(text: str | None) -> tuple[int, int]:
    """The simulated rig's frame size from --size's WxH (640x480 when not given)."""
    if text is None:
        return 640, 480
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--size: expected WxH in pixels, e.g. 1280x720 (not {text!r})") from None
    if w < 64 or h < 48 or w > 8192 or h > 8192:
        raise InputError(f"--size {w}x{h}: between 64x48 and 8192x8192")
    return w, h


def _input(args: argparse.Namespace) -> tuple[str, StereoCalibration, np.ndarray, np.ndarray]:
    if args.calib or args.left or args.right:
        if not (args.calib and args.left and args.right):
            raise InputError("bench needs --calib C together with LEFT and RIGHT (or none of them "
                             "for the simulated rig)")
        if args.size:
            raise InputError("--size is for the simulated rig; the images give their own size")
        calib = load_calibration(args.calib, args.left)
        left, right = read_pair(args.left, args.right, calib)
        return "files", calib, left, right
    rig = SimRig(RigConfig.for_size(rig_size(args.size)), seed=0)
    calib = rig.true_calibration(alpha=0.0)
    left, right = rig.render_scene(Scene.demo())
    return "simulated rig, demo scene", calib, left, right


def _time(step: Step, frames: int, warmup: int = 2, lanes: int = 1) -> dict[str, Any]:
    """Time `frames` calls of step() -> (stage timings dict or None, valid fraction), made by
    `lanes` threads at once (each makes its share of the calls, as the frame worker's lanes do)."""
    sums: dict[str, float] = {}
    valid = [float("nan")]
    lock = threading.Lock()

    def calls(n: int, record: bool = True) -> None:
        for _ in range(n):
            stages, v = step()
            if record:
                with lock:
                    valid[0] = v
                    for k, ms in (stages or {}).items():
                        sums[k] = sums.get(k, 0.0) + ms

    def in_lanes(n: int, record: bool = True) -> None:
        if lanes == 1:
            calls(n, record)
            return
        shares = [n // lanes + (1 if i < n % lanes else 0) for i in range(lanes)]
        with ThreadPoolExecutor(lanes, thread_name_prefix="bench-lane") as pool:
            for f in [pool.submit(calls, k, record) for k in shares]:
                f.result()

    in_lanes(max(warmup, lanes), record=False)  # every lane's pipeline built before timing
    rss0 = rss_mb()
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    in_lanes(frames)
    elapsed = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    return {
        "fps": frames / elapsed if elapsed > 0 else float("inf"),
        "ms_per_frame": 1000.0 * elapsed / frames,
        "stages_ms": {k: v / frames for k, v in sums.items()},  # each frame's own time (latency)
        # CPU time of all threads per frame: what the frame costs, whatever else the machine runs
        "cpu_ms_per_frame": 1000.0 * cpu / frames,
        "rss_start_mb": rss0,
        "rss_end_mb": rss_mb(),
        "valid_fraction": valid[0],
        "lanes": lanes,
    }


def bench_preset(calib: StereoCalibration, params: Preset, left: np.ndarray, right: np.ndarray,
                 frames: int, warmup: int = 2, processor: LiveProcessor | None = None
                 ) -> dict[str, Any]:
    """Time one preset as the Live tab runs it with its default views (pipeline and display
    conversion): as many frames at once as the processor's lanes, OpenCV with the threads
    `run_app` gives it. `processor`: a LiveProcessor of `params` to time (kept open, so that its
    health check keeps its own schedule over several calls), else one made and closed here."""
    frame = StereoFrame(left, right, 0.0, 0.0, 0)
    proc = processor if processor is not None else live_processor(calib, params)
    with opencv_threads_for_lanes():
        # (a kept processor sets a preset's own count only on its first frame: every run
        # starts from the lanes' count, so it is set here for each run)
        use_preset_threads(params)
        try:
            def step() -> tuple[dict[str, float], float]:
                t0 = time.perf_counter()
                out = proc(frame)
                stages = dict(out.result.timings_ms)
                stages["display"] = (time.perf_counter() - t0) * 1000.0 - stages["total"]
                stages["total"] += stages["display"]
                return stages, float(out.result.valid.mean())

            timed = _time(step, frames, warmup, proc.lanes)
            timed["cv_threads"] = cv2.getNumThreads()  # (what the run had)
            return timed
        finally:
            if processor is None:
                proc.close()


def live_processor(calib: StereoCalibration, params: Preset) -> LiveProcessor:
    """The Live tab's processor for `params`, with the views the Live tab starts with."""
    proc = LiveProcessor(calib, params)
    proc.set_views(DEFAULT_VIEWS)  # as the Live tab starts
    return proc


def bench_reference(calib: StereoCalibration, left: np.ndarray, right: np.ndarray, frames: int,
                    warmup: int = 2) -> dict[str, Any]:
    """Time the reference loop on the same pair."""
    w = calib.image_size[0]
    lo, n = reference_loop.MIN_DISP, reference_loop.NUM_DISP
    if w - (lo + n) <= reference_loop.WINDOW_SIZE // 2:
        raise InputError(f"the images are {w} px wide: too narrow for the reference loop, which "
                         f"searches disparities {lo}..{lo + n - 1} px")
    loop = reference_loop.ReferenceLoop(calib)

    def step() -> tuple[dict[str, float], float]:
        t0 = time.perf_counter()
        out = loop.process(left, right)
        total = (time.perf_counter() - t0) * 1000.0
        return {"total": total}, float(np.isfinite(out.disparity_px).mean())

    return _time(step, frames, warmup)


def bench_plain(calib: StereoCalibration, left: np.ndarray, right: np.ndarray, frames: int,
                warmup: int = 2) -> dict[str, Any]:
    """Time the plain OpenCV program on the same pair."""
    n = plain_loop.NUM_DISP
    if calib.image_size[0] * plain_loop.SCALE - n <= plain_loop.WINDOW_SIZE // 2:
        raise InputError(f"the images are {calib.image_size[0]} px wide: too narrow for the "
                         f"plain program, which searches {n} disparities of the halved "
                         "images")
    loop = plain_loop.PlainLoop(calib)

    def step() -> tuple[dict[str, float], float]:
        t0 = time.perf_counter()
        out = loop.process(left, right)
        total = (time.perf_counter() - t0) * 1000.0
        return {"total": total}, float((out.filtered16 > 0).mean())

    return _time(step, frames, warmup)


_TIMERS = {"report": bench_reference, "plain": bench_plain}
_WORDS = {"report": "the reference loop, its own code",
          "plain": "a plain OpenCV program set up with care"}
_SHORT = {"report": "reference loop", "plain": "plain"}  # "2.5x the reference loop"


def run_bench(args: argparse.Namespace) -> dict[str, Any]:
    if args.frames is None:
        args.frames = 30
    if not 1 <= args.frames <= MAX_FRAMES:
        raise InputError(f"--frames must be from 1 to {MAX_FRAMES}, not {args.frames}")
    rounds = getattr(args, "rounds", 1)
    if not 1 <= rounds <= 1000:
        raise InputError(f"--rounds must be between 1 and 1000, not {rounds}")
    params = load_presets(args.preset or ["live"])  # unknown names fail before any work
    names = list(params)
    source, calib, left, right = _input(args)
    which = getattr(args, "reference", "both")
    references = list(REFERENCES) if which == "both" else [which]
    out = {"source": source, "size": list(calib.image_size), "frames": args.frames,
           "rounds": rounds, "cv_threads": cv2.getNumThreads(), "references": references,
           "presets": {}, "cv_threads_presets": opencv_threads_beside_lanes()}
    # the references first and last (and between the rounds), so that a change of the
    # machine's load shows in their runs
    ref_frames = args.frames if rounds == 1 else max(2, args.frames // 8)

    def time_references() -> dict[str, dict[str, Any]]:
        return {r: _TIMERS[r](calib, left, right, ref_frames) for r in references}

    refs = [time_references()]
    runs: dict[str, list[dict[str, Any]]] = {n: [] for n in names}
    # one processor per preset for all rounds: its health check runs every two seconds as live
    procs = {n: live_processor(calib, p) for n, p in params.items()}
    try:
        for _ in range(rounds):
            for name, p in params.items():
                runs[name].append(bench_preset(calib, p, left, right, args.frames,
                                               processor=procs[name]))
                procs[name].health.wait()  # a check still running ends before the next run
            refs.append(time_references())
    finally:
        for proc in procs.values():
            proc.close()
    out["report_frames"] = ref_frames  # (each reference's frames a run)
    out["presets"] = {n: _merged(v) for n, v in runs.items()}
    for r in references:
        fps_runs = [each[r]["fps"] for each in refs]
        ref = dict(refs[-1][r])
        ref["fps"] = _harmonic(fps_runs)
        ref["fps_runs"] = fps_runs
        out[r] = ref
        out[f"over_{r}"] = {n: v["fps"] / ref["fps"] for n, v in out["presets"].items()}
        if rounds > 1:
            # each round against the reference's runs on either side of it
            out[f"rounds_over_{r}"] = {
                n: [v["fps"] / _harmonic([fps_runs[i], fps_runs[i + 1]])
                    for i, v in enumerate(vs)] for n, vs in runs.items()}
            out[f"median_over_{r}"] = {
                n: float(statistics.median(v)) for n, v in out[f"rounds_over_{r}"].items()}
    return out


def _harmonic(fps: list[float]) -> float:
    """The rate of runs of equal frame counts taken together."""
    return len(fps) / sum(1.0 / f for f in fps)


def _merged(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Runs of one preset (equal frame counts) as one: rates over all of them, stage times and
    CPU averaged, memory from the first start to the last end."""
    if len(runs) == 1:
        return runs[0]
    out = dict(runs[-1])
    out["fps"] = _harmonic([r["fps"] for r in runs])
    out["ms_per_frame"] = statistics.fmean(r["ms_per_frame"] for r in runs)
    out["cpu_ms_per_frame"] = statistics.fmean(r["cpu_ms_per_frame"] for r in runs)
    out["stages_ms"] = {k: statistics.fmean(r["stages_ms"].get(k, 0.0) for r in runs)
                        for k in runs[0]["stages_ms"]}
    out["rss_start_mb"] = runs[0]["rss_start_mb"]
    out["fps_runs"] = [r["fps"] for r in runs]
    out["cv_threads_runs"] = [r["cv_threads"] for r in runs]
    return out


def run(args: argparse.Namespace) -> int:
    if getattr(args, "window", None) is not None:
        # (cli.py runs it: the window is Qt, which no command module imports)
        raise InputError("--window runs the application's window: start it as "
                         "stereo-gui bench --window SECONDS")
    if getattr(args, "source", None):
        raise InputError("--source goes with --window (the pipeline alone runs on LEFT RIGHT "
                         "or the simulated rig)")
    if getattr(args, "clicks", None):
        if args.scenes or args.accuracy or args.calib or args.left or args.right or args.size:
            raise InputError("--clicks takes its images from the scene list: no --scenes, "
                             "--accuracy, --calib, images or --size")
        res = run_clicks(args.clicks, args.preset or ("live", "quality"))
        print(json.dumps(res, indent=2) if args.json else format_clicks(res))
        return 0
    if getattr(args, "scenes", None):
        if args.accuracy or args.calib or args.left or args.right or args.size:
            raise InputError("--scenes takes its images from the scene list: no --accuracy, "
                             "--calib, images or --size")
        res = run_scenes(args.scenes, args.preset or ("live", "quality"),
                         repeat=1 if args.frames is None else args.frames)
        print(json.dumps(res, indent=2) if args.json else format_scenes(res))
        return 0
    if args.accuracy:
        return run_accuracy_bench(args)
    res = run_bench(args)
    if args.json:
        print(json.dumps(res, indent=2))
        return 0
    w, h = res["size"]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    rounds = ("" if res["rounds"] == 1 else
              f" in {res['rounds']} rounds (the reference loop {res['report_frames']} a run)")
    print(f"{res['source']}, {w}x{h}, {res['frames']} frames per run{rounds}, "
          f"OpenCV threads {res['cv_threads']} (the presets {res['cv_threads_presets']}), "
          f"load average {load:.1f} on {os.cpu_count()} CPUs")
    where = "before and after" if res["rounds"] == 1 else "before, between and after the rounds"
    for r in res["references"]:
        ref = res[r]
        runs = (" and " if len(ref["fps_runs"]) == 2 else ", ").join(
            f"{v:.1f}" for v in ref["fps_runs"])
        print(f"{r:>10}: {ref['fps']:6.1f} fps ({_WORDS[r]}; runs {where}: {runs} fps; CPU "
              f"{ref['cpu_ms_per_frame']:.1f} ms/frame)")
    for name, r in res["presets"].items():
        stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages_ms"].items() if k != "total")
        beside = "; ".join(f"{res[f'over_{ref}'][name]:.2f}x the {_SHORT[ref]}"
                           for ref in res["references"])
        own = ("" if r["cv_threads"] == res["cv_threads_presets"] else
               f", OpenCV threads {r['cv_threads']}")  # (the preset's own count)
        print(f"{name:>10}: {r['fps']:6.1f} fps ({r['lanes']} at once{own}: a frame every "
              f"{r['ms_per_frame']:.1f} ms, each {r['stages_ms']['total']:.1f} ms; CPU "
              f"{r['cpu_ms_per_frame']:.1f} ms/frame; {stages} ms); "
              f"RSS {r['rss_start_mb']:.0f} -> {r['rss_end_mb']:.0f} MiB; {beside}")
    for ref in res["references"]:
        for name, ratios in res.get(f"rounds_over_{ref}", {}).items():
            each = ", ".join(f"{v:.2f}" for v in ratios)
            print(f"{name:>10}: rounds {each} x the {_SHORT[ref]} beside them "
                  f"(median {res[f'median_over_{ref}'][name]:.2f}x, "
                  f"{min(ratios):.2f}-{max(ratios):.2f}x)")
    return 0


def run_accuracy_bench(args: argparse.Namespace) -> int:
    if args.calib or args.left or args.right or args.size:
        raise InputError("--accuracy runs on the simulated rig: no --calib, images or --size")
    presets = tuple(dict.fromkeys(["report", PLAIN]
                                  + (args.preset or ["seed", "live", "quality"])))
    cal = ("true", "computed") if args.calibration == "both" else (args.calibration,)
    seed = BENCH_SEED if args.seed is None else args.seed
    conditions = list(dict.fromkeys(getattr(args, "condition", None) or ["rig"]))
    if "all" in conditions:
        conditions = list(CONDITIONS)
    seeds = getattr(args, "seeds", None)
    if seeds is not None:
        return _accuracy_over_seeds(args, presets, cal, conditions,
                                    list(range(seed, seed + seeds)))
    res = run_accuracy(presets=presets, seed=seed, calibrations=cal, conditions=conditions)
    if args.json:
        print(json.dumps({"seed": seed, "conditions": {
            c: CONDITIONS[c].description for c in conditions}, "calibrations": {
            k: [r.summary() for r in v] for k, v in res.items()}, "totals": {
            k: [{"condition": c, "preset": p, **t} for (c, p), t in condition_totals(v).items()]
            for k, v in res.items()}}, indent=2))
        return 0
    for c in conditions:
        print(f"condition {c}: {CONDITIONS[c].description}")
    print(f"accuracy on the simulated rig (seed {seed}): 9x7 grid over the whole frame; cover = "
          "readings / points both cameras see; errors of Z in %; +-cov = share of readings whose "
          "95 % bound covers the true error; med+- = median bound in % of the distance")
    for label, reports in res.items():
        print(format_table(label, reports))
    return 0


# what a condition's row over several seeds gives: (key of condition_totals, "worst" is the
# lowest or the highest of the seeds)
_OVER_SEEDS = (("coverage", min), ("worst_pct", max), ("rms_pct", max),
               ("covered_fraction", min), ("median_bound_pct", max))


def accuracy_over_seeds(totals: dict[int, dict[tuple[str, str], dict[str, float]]]
                        ) -> dict[tuple[str, str], dict[str, dict[str, Any]]]:
    """Per (condition, preset): the mean over the seeds of each whole-grid figure and its
    worst seed's value (the lowest reading share and coverage of the +-, the highest errors),
    with which seed that was; `totals` is {seed: condition_totals}."""
    out: dict[tuple[str, str], dict[str, dict[str, Any]]] = {}
    keys = dict.fromkeys(k for t in totals.values() for k in t)
    for key in keys:
        row: dict[str, dict[str, Any]] = {}
        for name, worst in _OVER_SEEDS:
            row[name] = over_seeds_figure({s: t[key][name] for s, t in totals.items()
                                           if key in t and math.isfinite(t[key][name])}, worst)
        out[key] = row
    return out


def _accuracy_over_seeds(args: argparse.Namespace, presets: Sequence[str], cal: Sequence[str],
                         conditions: list[str], seeds: list[int]) -> int:
    totals: dict[str, dict[int, dict[tuple[str, str], dict[str, float]]]] = {
        label: {} for label in cal}
    for s in seeds:
        res = run_accuracy(presets=presets, seed=s, calibrations=cal, conditions=conditions)
        for label, reports in res.items():
            totals[label][s] = condition_totals(reports)
        if not args.json:
            for label in cal:
                for (c, p), t in totals[label][s].items():
                    print(f"seed {s:>6} {label:>8} {c:>10} {p:>8}: read {100 * t['coverage']:5.1f} %"
                          f", worst {t['worst_pct']:6.2f} %, RMS {t['rms_pct']:5.2f} %, +- covers "
                          f"{100 * t['covered_fraction']:5.1f} %", flush=True)
    over = {label: accuracy_over_seeds(t) for label, t in totals.items()}
    if args.json:
        print(json.dumps({
            "seeds": seeds, "conditions": {c: CONDITIONS[c].description for c in conditions},
            "per_seed": {label: {str(s): [{"condition": c, "preset": p, **v}
                                          for (c, p), v in t.items()] for s, t in per.items()}
                         for label, per in totals.items()},
            "over_seeds": {label: [{"condition": c, "preset": p, **v} for (c, p), v in o.items()]
                           for label, o in over.items()}}, indent=2))
        return 0
    print(f"over {len(seeds)} seeds ({seeds[0]}-{seeds[-1]}): mean / worst seed (which)")
    for label, o in over.items():
        print(f"calibration: {label}")
        for (c, p), v in o.items():
            parts = []
            for name, words, scale in (("coverage", "read", 100), ("worst_pct", "worst", 1),
                                       ("rms_pct", "RMS", 1), ("covered_fraction", "+- covers",
                                                               100)):
                m = v[name]
                if m["worst_seed"] is None:
                    parts.append(f"{words} -")
                    continue
                parts.append(f"{words} {scale * m['mean']:.2f} % / {scale * m['worst']:.2f} % "
                             f"({m['worst_seed']})")
            print(f"  {c:>10} {p:>8}: " + "; ".join(parts))
    return 0
