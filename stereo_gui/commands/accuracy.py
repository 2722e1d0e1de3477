"""Accuracy over the whole frame on the simulated rig: `stereo-gui bench --accuracy`.

Fronto-parallel textured walls are rendered at known distances; a grid of pixels spread over the
whole rectified left image (9 x 7 by default, from a few pixels off the left edge to a few off the
right) is measured exactly as a click in the window measures it, and every reading is compared with
the distance the rig rendered there. Per preset and wall it reports

- coverage: readings / grid points both cameras see (a point whose match would fall outside the
  right image, or outside either raw image, cannot have depth and is not counted; such a point
  must say "not seen by the right camera"),
- worst and RMS relative error of Z, in %, over the readings,
- how often the printed +- (`expected_error_mm`, a 95 % bound) covered the true error, and the
  median +- in % of the distance.

The reference row "report" is the reference loop (core.reference_loop, the live loop of the
program of the report the project grew from): its remap, matcher and its 3x3 mean of the raw
disparity, triangulated through Q with the same calibration.
The row "plain" is plain OpenCV set up with care (`core.scene_score.plain_sgbm`: 8-direction
SGBM with a 1 px left-right check) on the same rectified images, read as the median of the 9x9
patch's valid disparities.

Each wall is rendered under a `Condition`: the rig's usual rich texture, or a smooth painted wall
at lower contrast, with what two cheap webcams add (the right camera's own gain and black level,
MJPG compression, darker corners).

The truth: the rectified pixel is taken back to the raw left pixel by the calibration under test
(its own maps), the true left camera's ray through that raw pixel is intersected with the wall,
and the point is expressed in the calibration's rectified frame. So a calibration's errors show
up as reading errors, as they would on a real rig.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_gui.core.calibrate import calibrate_stereo
from stereo_gui.core.click_score import plain_patch_disparity
from stereo_gui.core.detect import detect_pairs
from stereo_gui.core.errors import InputError
from stereo_gui.core.lens import rectify_map, undistort_points
from stereo_gui.core.matching import PipelineResult, StereoPipeline
from stereo_gui.core.measure import PATCH_PX, Measurement, measure_point
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.reference_loop import ReferenceFrame, ReferenceLoop
from stereo_gui.core.scene_score import plain_sgbm
from stereo_gui.core.shading import measure_pair_shading
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.presets import load_preset
from stereo_gui.pipeline.concurrency import preset_pipeline
from stereo_gui.sources.sim import Scene, SimRig
from stereo_gui.sources.sim.conditions import CONDITIONS, Condition

WALLS_MM = (500.0, 1000.0, 2000.0, 3000.0)
PLAIN = "plain"  # plain OpenCV SGBM with a left-right check, read as the 9x9 patch's median


GRID = (9, 7)  # columns, rows
GRID_MARGIN_PX = PATCH_PX // 2 + 4  # the outermost grid points sit this far inside the image
BENCH_SEED = 4242  # the benchmark's rig; tests use other seeds, so nothing is tuned to its scene


@dataclass(frozen=True)
class GridReading:
    """One grid point: rectified pixel, whether both cameras see it, truth and the reading."""

    x: float
    y: float
    seen: bool  # the point's match lies inside the right image (and both raw images)
    true_z_mm: float  # NaN where the ray hits nothing
    z_mm: float  # NaN where there is no reading
    expected_error_mm: float
    reason: str | None  # why there is no reading

    @property
    def read(self) -> bool:
        return math.isfinite(self.z_mm)

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.z_mm - self.true_z_mm) / self.true_z_mm

    @property
    def covered(self) -> bool:
        """The printed +- covered the true error."""
        return abs(self.z_mm - self.true_z_mm) <= self.expected_error_mm


@dataclass(frozen=True)
class WallReport:
    """Accuracy of one preset on one wall (relative errors in %)."""

    preset: str
    wall_mm: float
    readings: tuple[GridReading, ...] = field(repr=False)
    condition: str = "rig"

    @property
    def seen(self) -> list[GridReading]:
        return [r for r in self.readings if r.seen]

    @property
    def coverage(self) -> float:
        seen = self.seen
        return sum(r.read for r in seen) / len(seen) if seen else float("nan")

    def _errors(self) -> np.ndarray:
        return np.array([r.error_pct for r in self.seen if r.read])

    @property
    def worst_pct(self) -> float:
        e = self._errors()
        return float(np.abs(e).max()) if e.size else float("nan")

    @property
    def rms_pct(self) -> float:
        e = self._errors()
        return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")

    @property
    def covered_fraction(self) -> float:
        read = [r for r in self.seen if r.read]
        with_bound = [r for r in read if math.isfinite(r.expected_error_mm)]
        return sum(r.covered for r in with_bound) / len(read) if with_bound else float("nan")

    @property
    def median_bound_pct(self) -> float:
        b = [100.0 * r.expected_error_mm / r.true_z_mm for r in self.seen if r.read]
        return float(np.median(b)) if b else float("nan")

    @property
    def unseen_read(self) -> int:
        """Points the right camera cannot see that still got a reading (should be 0)."""
        return sum(1 for r in self.readings if not r.seen and r.read)

    @property
    def reasons(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for r in self.seen:
            if not r.read:
                out[r.reason or "?"] = out.get(r.reason or "?", 0) + 1
        return out

    def summary(self) -> dict[str, Any]:
        return {"preset": self.preset, "wall_mm": self.wall_mm, "condition": self.condition,
                "points": len(self.readings),
                "seen": len(self.seen), "coverage": self.coverage, "worst_pct": self.worst_pct,
                "rms_pct": self.rms_pct, "covered_fraction": self.covered_fraction,
                "median_bound_pct": self.median_bound_pct, "unseen_read": self.unseen_read,
                "reasons": self.reasons}


def grid_pixels(size: tuple[int, int], grid: tuple[int, int] = GRID,
                margin: float = GRID_MARGIN_PX) -> list[tuple[float, float]]:
    """Grid of rectified pixels over the whole image, row by row."""
    w, h = size
    xs = np.linspace(margin, w - 1 - margin, grid[0])
    ys = np.linspace(margin, h - 1 - margin, grid[1])
    return [(float(round(x)), float(round(y))) for y in ys for x in xs]


class WallTruth:
    """True depth and visibility of rectified pixels of `calib` for a wall rendered by `rig`."""

    def __init__(self, rig: SimRig, calib: StereoCalibration, wall_mm: float) -> None:
        self.rig = rig
        self.calib = calib
        self.wall_mm = float(wall_mm)
        w, h = calib.image_size
        self._maps = [rectify_map(calib.model, M, D, R, P, (w, h), cv2.CV_32FC1)
                      for M, D, R, P in ((calib.M1, calib.D1, calib.R1, calib.P1),
                                         (calib.M2, calib.D2, calib.R2, calib.P2))]

    def _raw(self, side: int, x: float, y: float) -> tuple[float, float]:
        mx, my = self._maps[side]
        h, w = mx.shape
        xi, yi = int(round(x)), int(round(y))
        if not (0 <= xi < w and 0 <= yi < h):
            return float("nan"), float("nan")
        return float(mx[yi, xi]), float(my[yi, xi])

    def point(self, x: float, y: float) -> tuple[float, bool]:
        """(true Z in the calibration's rectified frame mm, seen by both cameras)."""
        t = self.rig.truth
        w, h = self.calib.image_size
        u, v = self._raw(0, x, y)
        if not (0 <= u <= w - 1 and 0 <= v <= h - 1):
            return float("nan"), False
        xn, yn = undistort_points(t.model, np.array([[u, v]]), t.M1, t.D1)[0]
        ray = np.array([xn, yn, 1.0])
        p_left = ray * (self.wall_mm / ray[2])  # the wall is the plane Z = wall_mm
        p_rect = np.asarray(self.calib.R1, np.float64) @ p_left
        # where the calibration's rectified right camera sees that point
        q = np.asarray(self.calib.P2, np.float64) @ np.append(p_rect, 1.0)
        xr = q[0] / q[2]
        # and whether the true right camera sees it at all
        uv = self.rig.project(p_left.reshape(1, 3), 1)[0]
        seen = bool(0 <= xr <= w - 1 and 0 <= uv[0] <= w - 1 and 0 <= uv[1] <= h - 1)
        return float(p_rect[2]), seen


def _reference_reading(result: ReferenceFrame, x: float, y: float, calib: StereoCalibration
                       ) -> tuple[float, str | None]:
    """The reference program's measurement done with plain OpenCV: the mean raw disparity of the
    3x3 patch around the pixel (its code), over the pixels SGBM matched (it averaged the invalid marker
    too, which no honest comparison keeps), triangulated through Q."""
    xi, yi = int(x), int(y)
    d = result.disparity_px[yi - 1:yi + 2, xi - 1:xi + 2]
    d = d[np.isfinite(d)]
    if d.size == 0:
        return float("nan"), "no valid pixels"
    mean = float(d.mean())
    X, Y, Z, W = np.asarray(calib.Q, np.float64) @ np.array([x, y, mean, 1.0])
    if not W > 0:
        return float("nan"), "too far"
    return float(Z / W), None


def _plain_reading(disparity_px: np.ndarray, x: float, y: float, calib: StereoCalibration
                   ) -> tuple[float, str | None]:
    """Plain OpenCV's reading: the median of the valid disparities of the 9x9 patch around the
    pixel, triangulated through Q."""
    d = plain_patch_disparity(disparity_px, int(round(x)), int(round(y)), PATCH_PX, min_values=1)
    if not math.isfinite(d):
        return float("nan"), "no valid pixels"
    X, Y, Z, W = np.asarray(calib.Q, np.float64) @ np.array([x, y, d, 1.0])
    if not W > 0:
        return float("nan"), "too far"
    return float(Z / W), None


def plain_disparity(calib: StereoCalibration, left: np.ndarray, right: np.ndarray,
                    z_min_mm: float = 450.0) -> np.ndarray:
    """Plain OpenCV SGBM (`plain_sgbm`) on the rectified pair, disparities 0 .. the working
    distance's (as the presets search), full resolution."""
    pipe = StereoPipeline(calib, MatcherParams(z_min_mm=z_min_mm))
    rl, rr = pipe.rectify(left, right)
    d_max = calib.focal_px * calib.rectified_baseline_mm / z_min_mm - calib.disparity_offset_px
    num = max(16, int(math.ceil((d_max + 1) / 16.0)) * 16)
    return plain_sgbm(rl, rr, num)


# a grid point read: Z (mm, NaN when none), why there is none, the reading's 95 % bound (mm)
GridRead = tuple[float, str | None, float]


def _reference_read(frame: ReferenceFrame, calib: StereoCalibration, x: float, y: float
                    ) -> GridRead:
    return (*_reference_reading(frame, x, y, calib), float("nan"))


def _plain_read(disparity_px: np.ndarray, calib: StereoCalibration, x: float, y: float
                ) -> GridRead:
    return (*_plain_reading(disparity_px, x, y, calib), float("nan"))


def _preset_read(result: PipelineResult, x: float, y: float) -> GridRead:
    m: Measurement = measure_point(result, x, y)
    return (m.Z_mm if m.valid else float("nan")), m.reason, m.expected_error_mm


def evaluate_wall(rig: SimRig, calib: StereoCalibration, params: Preset | MatcherParams | str,
                  wall_mm: float, seed: int, grid: tuple[int, int] = GRID,
                  condition: Condition | None = None) -> WallReport:
    """Render a wall at `wall_mm` (under `condition`, default the rig's usual texture), run one
    preset (or "report": the reference loop; "plain": plain OpenCV) and measure the grid."""
    condition = condition or CONDITIONS["rig"]
    scene = Scene.wall(wall_mm, seed=seed + int(wall_mm), contrast=condition.contrast)
    left, right = rig.render_scene(scene, np.random.default_rng(seed * 7 + int(wall_mm)))
    truth = WallTruth(rig, calib, wall_mm)
    read: Callable[[float, float], GridRead]
    if params == "report":
        read = functools.partial(_reference_read, ReferenceLoop(calib).process(left, right),
                                 calib)
        name = "report"
    elif params == PLAIN:
        read = functools.partial(_plain_read, plain_disparity(calib, left, right), calib)
        name = PLAIN
    else:
        preset = Preset.of(load_preset(params) if isinstance(params, str) else params)
        with preset_pipeline(calib, preset) as pipe:
            read = functools.partial(_preset_read, pipe.process(left, right))
        name = preset.name
    readings = []
    for x, y in grid_pixels(calib.image_size, grid):
        z_true, seen = truth.point(x, y)
        z, reason, bound = read(x, y)
        readings.append(GridReading(x, y, seen, z_true, z, bound, reason))
    return WallReport(name, float(wall_mm), tuple(readings), condition.name)


def _loader(image: np.ndarray) -> Callable[[], np.ndarray]:
    """A loader of an image already in memory."""
    return lambda: image


def computed_calibration(rig: SimRig, pairs: int = 20, seed: int = BENCH_SEED
                         ) -> StereoCalibration:
    """A calibration computed the way the application does from `pairs` rendered board pairs."""
    images = rig.calibration_set(pairs, seed=seed)
    board = rig.config.board
    detections = detect_pairs([(f"pair{i}", l, r) for i, (l, r) in enumerate(images)], board)
    calib = calibrate_stereo(detections, board, rig.config.image_size).calibration
    shading = measure_pair_shading([(d, _loader(a), _loader(b))
                                    for d, (a, b) in zip(detections, images, strict=True)],
                                   board.cols, board.rows)
    return calib.with_updates(lens_shading=shading)


def run_accuracy(presets: Sequence[Preset | MatcherParams | str] = ("report", "seed", "live",
                                                                    "quality"),
                 walls: Sequence[float] = WALLS_MM, seed: int = BENCH_SEED,
                 calibrations: Sequence[str] = ("true", "computed"), pairs: int = 20,
                 conditions: Sequence[str] = ("rig",)) -> dict[str, list[WallReport]]:
    """Every preset on every wall under every condition, for each calibration; {calibration
    label: [WallReport]}. Under a condition with webcam effects the calibration is that of its
    cameras (true: with their lens shading; computed: from board pairs they rendered, as a
    technician calibrates the cameras they measure with); otherwise the rig's own, computed
    once."""
    if not walls:
        raise InputError("no wall distances to measure")
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown:
        raise InputError(f"unknown condition {unknown[0]!r}: one of {', '.join(CONDITIONS)}")
    base = SimRig(seed=seed)
    rigs = {c: base if c == "rig" else SimRig(CONDITIONS[c].rig_config(base.config), seed=seed)
            for c in conditions}
    out: dict[str, list[WallReport]] = {}
    for label in calibrations:
        if label not in ("true", "computed"):
            raise InputError(f"unknown calibration {label!r}: true or computed")
        calibs: dict[str, StereoCalibration] = {}
        for c in conditions:
            cameras = rigs[c] if CONDITIONS[c].changes_cameras else base
            key = c if CONDITIONS[c].changes_cameras else "rig"
            if key not in calibs:
                calibs[key] = (cameras.true_calibration() if label == "true"
                               else computed_calibration(cameras, pairs, seed))
            calibs[c] = calibs[key]
        out[label] = [evaluate_wall(rigs[c], calibs[c], p, z, seed, condition=CONDITIONS[c])
                      for c in conditions for z in walls for p in presets]
    return out


def condition_totals(reports: list[WallReport]) -> dict[tuple[str, str], dict[str, float]]:
    """Per (condition, preset): the whole grid over all walls: coverage, worst and RMS error (%),
    how often the +- covered the truth, and the median +- (% of the distance)."""
    groups: dict[tuple[str, str], list[WallReport]] = {}
    for r in reports:
        groups.setdefault((r.condition, r.preset), []).append(r)
    out: dict[tuple[str, str], dict[str, float]] = {}
    for key, reps in groups.items():
        seen = [g for r in reps for g in r.seen]
        read = [g for g in seen if g.read]
        errs = np.array([g.error_pct for g in read])
        bounded = [g for g in read if math.isfinite(g.expected_error_mm)]
        out[key] = {
            "coverage": len(read) / len(seen) if seen else float("nan"),
            "worst_pct": float(np.abs(errs).max()) if errs.size else float("nan"),
            "rms_pct": float(np.sqrt(np.mean(errs ** 2))) if errs.size else float("nan"),
            "covered_fraction": (sum(g.covered for g in bounded) / len(read)
                                 if bounded else float("nan")),
            "median_bound_pct": (float(np.median([100 * g.expected_error_mm / g.true_z_mm
                                                  for g in read])) if bounded else float("nan")),
            "unseen_read": sum(r.unseen_read for r in reps)}
    return out


def format_table(label: str, reports: list[WallReport]) -> str:
    """A plain-text table of one calibration's reports: wall by wall, then each condition's and
    preset's whole grid over all walls."""
    cw = max([8, *(len(r.condition) for r in reports)])  # the condition column's width
    lines = [f"calibration: {label}",
             f"{'cond':>{cw}} {'wall':>6} {'preset':>8} {'cover':>7} {'worst%':>7} {'rms%':>6} "
             f"{'+-cov':>6} {'med+-%':>7}  no reading (seen points)"]

    def row(cond: str, wall: str, preset: str, t: dict[str, Any], tail: str) -> str:
        return (f"{cond:>{cw}} {wall:>6} {preset:>8} {_num(100 * t['coverage'], 1):>6}% "
                f"{_num(t['worst_pct']):>7} {_num(t['rms_pct']):>6} "
                f"{_num(100 * t['covered_fraction'], 0):>5}% {_num(t['median_bound_pct']):>7}"
                f"{tail}")

    for r in reports:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(r.reasons.items())) or "-"
        if r.unseen_read:
            reasons += f"; {r.unseen_read} unseen points read"
        lines.append(row(r.condition, f"{r.wall_mm / 1000:5.1f}m", r.preset, r.summary(),
                         f"  {reasons}"))
    lines.append("whole grid, all walls:")
    for (cond, preset), t in condition_totals(reports).items():
        unseen = f"; {t['unseen_read']} unseen points read" if t["unseen_read"] else ""
        lines.append(row(cond, "all", preset, t, unseen))
    return "\n".join(lines)


