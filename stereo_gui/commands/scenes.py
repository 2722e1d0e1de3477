"""`stereo-gui bench --scenes FILE`: the presets' final maps on rectified scenes with ground truth,
side by side with the plain OpenCV baseline (`core.scene_score.plain_sgbm`), scene by scene.

Every method searches the same disparities on a scene: 0 up to 1.15 times its largest true
disparity. Each preset runs at its own speed setting (the live preset on images at most 320 px
wide); the baseline runs at full resolution and again at the size the first reduced-resolution
preset asked for matches at. A preset's map is its final map: what the views show, a click reads
and every export writes. Times are of one frame in one thread (a Live tab lane), OpenCV with the
threads the application gives it.
"""

from __future__ import annotations

import functools
import math
import os
import statistics
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.scene_score import (
    DisparityScore,
    disparity_search_range,
    plain_sgbm,
    score_disparity,
)
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.presets import load_presets
from stereo_gui.files.scenes import load_scene, read_scene_list
from stereo_gui.pipeline.concurrency import opencv_threads_for_lanes

BASELINE = "plain"
MARGIN_BAD2 = 0.005  # a preset may be this much worse in bad-2 than its baseline on a scene
MARGIN_DENSITY = 0.02  # ... and this much less dense


@dataclass
class SceneRow:
    """One scene: each method's score and time (ms); the baseline each preset is held to."""

    name: str
    size: tuple[int, int]
    num_disparities: int
    scores: dict[str, DisparityScore] = field(default_factory=dict)  # method -> its score
    ms: dict[str, float] = field(default_factory=dict)  # method -> ms per frame
    # preset -> the baseline it is held to on this scene (a preset with a largest matching
    # width matches a narrow scene at full size and a wide one reduced)
    baselines: dict[str, str] = field(default_factory=dict)


def baseline_of(preset: str, scale: float) -> str:
    """The baseline a preset is compared with: plain SGBM at the preset's matched size."""
    return BASELINE if scale >= 1.0 else f"{BASELINE}@{preset}"


def run_scenes(list_path: str | os.PathLike[str], presets: Sequence[str] = ("live", "quality"),
               repeat: int = 1) -> dict[str, Any]:
    """Score every preset and the baselines on every scene of the list; the result as a dict
    (the `--json` output)."""
    if not 1 <= repeat <= 100:
        raise InputError(f"--frames must be between 1 and 100 with --scenes, not {repeat}")
    specs = read_scene_list(list_path)
    params = load_presets(presets, reserved=(BASELINE,))
    rows: list[SceneRow] = []
    with opencv_threads_for_lanes():
        for spec in specs:
            scene = load_scene(spec)
            w, h = scene.size
            num = disparity_search_range(scene.truth_px)
            row = SceneRow(spec.name, (w, h), num)
            calib = StereoCalibration.identity((w, h), 1000.0, 100.0)
            methods: dict[str, Callable[[], np.ndarray]] = {
                BASELINE: functools.partial(plain_sgbm, scene.left, scene.right, num)}
            for name, p in params.items():
                p = p.replace(z_min_mm=None, z_max_mm=None, min_disparity=0,
                              num_disparities=num, parallel=False, cv_threads=None)
                scale = p.matcher.effective_scale(w, h)
                base = baseline_of(name, scale)
                row.baselines[name] = base
                if base not in methods:
                    methods[base] = functools.partial(plain_sgbm, scene.left, scene.right, num,
                                                      scale)
                pipe = StereoPipeline(calib, p)
                methods[name] = functools.partial(_final_map, pipe, scene.left, scene.right)
            for method, make in methods.items():
                disparity = make()  # (the first call builds what the matcher keeps)
                t0 = time.perf_counter()
                for _ in range(repeat):
                    disparity = make()
                row.ms[method] = (time.perf_counter() - t0) * 1000.0 / repeat
                row.scores[method] = score_disparity(disparity, scene.truth_px)
            rows.append(row)
    return summarize(rows, list(params))


