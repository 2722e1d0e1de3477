"""Rectified scenes with ground truth from the simulated rig, for `stereo-gui bench --clicks`:
`stereo-gui simulate OUT_DIR --click-scenes`.

For each seed, walls at CLICK_WALLS_MM under the conditions CLICK_CONDITIONS (the rig's rich
texture, a painted wall at a quarter of its contrast, a painted wall through two cheap webcams)
and the demo scene under the same conditions are rendered, rectified with the rig's true
calibration (alpha 0) through the pipeline's own maps, and written with

- the true disparity of every rectified left pixel (a PFM as Middlebury 2014's disp0GT.pfm:
  float px, bottom row first, inf where the left camera sees no surface there), computed from
  the rig's geometry: the rectified pixel's ray meets the scene's planes, and the point is
  projected into the rectified right camera (d = x_left - x_right, Z = F B / (d + DOFFS));
- a mask of the pixels both cameras see (255; 0 where the point falls outside the right raw or
  rectified image, or an object hides it from the right camera), as Middlebury's mask0nocc.png;
- a line of CLICK_LIST (files.scenes' scene list, 7 fields) naming them, with the calibration
  as `rectified:F,B,DOFFS` (the rectified pair's focal length px, baseline mm and disparity
  offset px, read from the true calibration's P2 and Q).

Everything is written as one set (files.atomic.write_many_atomic), as simulate's other sets.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
from collections.abc import Generator, Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.lens import rectify_map
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import MatcherParams
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.atomic import AtomicItem, Verify, encode_image, write_many_atomic
from stereo_gui.files.scenes import read_pfm
from stereo_gui.sources.sim.calibration_set import Progress
from stereo_gui.sources.sim.camera import RigConfig
from stereo_gui.sources.sim.conditions import CONDITIONS
from stereo_gui.sources.sim.rig import SimRig
from stereo_gui.sources.sim.scene import Scene

log = logging.getLogger(__name__)

CLICK_WALLS_MM = (500.0, 1000.0, 2000.0, 3000.0)
CLICK_CONDITIONS = ("rig", "quarter", "webcams")
CLICK_FOLDER = "click-scenes"  # the scenes' files, beside the list
CLICK_LIST = "clicks.tsv"
CLICK_SUFFIXES = ("-L.png", "-R.png", "-truth.pfm", "-mask.png")  # a scene's files
MAX_CLICK_SEEDS = 1000


@dataclass(frozen=True, eq=False)
class ClickScene:
    """One scene to write: its name, the condition it is rendered under, what the rig shows
    and the noise's seed."""

    name: str
    condition: str
    scene: Scene
    noise_seed: int
    distance_mm: float | None  # a wall's distance; None for the demo scene


def click_scene_plan(seed: int, walls: Sequence[float] = CLICK_WALLS_MM,
                     conditions: Sequence[str] = CLICK_CONDITIONS, demo: bool = True
                     ) -> list[ClickScene]:
    """The scenes of one seed: each wall under each condition, then the demo scene under each
    condition. The textures and the noise follow the seed (as bench --accuracy renders its
    walls: texture seed + distance, noise seed * 7 + distance)."""
    out = []
    for c in conditions:
        contrast = CONDITIONS[c].contrast
        for z in walls:
            out.append(ClickScene(f"s{seed}-{c}-wall{z / 1000:g}m", c,
                                  Scene.wall(z, seed=seed + int(z), contrast=contrast),
                                  seed * 7 + int(z), float(z)))
        if demo:
            base = Scene.demo()
            objects = tuple(replace(o, seed=o.seed + 1000 * seed, contrast=o.contrast * contrast)
                            for o in base.objects)
            out.append(ClickScene(f"s{seed}-{c}-demo", c, Scene(objects, name="demo"),
                                  seed * 7 + 1, None))
    return out


def click_scene_names(seeds: Iterable[int], walls: Sequence[float] = CLICK_WALLS_MM,
                      conditions: Sequence[str] = CLICK_CONDITIONS, demo: bool = True
                      ) -> list[str]:
    """The files (relative to OUT_DIR) write_click_scenes writes for these arguments."""
    names = [f"{CLICK_FOLDER}/{s.name}{suffix}" for seed in seeds
             for s in click_scene_plan(seed, walls, conditions, demo) for suffix in CLICK_SUFFIXES]
    return names + [CLICK_LIST]


def rectified_spec(calib: StereoCalibration) -> str:
    """`rectified:F,B,DOFFS` of a calibration's rectified pair (what its P2 and Q give)."""
    doffs = calib.disparity_offset_px + 0.0  # (no "-0")
    return (f"rectified:{calib.focal_px:.6f},{calib.rectified_baseline_mm:.6f},"
            f"{0.0 if abs(doffs) < 1e-9 else doffs:.6f}")


