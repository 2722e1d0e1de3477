"""`stereo-gui bench --clicks FILE`: the double-click judged on rectified scenes with ground truth,
beside plain OpenCV's patch median, scene by scene (scoring: `core.click_score`).

Every scene of the list (the `bench --scenes` format, with an optional calibration and mask per
line; Middlebury 2014's calib.txt and mask0nocc.png are found beside its images) is processed once
by each preset as `measure --calib` processes a pair, and an 11 x 8 grid is clicked as the window
reads a double-click (`core.measure.measure_point`). A scene without a calibration of its own is
read through an assumed one (ASSUMED_CALIB): its errors in % are then its disparity's, and the
presets search the disparities the truth holds (1.15 times its largest, as the baseline does),
since no working distance of theirs means anything there.

Plain OpenCV set up with care (`core.scene_score.plain_sgbm`, disparities to 1.15 times the
truth's largest) is read as the median of the same patch.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from stereo_gui.commands.scenes import _pct, over_seeds_figure
from stereo_gui.core.click_map import reading_map
from stereo_gui.core.click_score import (
    NEAR_SHARE,
    Click,
    ClickScore,
    click_points,
    map_right,
    plain_patch_disparity,
    seen_by_both,
    true_z_mm,
    true_z_span_mm,
    truth_step_px,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.measure import measure_point
from stereo_gui.core.scene_score import disparity_search_range, plain_sgbm
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.presets import load_presets
from stereo_gui.files.scenes import load_scene, read_scene_list, read_seen_mask
from stereo_gui.pipeline.concurrency import opencv_threads_for_lanes, preset_pipeline

PLAIN = "plain"
ASSUMED_CALIB = "rectified:1000,100"

# the simulated rig's click scenes (`simulate --click-scenes`) are named s<seed>-<condition>-...:
# a list of several seeds is summed per seed too, with the mean and the worst seed
SEED_NAME = re.compile(r"^s(\d+)-")
# what a method's row over the seeds gives: (key of ClickScore.summary, "worst" of the seeds)
_OVER_SEEDS = (("read", min), ("within_2pct", min), ("covers", min), ("covers_within_5pct", min),
               ("worst", max))

# a click's (x, y, true disparity px, true Z mm, the true Z's span for a truth stored in steps)
TruePoint = tuple[int, int, float, float, tuple[float, float] | None]


def run_clicks(list_path: str | os.PathLike[str], presets: Sequence[str] = ("live", "quality")
               ) -> dict[str, Any]:
    """Click every scene of the list with each preset and plain OpenCV; the `--json` result."""
    specs = read_scene_list(list_path)
    params = load_presets(presets, reserved=(PLAIN,))
    methods = [*params, PLAIN]
    totals = {m: ClickScore() for m in methods}
    metric = {m: ClickScore() for m in methods}  # the scenes with a calibration of their own
    seeds: dict[int, dict[str, ClickScore]] = {}  # the rig's click scenes, per seed
    scenes: list[dict[str, Any]] = []
    with opencv_threads_for_lanes():
        for spec in specs:
            scene = load_scene(spec)
            own = spec.calib is not None
            calib = load_any_calibration(ASSUMED_CALIB if spec.calib is None else spec.calib,
                                         scene.size).calibration
            if tuple(calib.image_size) != scene.size:
                raise InputError(f"scene {spec.name}: its calibration is for "
                                 f"{calib.image_size[0]}x{calib.image_size[1]}, its images "
                                 f"{scene.size[0]}x{scene.size[1]}")
            seen = read_seen_mask(spec)
            if seen is None:
                seen = seen_by_both(scene.truth_px)
            points = click_points(scene.truth_px, seen)
            true_d = [(x, y, float(scene.truth_px[y, x])) for x, y in points]
            step = truth_step_px(scene.truth_px)
            truth = [(x, y, d, true_z_mm(calib, x, y, d),
                      true_z_span_mm(calib, x, y, d, step) if step else None)
                     for x, y, d in true_d]
            num = disparity_search_range(scene.truth_px)
            entry: dict[str, Any] = {
                "name": spec.name, "size": list(scene.size),
                "calibration": spec.calib if own else f"assumed {ASSUMED_CALIB}",
                "points": len(points), "truth_step_px": step, "methods": {}}
            seed = SEED_NAME.match(spec.name)
            sums = [totals] + ([metric] if own else []) + (
                [seeds.setdefault(int(seed.group(1)), {m: ClickScore() for m in methods})]
                if seed else [])
            for name, preset in params.items():
                if not own:
                    preset = preset.replace(z_min_mm=None, z_max_mm=None, min_disparity=0,
                                            num_disparities=num)
                t0 = time.perf_counter()
                with preset_pipeline(calib, preset) as pipe:
                    result = pipe.process(scene.left, scene.right)
                clicks = click_scene(result, calib, truth)
                entry["methods"][name] = _scored(clicks, time.perf_counter() - t0,
                                                 result.disparity_range_px)
                for scores in sums:
                    scores[name].add(clicks)
            t0 = time.perf_counter()
            plain = plain_sgbm(scene.left, scene.right, num)
            clicks = click_plain(plain, calib, truth)
            entry["methods"][PLAIN] = _scored(clicks, time.perf_counter() - t0, (0, num - 1))
            for scores in sums:
                scores[PLAIN].add(clicks)
            scenes.append(entry)
    out: dict[str, Any] = {
        "list": str(list_path), "presets": list(params), "scenes": scenes,
        "total": {m: t.summary() for m, t in totals.items()},
        "own_calibration": {m: t.summary() for m, t in metric.items()}}
    if len(seeds) >= 2:
        out["over_seeds"] = over_seeds({s: {m: c.summary() for m, c in per.items()}
                                        for s, per in sorted(seeds.items())})
    return out


def over_seeds(per_seed: dict[int, dict[str, dict[str, Any]]]) -> dict[str, Any]:
    """Per method: the mean over the seeds of each seed's read share, share right within 2 %,
    coverage of the +- (of all readings and of those within NEAR_SHARE) and worst error, and the
    worst seed's value (the lowest shares, the highest error) with which seed that was;
    `per_seed` is {seed: {method: summary}}."""
    methods = dict.fromkeys(m for per in per_seed.values() for m in per)
    out: dict[str, Any] = {"seeds": list(per_seed), "methods": {}}
    for m in methods:
        row: dict[str, Any] = {}
        for key, worst in _OVER_SEEDS:
            row[key] = over_seeds_figure({s: per[m][key] for s, per in per_seed.items()
                                          if m in per and per[m].get(key) is not None}, worst)
        out["methods"][m] = row
    return out


def click_scene(result: PipelineResult, calib: StereoCalibration, truth: list[TruePoint]
                ) -> list[Click]:
    """The clicks of one processed scene: (x, y, true disparity, true Z) each, read as a
    double-click in the window reads them."""
    shown = reading_map(result)
    out = []
    for x, y, d, z, span in truth:
        m = measure_point(result, x, y, calibration=calib)
        right = map_right(calib, x, y, float(shown[y, x]), d, z)
        if m.valid:
            out.append(Click(x, y, z, m.Z_mm, m.expected_error_mm, None, right, span))
        else:
            out.append(Click(x, y, z, reason=str(m.reason), map_right=right))
    return out


def click_plain(disparity_px: np.ndarray, calib: StereoCalibration, truth: list[TruePoint]
                ) -> list[Click]:
    """Plain OpenCV's clicks: the patch median, triangulated through the same calibration."""
    out = []
    for x, y, d, z, span in truth:
        read = plain_patch_disparity(disparity_px, x, y)
        right = map_right(calib, x, y, float(disparity_px[y, x]), d, z)
        z_read = true_z_mm(calib, x, y, read) if math.isfinite(read) else float("nan")
        if math.isfinite(z_read):
            out.append(Click(x, y, z, z_read, map_right=right, true_z_span=span))
        else:
            out.append(Click(x, y, z, reason="too few valid pixels", map_right=right))
    return out