def _final_map(pipe: StereoPipeline, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """A preset's final map of a rectified pair (no colour for the right view, no WLS)."""
    return pipe.process(left, right, right_colour=False, wls=False).final_px


def _baseline_label(rows: list[SceneRow], preset: str) -> str:
    """The name of what a preset is held to: one baseline, or plain SGBM at whatever size the
    preset matched each scene."""
    bases = list(dict.fromkeys(r.baselines[preset] for r in rows))
    return bases[0] if len(bases) == 1 else f"{BASELINE} at {preset}'s matching size"


def summarize(rows: list[SceneRow], presets: list[str]) -> dict[str, Any]:
    """The per-scene table, each preset's verdict against its baseline, and the averages."""
    methods = list(dict.fromkeys(m for r in rows for m in r.scores))
    out: dict[str, Any] = {"scenes": [], "presets": presets,
                           "baseline_of": {p: _baseline_label(rows, p) for p in presets},
                           "margins": {"bad2": MARGIN_BAD2, "density": MARGIN_DENSITY}}
    for r in rows:
        entry: dict[str, Any] = {
            "name": r.name, "size": list(r.size), "num_disparities": r.num_disparities,
            "methods": {m: {**_finite(r.scores[m].to_dict()), "ms": r.ms[m]}
                        for m in methods if m in r.scores},
            "baseline_of": dict(r.baselines)}
        entry["within_margins"] = {p: within(r.scores[p], r.scores[r.baselines[p]])
                                   for p in presets}
        out["scenes"].append(entry)
    out["mean"] = {}
    for m in methods:
        scores = [r.scores[m] for r in rows if m in r.scores]
        out["mean"][m] = {
            "bad1": _mean(s.bad1 for s in scores), "bad2": _mean(s.bad2 for s in scores),
            "bad4": _mean(s.bad4 for s in scores), "density": _mean(s.density for s in scores),
            "correct_density": _mean(s.correct_density for s in scores),
            "ms": _mean(r.ms[m] for r in rows if m in r.ms)}
    out["verdict"] = {}
    for p in presets:
        mp = out["mean"][p]
        # each scene's own baseline, averaged as the preset's scores are
        mb = {"bad2": _mean(r.scores[r.baselines[p]].bad2 for r in rows),
              "density": _mean(r.scores[r.baselines[p]].density for r in rows)}
        out["verdict"][p] = {
            "baseline": out["baseline_of"][p],
            "scenes_within_margins": sum(e["within_margins"][p] for e in out["scenes"]),
            "scenes": len(rows),
            "outside": [e["name"] for e in out["scenes"] if not e["within_margins"][p]],
            "bad2_ratio": mp["bad2"] / mb["bad2"] if mb["bad2"] else float("nan"),
            "mean_bad2_not_higher": mp["bad2"] <= mb["bad2"],
            "mean_density_not_lower": mp["density"] >= mb["density"],
        }
    return out


def within(score: DisparityScore, base: DisparityScore) -> bool:
    """A preset's score is within the margins of its baseline's on a scene."""
    if not math.isfinite(score.bad2):
        return False
    bad_ok = not math.isfinite(base.bad2) or score.bad2 <= base.bad2 + MARGIN_BAD2
    return bad_ok and score.density >= base.density - MARGIN_DENSITY


def format_scenes(res: dict[str, Any]) -> str:
    """The table a person reads: per scene and method bad-2 % / density %, then the averages
    and each preset's verdict."""
    methods = list(res["mean"])
    lines = [
        "scenes: bad-2 % (share of valued pixels off by more than 2 px) / density % (share of "
        "known pixels with a value); * = outside the margins of its baseline (bad-2 +"
        f"{100 * res['margins']['bad2']:.1f} points, density -"
        f"{100 * res['margins']['density']:.0f} points)",
        f"{'scene':<16}" + "".join(f"{m:>16}" for m in methods)]
    for e in res["scenes"]:
        cells = []
        for m in methods:
            s = e["methods"].get(m)
            if s is None:
                cells.append(f"{'':>16}")
                continue
            flag = "*" if m in e["within_margins"] and not e["within_margins"][m] else " "
            cells.append(f"{_pct(s['bad2']):>7}/{_pct(s['density']):>6}{flag:>2}")
        lines.append(f"{e['name'][:16]:<16}" + "".join(cells))
    lines.append(f"{'mean':<16}" + "".join(
        f"{_pct(res['mean'][m]['bad2']):>7}/{_pct(res['mean'][m]['density']):>6}  "
        for m in methods))
    lines.append("")
    for m in methods:
        a = res["mean"][m]
        lines.append(f"{m:>16}: bad-1 {_pct(a['bad1'])} %, bad-2 {_pct(a['bad2'])} %, bad-4 "
                     f"{_pct(a['bad4'])} %, density {_pct(a['density'])} %, right (within 2 px) "
                     f"{_pct(a['correct_density'])} % of the known pixels; {a['ms']:.0f} ms a "
                     "frame")
    for p, v in res["verdict"].items():
        outside = f" (outside: {', '.join(v['outside'])})" if v["outside"] else ""
        lines.append(
            f"{p}: within the margins of {v['baseline']} on {v['scenes_within_margins']} of "
            f"{v['scenes']} scenes{outside}; mean bad-2 {v['bad2_ratio']:.2f} x the "
            f"baseline's, mean density {'not lower' if v['mean_density_not_lower'] else 'LOWER'}")
    return "\n".join(lines)


def _pct(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100 * v:.1f}"


def _mean(values: Iterable[float | None]) -> float:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return statistics.fmean(finite) if finite else float("nan")


def over_seeds_figure(values: dict[int, float], worst: Callable[..., int]
                      ) -> dict[str, Any]:
    """One figure over several seeds: its mean, its worst seed's value (`worst` is min or max:
    the lowest share, the highest error) and which seed that was (None each without values)."""
    if not values:
        return {"mean": None, "worst": None, "worst_seed": None}
    seed = worst(values, key=values.__getitem__)
    return {"mean": float(statistics.fmean(values.values())), "worst": values[seed],
            "worst_seed": seed}


def _finite(d: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}