def true_disparity(rig: SimRig, calib: StereoCalibration, scene: Scene
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(true disparity of every rectified left pixel of `calib`, float32 px, inf where the left
    camera sees no surface; bool mask of the pixels both cameras see), from the rig's geometry.

    A rectified left pixel (x, y) is the ray R1^T K1^-1 (x, y, 1) of the left camera (K1 =
    P1's left 3x3); its nearest hit with the scene's rectangles is the point it shows, provided
    the pixel's map lands inside the raw left image (else the rectified image is black there).
    The point in the rectified frame (R1 p) projects through P2 to x_right; d = x - x_right.
    Both cameras see it where x_right and the point's raw right pixel lie inside the images and
    no object stands between it and the right camera.
    """
    w, h = (int(v) for v in calib.image_size)
    P1 = np.asarray(calib.P1, np.float64)
    P2 = np.asarray(calib.P2, np.float64)
    R1 = np.asarray(calib.R1, np.float64)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    pix = np.stack([xs, ys, np.ones_like(xs)], -1).reshape(-1, 3)
    rays = pix @ np.linalg.inv(P1[:, :3]).T @ R1  # (R1^T K1^-1 pix) for every pixel
    t_hit = _nearest_hits(scene, np.zeros(3), rays, limit=None)
    # the left rectified image shows what its map takes from inside the raw image
    mx, my = rectify_map(calib.model, calib.M1, calib.D1, R1, P1, (w, h), cv2.CV_32FC1)
    inside_left = ((mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1)).reshape(-1)
    known = np.isfinite(t_hit) & inside_left
    pts = rays[known] * t_hit[known, None]  # left camera frame, mm
    rect = pts @ R1.T
    q = rect @ P2[:, :3].T + P2[:, 3]
    x_right = q[:, 0] / q[:, 2]
    disparity = np.full(w * h, np.inf, np.float32)
    disparity[known] = (pix[known, 0] - x_right).astype(np.float32)
    # both cameras: inside the rectified and the raw right image, not hidden from the right
    uv = rig.project(pts, 1)
    seen = ((x_right >= 0) & (x_right <= w - 1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1)
            & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1))
    t = rig.truth
    centre_right = (-t.R.T @ t.T).reshape(3)
    if len(scene.objects) > 1:  # a single plane cannot hide itself
        blocked = _nearest_hits(scene, centre_right, pts - centre_right, limit=1.0 - 1e-6)
        seen &= ~np.isfinite(blocked)
    mask = np.zeros(w * h, bool)
    mask[np.flatnonzero(known)[seen]] = True
    return disparity.reshape(h, w), mask.reshape(h, w)


def _nearest_hits(scene: Scene, origin: np.ndarray, directions: np.ndarray,
                  limit: float | None) -> np.ndarray:
    """Per direction (N, 3), the smallest ray parameter t > 0 (point origin + t * direction)
    at which it meets one of the scene's rectangles, inf for none; with `limit`, only hits
    with t < limit count."""
    best = np.full(len(directions), np.inf)
    for obj in scene.objects:
        n = obj.normal
        denom = directions @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = float(n @ (obj.center - origin)) / denom
        ok = np.isfinite(t) & (t > 0)
        if limit is not None:
            ok &= t < limit
        rel = origin + directions * np.where(ok, t, 0.0)[:, None] - obj.center
        ok &= (np.abs(rel @ obj.u) <= obj.width_mm / 2) & (np.abs(rel @ obj.v) <= obj.height_mm / 2)
        best = np.where(ok & (t < best), t, best)
    return best


def _geometry_key(calib: StereoCalibration, scene: Scene) -> bytes:
    """What the true disparity depends on: the rectification and the objects' places."""
    parts = [np.asarray(m, np.float64).tobytes() for m in
             (calib.P1, calib.P2, calib.R1, calib.M1, calib.D1, calib.M2, calib.D2, calib.R,
              calib.T)]
    parts += [np.concatenate([o.center, o.u, o.v, [o.width_mm, o.height_mm]]).tobytes()
              for o in scene.objects]
    return b"|".join(parts)


def encode_pfm(image: np.ndarray) -> bytes:
    """A float image as a single-channel little-endian PFM (bottom row first)."""
    a = np.asarray(image, np.float32)
    if a.ndim != 2:
        raise ValueError("a PFM truth has one channel")
    h, w = a.shape
    header = f"Pf\n{w} {h}\n-1.0\n".encode("ascii")  # a negative scale: little-endian
    return header + np.ascontiguousarray(a[::-1]).astype("<f4").tobytes()


def _verify_pfm(shape: tuple[int, ...]) -> Verify:
    def verify(path: Path) -> None:
        if read_pfm(path).shape != shape:
            raise ValueError("the PFM reads back at another size")
    return verify


def _verify_png(path: Path) -> None:
    if cv2.imread(str(path), cv2.IMREAD_UNCHANGED) is None:
        raise ValueError("the PNG does not decode")


_LIST_HEADER = ("# stereo-gui simulate --click-scenes: rectified pairs of the simulated rig with "
                "their true disparity",
                "# name\tleft\tright\tground_truth\tdivide_by\tcalib\tmask")


def _scene_files(out: Path, rig: SimRig, cs: ClickScene,
                 truths: dict[bytes, tuple[np.ndarray, np.ndarray]]
                 ) -> Generator[AtomicItem, None, str]:
    """One click scene's files (rectified pair, true disparity, mask) as write_many_atomic
    takes them; returns its line of the list. `truths` keeps the true disparities by geometry."""
    calib = rig.true_calibration(alpha=0.0)
    left, right = rig.render_scene(cs.scene, np.random.default_rng(cs.noise_seed))
    # the pipeline's own maps and interpolation (a rectified: calibration skips them)
    with StereoPipeline(calib, MatcherParams()) as pipe:
        rl, rr = pipe.rectify(left, right)
    # the truth is the geometry's alone: shared by the conditions and the seeds
    key = _geometry_key(calib, cs.scene)
    if key not in truths:
        truths[key] = true_disparity(rig, calib, cs.scene)
    disparity, seen = truths[key]
    stem = f"{CLICK_FOLDER}/{cs.name}"
    names = [stem + s for s in CLICK_SUFFIXES]
    for name, img in ((names[0], rl), (names[1], rr),
                      (names[3], np.where(seen, 255, 0).astype(np.uint8))):
        yield out / name, encode_image(out / name, img), _verify_png
    yield out / names[2], encode_pfm(disparity), _verify_pfm(disparity.shape)
    log.debug("click scene %s: %d of %d pixels known, %d seen by both", cs.name,
              int(np.isfinite(disparity).sum()), disparity.size, int(seen.sum()))
    return "\t".join([cs.name, names[0], names[1], names[2], "1", rectified_spec(calib),
                      names[3]])


def write_click_scenes(out_dir: str | os.PathLike[str], seeds: Iterable[int] = (0, 1, 2),
                       config: RigConfig | None = None, walls: Sequence[float] = CLICK_WALLS_MM,
                       conditions: Sequence[str] = CLICK_CONDITIONS, demo: bool = True,
                       progress: Progress | None = None, what: str | None = None
                       ) -> list[ClickScene]:
    """Write the click scenes of every seed into OUT_DIR/CLICK_FOLDER and their list
    OUT_DIR/CLICK_LIST; return the scenes. `progress(done, total)` after each scene.

    Every file is written under a temporary name first and replaces an earlier one only when
    all are on disk (write_many_atomic), so a disk that fills leaves an earlier set whole.
    """
    out = Path(out_dir)
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise InputError("no seeds to render click scenes for")
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown:
        raise InputError(f"no wall condition {unknown[0]!r}: choose one of {', '.join(CONDITIONS)}")
    base = config or RigConfig()
    plans = [(seed, click_scene_plan(seed, walls, conditions, demo)) for seed in seeds]
    total = sum(len(p) for _, p in plans)
    folder = out / CLICK_FOLDER
    made_folder = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    written: list[ClickScene] = []
    truths: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def files() -> Iterator[AtomicItem]:
        lines = list(_LIST_HEADER)
        for seed, plan in plans:
            rigs: dict[str, SimRig] = {}
            for cs in plan:
                rig = rigs.get(cs.condition)
                if rig is None:
                    rig = rigs[cs.condition] = SimRig(CONDITIONS[cs.condition].rig_config(base),
                                                      seed=seed)
                lines.append((yield from _scene_files(out, rig, cs, truths)))
                written.append(cs)
                if progress:
                    progress(len(written), total)
        yield out / CLICK_LIST, ("\n".join(lines) + "\n").encode("utf-8"), None

    try:
        write_many_atomic(files(), what=what)
    except BaseException:
        if made_folder:  # the new set's own folder goes with it
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    return written


def centre_check(calib: StereoCalibration, disparity: np.ndarray) -> float:
    """Z = F B / (d + DOFFS) at the image centre of a truth map, mm (NaN where unknown)."""
    h, w = disparity.shape
    d = float(disparity[h // 2, w // 2])
    if not math.isfinite(d):
        return float("nan")
    return calib.focal_px * calib.rectified_baseline_mm / (d + calib.disparity_offset_px)
