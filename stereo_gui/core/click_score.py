"""How readings at clicked pixels are judged against ground truth: the click benchmark's scoring.

A scene with true disparity (float px, 0 where unknown) and a metric calibration is clicked on a
grid spread over the whole frame (CLICK_GRID, columns x rows). A grid point counts where the truth
is known and both cameras see it over the whole patch a reading looks at (PATCH_PX square): no
reading can be asked for where the truth itself is missing or occluded. Each point's true Z is
the truth's disparity at the pixel taken through the scene's own calibration (Middlebury's
Z = baseline * f / (d + doffs)), so the comparison holds for any rig.

A reading is right within 1 % or 2 % when its Z is that close to the true Z; its bound covers
when |Z - true Z| <= its printed +-. A truth stored in whole steps of a pixel (`truth_step_px`:
the older Middlebury scenes hold whole pixels of their full-size images, so tsukuba's truth is
known to 1 px, a third-size scene's to 1/3 px, teddy's to 1/4 px) knows the true Z only to the
span its step leaves: there a reading's error is its distance from that span (a reading inside
it is not known to be wrong; plain OpenCV's is judged the same way), and the +- covers when it
reaches the span. For each refusal, whether the map under the click was right there (within 2 %
of Z or 0.5 px of disparity) is counted too: a refusal of a right map is an answer thrown away,
of a wrong one a wrong answer stopped.

Plain OpenCV's reading is the median of the valid disparities of the same patch, with at least
PLAIN_MIN_VALUES of them.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from stereo_gui.core.measure import PATCH_PX
from stereo_gui.core.stereo_calibration import StereoCalibration, triangulate

CLICK_GRID = (11, 8)  # columns, rows
PLAIN_MIN_VALUES = 5  # plain OpenCV's patch median needs this many valid disparities
OCCLUSION_TOLERANCE_PX = 1.0  # a nearer surface must cover the point's right-image column by this
MAP_RIGHT_SHARE = 0.02  # the map under a refused click was right: within 2 % of Z ...
MAP_RIGHT_PX = 0.5  # ... or this close in disparity
RIGHT_SHARES = (0.01, 0.02)
# a reading within this share of the true Z read the clicked surface (its error is the match's
# sub-pixel error, which the +- is there to bound); one further off mostly read another surface,
# which no +- foresees. The +- is also judged on the first alone (`covers_near`): on the 13 public
# scenes it covers 95.0 % of those (live) where it covers 90.6 % of all readings
NEAR_SHARE = 0.05
SPARSE_TRUTH = 0.5  # a truth known at fewer of the pixels is a sparse one (a laser scanner's)
SPARSE_PATCH_SHARE = 1.0 / 3.0
TRUTH_STEP_MIN_PX = 1.0 / 64.0  # a finer grid is a truth stored as numbers (KITTI's 1/256 px)
TRUTH_STEP_MIN_VALUES = 5  # (tsukuba's truth holds 7)


def seen_by_both(truth_px: np.ndarray) -> np.ndarray:
    """Mask of the known pixels of a left view's true disparity that the right camera sees too:
    their match x - d lies inside the right image, and no nearer known pixel to their right
    lands on or beyond that column (it would hide them). For truths without an occlusion mask of
    their own."""
    t = np.asarray(truth_px, np.float64)
    h, w = t.shape
    known = t > 0
    x = np.arange(w, dtype=np.float64)[None, :]
    u = np.where(known, x - t, np.inf)  # right-image column each pixel matches
    # the leftmost right-image column reached by any known pixel to the right of each pixel
    reach = np.minimum.accumulate(u[:, ::-1], axis=1)[:, ::-1]
    beyond = np.concatenate([reach[:, 1:], np.full((h, 1), np.inf)], axis=1)
    return known & (u >= 0) & (u <= beyond + OCCLUSION_TOLERANCE_PX)


def click_points(truth_px: np.ndarray, seen: np.ndarray, grid: tuple[int, int] = CLICK_GRID,
                 patch: int = PATCH_PX) -> list[tuple[int, int]]:
    """The grid's pixels (row by row) whose whole patch is known and seen by both cameras; the
    grid spans the image at the centres of equal cells. A sparse truth (a laser scanner's, known
    at under SPARSE_TRUTH of the pixels) cannot be known over a whole patch: there the centre
    must be known, a SPARSE_PATCH_SHARE of the patch too, and none of it occluded."""
    h, w = truth_px.shape
    half = patch // 2
    known = truth_px > 0
    sparse = known.mean() < SPARSE_TRUTH
    out = []
    for j in range(grid[1]):
        y = int((j + 0.5) * h / grid[1])
        for i in range(grid[0]):
            x = int((i + 0.5) * w / grid[0])
            if not (half <= x < w - half and half <= y < h - half):
                continue
            k = known[y - half:y + half + 1, x - half:x + half + 1]
            s = seen[y - half:y + half + 1, x - half:x + half + 1]
            if sparse:
                ok = (known[y, x] and seen[y, x] and k.mean() >= SPARSE_PATCH_SHARE
                      and not (k & ~s).any())
            else:
                ok = (k & s).all()
            if ok:
                out.append((x, y))
    return out


def truth_step_px(truth_px: np.ndarray) -> float:
    """The step a truth's disparities are stored in (px), 0 for a truth stored as numbers: the
    smallest difference of its known values where that lies between TRUTH_STEP_MIN_PX and 1 px
    and every value is a whole multiple of it. A truth of fewer than TRUTH_STEP_MIN_VALUES
    values (a made-up scene of a few planes) shows no grid: its values are taken as exact."""
    t = np.asarray(truth_px, np.float64)
    values = np.unique(t[np.isfinite(t) & (t > 0)])
    if values.size < TRUTH_STEP_MIN_VALUES:
        return 0.0
    step = float(np.min(np.diff(values)))
    if not TRUTH_STEP_MIN_PX <= step <= 1.0:
        return 0.0
    k = values / step
    return step if bool(np.all(np.abs(k - np.round(k)) < 0.01)) else 0.0


def true_z_span_mm(calibration: StereoCalibration, x: float, y: float, truth_d: float,
                   step_px: float) -> tuple[float, float]:
    """The true Z's span (near, far; mm) for a truth known to `step_px`: the Z of its disparity
    half a step either way (infinite far where that passes infinity)."""
    near = true_z_mm(calibration, x, y, truth_d + step_px / 2.0)
    far = true_z_mm(calibration, x, y, truth_d - step_px / 2.0) if step_px > 0 else near
    return near, far if math.isfinite(far) and far > 0 else math.inf


def true_z_mm(calibration: StereoCalibration, x: float, y: float, truth_d: float) -> float:
    """The true Z (mm) of rectified pixel (x, y) of true disparity `truth_d` px."""
    xyz = triangulate(calibration, x, y, truth_d)
    return float("nan") if xyz is None else xyz[2]


def plain_patch_disparity(disparity_px: np.ndarray, x: int, y: int, patch: int = PATCH_PX,
                          min_values: int = PLAIN_MIN_VALUES) -> float:
    """Plain OpenCV's reading of a click: the median of the patch's valid disparities (px), NaN
    with fewer than `min_values` of them."""
    half = patch // 2
    d = disparity_px[max(0, y - half):y + half + 1, max(0, x - half):x + half + 1]
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size >= min_values else float("nan")


@dataclass(frozen=True)
class Click:
    """One clicked point: its true Z (mm), the reading (Z NaN when refused), the reading's 95 %
    bound (mm), the refusal's reason, whether the map under the click was right there, and the
    span the true Z lies in where the truth is stored in steps (`true_z_span_mm`; None: exact)."""

    x: int
    y: int
    true_z_mm: float
    z_mm: float = float("nan")
    bound_mm: float = float("nan")
    reason: str | None = None
    map_right: bool | None = None
    true_z_span: tuple[float, float] | None = None

    @property
    def read(self) -> bool:
        return math.isfinite(self.z_mm)

    @property
    def error_share(self) -> float:
        """|Z - true Z| / true Z, for a truth stored in steps the distance from Z to the span
        the true Z lies in (0 inside it); NaN when refused."""
        if not self.read:
            return float("nan")
        near, far = self.true_z_span or (self.true_z_mm, self.true_z_mm)
        return max(near - self.z_mm, self.z_mm - far, 0.0) / self.true_z_mm

    @property
    def covered(self) -> bool:
        """Whether the reading's +- reaches the true Z (its span, for a truth stored in steps)."""
        near, far = self.true_z_span or (self.true_z_mm, self.true_z_mm)
        return (self.read and self.z_mm - self.bound_mm <= far
                and self.z_mm + self.bound_mm >= near)