def _num(v: float, digits: int = 2) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{digits}f}"


# ---- Middlebury benchmark pairs -------------------------------------------------------------
# name: (left, right, ground truth of the left view, its scale, the benchmark's disparity range)
MIDDLEBURY = {"teddy": ("im2.png", "im6.png", "disp2.png", 4.0, 64),
              "tsukuba": ("im3.png", "im4.png", "disp3.pgm", 16.0, 32)}
BAD_PX = 2.0  # "bad 2.0": a disparity off by more than 2 px


@dataclass(frozen=True)
class BenchmarkScore:
    """Bad-2.0 rate (share of known pixels with a disparity that is off by more than 2 px, among
    those with one) and density (share of known pixels with a disparity) of one map."""

    pair: str
    preset: str
    stage: str  # "raw" (SGBM) or "final" (what the view and the exports show)
    bad: float
    density: float


def score_map(disparity_px: np.ndarray, truth_px: np.ndarray) -> tuple[float, float]:
    """(bad-2.0 rate, density) of a float map (NaN invalid) against ground truth (0 unknown)."""
    known = truth_px > 0
    ok = known & np.isfinite(disparity_px)
    if not ok.any():
        return float("nan"), 0.0
    bad = float((np.abs(disparity_px - truth_px)[ok] > BAD_PX).mean())
    return bad, float(ok.sum() / known.sum())