def _scored(clicks: list[Click], seconds: float, span: tuple[float, float]) -> dict[str, Any]:
    return {**ClickScore().add(clicks).summary(), "seconds": seconds,
            "disparity_range_px": [float(span[0]), float(span[1])]}


def format_clicks(res: dict[str, Any]) -> str:
    """The table a person reads: per scene and method read / within 2 % / worst, then the sums
    (over all scenes, and over those with a calibration of their own, whose errors in % are of
    Z) with coverage of the +- and the reasons of the refusals."""
    methods = [*res["presets"], PLAIN]
    lines = ["clicks: an 11x8 grid where the truth is known and seen by both cameras over the "
             "9x9 patch; read % / right within 2 % (of the clicks) / worst error %",
             f"{'scene':<16}{'pts':>5}" + "".join(f"{m:>22}" for m in methods)]
    for e in res["scenes"]:
        cells = []
        for m in methods:
            s = e["methods"][m]
            cells.append(f"{_pct(s['read']):>7}/{_pct(s['within_2pct']):>6}/"
                         f"{_pct(s['worst']):>6}  ")
        lines.append(f"{e['name'][:16]:<16}{e['points']:>5}" + "".join(cells))
    for key, title in (("total", "all scenes"),
                       ("own_calibration", "the scenes with a calibration of their own")):
        if not res[key][PLAIN]["points"]:
            continue
        lines += ["", f"{title}:"]
        for m in methods:
            t = res[key][m]
            lines.append(f"{m:>10}: {t['points']} clicks, read {_pct(t['read'])} %, within 1 % "
                         f"{_pct(t['within_1pct'])} %, within 2 % {_pct(t['within_2pct'])} %, "
                         f"worst {_pct(t['worst'])} %"
                         + ("" if m == PLAIN else f", +- covers {_pct(t['covers'])} % "
                            f"({_pct(t['covers_within_5pct'])} % of the readings within "
                            f"{100 * NEAR_SHARE:g} %)"))
            for reason, n in t["reasons"].items():
                lines.append(f"{'':>12}{reason}: {n['refused']} refused, the map right at "
                             f"{n['map_right']}")
    if "over_seeds" in res:
        lines += ["", _over_seeds_text(res["over_seeds"])]
    assumed = [e["name"] for e in res["scenes"] if e["calibration"].startswith("assumed")]
    if assumed:
        lines.append(f"assumed calibration ({ASSUMED_CALIB}; the presets search the truth's "
                     f"disparities): {', '.join(assumed)}")
    stepped = [f"{e['name']} {_step_text(e['truth_step_px'])}" for e in res["scenes"]
               if e.get("truth_step_px")]
    if stepped:
        lines.append("truths stored in steps (errors are counted from the span of the truth's "
                     f"step, and the +- covers where it reaches it): {', '.join(stepped)}")
    return "\n".join(lines)


def _over_seeds_text(over: dict[str, Any]) -> str:
    """The rows over the seeds: each method's mean / worst seed (which) of each figure."""
    seeds = over["seeds"]
    lines = [f"over {len(seeds)} seeds ({seeds[0]}-{seeds[-1]}): mean / worst seed (which)"]
    for m, row in over["methods"].items():
        parts = []
        for key, words in (("read", "read"), ("within_2pct", "within 2 %"),
                           ("covers", "+- covers"),
                           ("covers_within_5pct", f"+- covers within {100 * NEAR_SHARE:g} %"),
                           ("worst", "worst")):
            v = row[key]
            if v["mean"] is None:
                continue
            parts.append(f"{words} {_pct(v['mean'])} % / {_pct(v['worst'])} % "
                         f"({v['worst_seed']})")
        lines.append(f"{m:>10}: " + ", ".join(parts))
    return "\n".join(lines)


def _step_text(step: float) -> str:
    """A truth's step as a person reads it: 1 px, 1/3 px."""
    n = round(1.0 / step)
    return "1 px" if n <= 1 else (f"1/{n} px" if abs(step * n - 1.0) < 1e-3 else f"{step:g} px")