def map_right(calibration: StereoCalibration, x: int, y: int, map_d: float, truth_d: float,
              true_z: float) -> bool:
    """Whether a map's disparity at a click is right: within MAP_RIGHT_PX of the truth's, or its
    Z within MAP_RIGHT_SHARE of the true Z."""
    if not math.isfinite(map_d):
        return False
    if abs(map_d - truth_d) <= MAP_RIGHT_PX:
        return True
    z = true_z_mm(calibration, x, y, map_d)
    return math.isfinite(z) and abs(z - true_z) <= MAP_RIGHT_SHARE * true_z


@dataclass
class ClickScore:
    """Clicks summed: how many were asked, read, right within 1 % and 2 % (shares of the
    clicks asked), the worst error of a reading (share of Z), how often the +- covered the truth
    (share of the readings, and of those within NEAR_SHARE), and each refusal's count with how
    many of those had a right map."""

    clicks: list[Click] = field(default_factory=list)

    def add(self, clicks: Iterable[Click]) -> ClickScore:
        self.clicks.extend(clicks)
        return self

    @property
    def points(self) -> int:
        return len(self.clicks)

    def _share(self, n: int, of: int) -> float:
        return n / of if of else float("nan")

    @property
    def read(self) -> float:
        return self._share(sum(c.read for c in self.clicks), self.points)

    def within(self, share: float) -> float:
        return self._share(sum(c.read and c.error_share <= share for c in self.clicks),
                           self.points)

    @property
    def worst(self) -> float:
        errors = [c.error_share for c in self.clicks if c.read]
        return max(errors) if errors else float("nan")

    def _coverage(self, within: float = math.inf) -> float:
        """How often the +- covered the truth, of the readings with a +- at most `within` off."""
        readings = [c for c in self.clicks
                    if c.read and math.isfinite(c.bound_mm) and c.error_share <= within]
        return self._share(sum(c.covered for c in readings), len(readings))

    @property
    def covers(self) -> float:
        return self._coverage()

    @property
    def covers_near(self) -> float:
        """How often the +- covered the truth where the reading is within NEAR_SHARE of it (of
        the clicked surface): the +-'s width judged apart from readings of another surface."""
        return self._coverage(NEAR_SHARE)

    def reasons(self) -> dict[str, dict[str, int]]:
        """Each refusal's reason: how many clicks it refused and how many of those the map under
        the click had right."""
        refused = Counter(c.reason for c in self.clicks if not c.read)
        right = Counter(c.reason for c in self.clicks if not c.read and c.map_right)
        return {str(r): {"refused": n, "map_right": right[r]}
                for r, n in refused.most_common()}

    def summary(self) -> dict[str, object]:
        def num(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"points": self.points, "read": num(self.read),
                "within_1pct": num(self.within(RIGHT_SHARES[0])),
                "within_2pct": num(self.within(RIGHT_SHARES[1])), "worst": num(self.worst),
                "covers": num(self.covers), "covers_within_5pct": num(self.covers_near),
                "reasons": self.reasons()}
