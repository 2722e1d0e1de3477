"""Coverage of the images by a set of calibration views, by region, and readiness to calibrate.

A calibration can only be trusted where the target's points have been: the lens model is fitted
to them and extrapolated elsewhere, and the image corners are where the distortion is largest.
So each image is cut into a 5 x 5 grid of cells and the cells are grouped into nine regions a
person can name: the four corners (one cell each), the four edges (the three cells between two
corners) and the centre (the inner 3 x 3 cells). A region is covered when every one of its cells
holds at least MIN_POINTS_PER_CELL points of the kept views, in that camera's image.

"Ready to calibrate" follows from coverage, not a count of pairs: every region of both images
covered (except, if need be, the far side of each image, FAR_SIDE: the left image's left edge and
the right image's right edge, which both cameras see only from far away), the board tilted
enough (ROS camera_calibration's skew) and seen at a spread of distances (its size), with at
least MIN_PAIRS pairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import PairDetection, pair_pose

GRID = 5  # cells across and down each image
MIN_POINTS_PER_CELL = 3
MIN_PAIRS = 10  # fewest pairs for a stable solve, however well they cover the images
TILT_NEEDED = 0.5  # largest skew (ROS's 0..1 measure) the views must reach
SIZE_SPREAD_NEEDED = 0.15  # spread of the board's size (sqrt of its area share) the views must reach

SIDES = ("left", "right")
# region name -> its cells (row, col) of the 5 x 5 grid
REGIONS: dict[str, tuple[tuple[int, int], ...]] = {
    "top-left corner": ((0, 0),),
    "top edge": ((0, 1), (0, 2), (0, 3)),
    "top-right corner": ((0, 4),),
    "left edge": ((1, 0), (2, 0), (3, 0)),
    "centre": tuple((r, c) for r in (1, 2, 3) for c in (1, 2, 3)),
    "right edge": ((1, 4), (2, 4), (3, 4)),
    "bottom-left corner": ((4, 0),),
    "bottom edge": ((4, 1), (4, 2), (4, 3)),
    "bottom-right corner": ((4, 4),),
}
CORNERS = ("top-left corner", "top-right corner", "bottom-left corner", "bottom-right corner")
# the side of each image the other camera does not share: a board there is seen by both cameras
# only from far away (or, a ChArUco board, partly), so readiness asks for it but does not wait
FAR_SIDE = {"left": ("top-left corner", "left edge", "bottom-left corner"),
            "right": ("top-right corner", "right edge", "bottom-right corner")}


def cell_counts(points_px: Sequence[np.ndarray], image_size: tuple[int, int]) -> np.ndarray:
    """How many of the given points (arrays of (N, 2) px) fall in each cell, (GRID, GRID) int."""
    w, h = image_size
    counts = np.zeros((GRID, GRID), np.int64)
    for pts in points_px:
        p = np.asarray(pts, np.float64).reshape(-1, 2)
        inside = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
        p = p[inside]
        c = np.clip((p[:, 0] * GRID / w).astype(int), 0, GRID - 1)
        r = np.clip((p[:, 1] * GRID / h).astype(int), 0, GRID - 1)
        np.add.at(counts, (r, c), 1)
    return counts


def empty_regions(counts: np.ndarray) -> list[str]:
    """Names of the regions not covered by a cell count grid, in REGIONS order."""
    return [name for name, cells in REGIONS.items()
            if any(counts[r, c] < MIN_POINTS_PER_CELL for r, c in cells)]


def regions_filled(points_px: np.ndarray, counts: np.ndarray, image_size: tuple[int, int]) -> list[str]:
    """The empty regions that `points_px` would help fill (it adds points to an empty cell)."""
    new = cell_counts([points_px], image_size)
    out = []
    for name, cells in REGIONS.items():
        if any(counts[r, c] < MIN_POINTS_PER_CELL and new[r, c] > 0 for r, c in cells):
            out.append(name)
    return out


def uncovered_regions(pairs: Sequence[PairDetection], image_size: tuple[int, int]
                      ) -> dict[str, list[str]]:
    """{"left": [...], "right": [...]}: regions of each image the pairs' points never covered
    (PairDetection objects; every point a camera saw counts)."""
    out: dict[str, list[str]] = {}
    for side in SIDES:
        dets = [getattr(p, side) for p in pairs if getattr(p, side) is not None]
        out[side] = empty_regions(cell_counts([d.corners for d in dets], image_size))
    return out


def join_words(items: Sequence[str]) -> str:
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def regions_in_words(empty: dict[str, list[str]]) -> str:
    """'the top-left corner of both images, the right edge of the left image', or ''."""
    left, right = empty.get("left", []), empty.get("right", [])
    parts = []
    both = [r for r in REGIONS if r in left and r in right]
    if both:
        parts.append(f"{join_words(['the ' + r for r in both])} of both images")
    for side, regs in (("left", left), ("right", right)):
        only = [r for r in REGIONS if r in regs and r not in both]
        if only:
            parts.append(f"{join_words(['the ' + r for r in only])} of the {side} image")
    return join_words(parts)


@dataclass(frozen=True)
class Readiness:
    """How far a set of views is from being enough to calibrate, and what is missing.

    `counts` holds each camera's cell counts; tilt and size are the largest skew and the spread
    of sizes of the views' pose descriptors (0..1, ROS camera_calibration's measures)."""

    counts: dict[str, np.ndarray]  # side -> (GRID, GRID) int array
    image_size: tuple[int, int]
    pairs: int
    tilt: float
    size_spread: float

    @property
    def empty(self) -> dict[str, list[str]]:
        return {side: empty_regions(self.counts[side]) for side in SIDES}

    @property
    def required_empty(self) -> dict[str, list[str]]:
        """Empty regions readiness waits for (the far sides excepted)."""
        return {side: [r for r in regs if r not in FAR_SIDE[side]]
                for side, regs in self.empty.items()}

    @property
    def far_empty(self) -> dict[str, list[str]]:
        return {side: [r for r in regs if r in FAR_SIDE[side]]
                for side, regs in self.empty.items()}

    @property
    def regions_covered(self) -> bool:
        return not any(self.required_empty.values())

    @property
    def tilt_ok(self) -> bool:
        return self.tilt >= TILT_NEEDED

    @property
    def distance_ok(self) -> bool:
        return self.size_spread >= SIZE_SPREAD_NEEDED

    @property
    def ready(self) -> bool:
        return (self.regions_covered and self.tilt_ok and self.distance_ok
                and self.pairs >= MIN_PAIRS)

    def region_share(self, side: str) -> float:
        """Share of the nine regions of one image that are covered, 0..1."""
        return 1.0 - len(self.empty[side]) / len(REGIONS)

    def missing(self) -> list[str]:
        """What to do next, in words a person can follow (empty when ready)."""
        out = []
        words = regions_in_words(self.required_empty)
        if words:
            out.append(f"Move the board to {words} (not yet covered)")
        if not self.tilt_ok:
            out.append("tilt the board more (up to 40 degrees)")
        if not self.distance_ok:
            out.append("hold it nearer and farther")
        if self.pairs < MIN_PAIRS:
            more = MIN_PAIRS - self.pairs
            out.append(f"take at least {more} more pair{'' if more == 1 else 's'}")
        return out

    def advice(self) -> str:
        """What would still help once ready: the far sides, in words ('' when covered)."""
        words = regions_in_words(self.far_empty)
        if not words:
            return ""
        return (f"Also not yet covered: {words}. Both cameras see the board there only when it is "
                "far away (or, a ChArUco board, partly in view).")

    def summary(self) -> str:
        """One or two sentences for the Capture tab."""
        if self.ready:
            text = (f"Ready to calibrate: {self.pairs} pairs cover the images both cameras "
                    "share, with tilt and distance spread.")
        else:
            text = "Not ready yet: " + "; ".join(self.missing()) + "."
        extra = self.advice()
        return f"{text} {extra}" if extra else text


def readiness(pairs: Sequence[PairDetection | None], board: BoardSpec,
              image_size: tuple[int, int]) -> Readiness:
    """The Readiness of kept pairs (PairDetection objects in which both cameras saw the board)."""
    usable = [p for p in pairs if p is not None and p.found]
    counts: dict[str, np.ndarray] = {}
    for side in SIDES:
        counts[side] = cell_counts([getattr(p, side).corners for p in usable], image_size)
    poses = [q for q in (pair_pose(p, board) for p in usable) if q is not None]
    tilt = max((q.skew for q in poses), default=0.0)
    sizes = [q.size for q in poses]
    spread = (max(sizes) - min(sizes)) if sizes else 0.0
    return Readiness(counts, (int(image_size[0]), int(image_size[1])), len(usable), float(tilt),
                     float(spread))