def middlebury_scores(folder: str | os.PathLike[str],
                      presets: Sequence[str] = ("seed", "live", "quality")
                      ) -> list[BenchmarkScore]:
    """Raw and final maps of each preset on the Middlebury pairs found in `folder`. Presets other
    than seed search the benchmark's own disparity range (0..N) instead of deriving one from
    working distances; the seed keeps the reference loop's 2..129."""
    folder = Path(folder)
    out = []
    for pair, (a, b, g, div, num) in MIDDLEBURY.items():
        left = cv2.imread(str(folder / pair / a))
        right = cv2.imread(str(folder / pair / b))
        truth = cv2.imread(str(folder / pair / g), cv2.IMREAD_GRAYSCALE)
        if left is None or right is None or truth is None:
            continue
        truth = truth.astype(np.float32) / div
        calib = StereoCalibration.identity((left.shape[1], left.shape[0]), 500.0, 100.0)
        for name in presets:
            p = load_preset(name)
            if name != "seed":
                p = p.replace(z_min_mm=None, z_max_mm=None, min_disparity=0, num_disparities=num)
            with preset_pipeline(calib, p) as pipe:
                r = pipe.process(left, right)
            for stage, m in (("raw", r.disparity_px), ("final", r.final_px)):
                bad, density = score_map(m, truth)
                out.append(BenchmarkScore(pair, name, stage, bad, density))
    return out
