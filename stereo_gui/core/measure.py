"""Distances at clicked pixels: patch statistics, subpixel refinement, triangulation through Q.

A click is a pixel (x, y) of the full-resolution rectified left image. Point mode takes the median
of the valid disparities in a square patch; object mode takes the region the WLS view shows as
one surface and reads the most frequent disparity in it. In point mode, when the rectified
images are at hand, the disparity is then refined to a fraction of a pixel by a 1-D Lucas-Kanade
alignment of the patch (SGBM's own subpixel estimate is biased towards whole pixels, "pixel
locking", which at 3 m is worth several centimetres). A reduced-resolution preset's
estimate is first replaced by a full-resolution re-match of a strip around the clicked row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import cv2
import numpy as np

from stereo_gui.core.align import (
    MAD_TO_SIGMA,
    QUANTUM_PX,
    REFINE_GROWTH,
    REFINE_HALF_PX,
    SURFACE_BAND_PX,
    Refinement,
    fit_plane,
    one_surface,
    refine_point,
    robust_spread,
    window_correlation,
)
from stereo_gui.core.disparity import (
    BLANK_HALF_PX,
    BLANK_LAG_PX,
    agreement,
    blank_mask,
    compute_padded,
    fixed_to_px,
    local_contrast,
    unseen_mask,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.uncertainty import Z95, depth_sigma_mm

PATCH_PX = 9  # default side of the square patch a measurement looks at, px (odd)



class Reason(StrEnum):
    """Why a reading has no distance. The values are the words files, exports and the JSON of
    `measure` carry, so a member equals (and is written as) its text."""

    NO_VALID_PIXELS = "no valid pixels"
    TOO_FEW = "too few valid pixels"
    NOT_SEEN = "not seen by the right camera"
    NOT_SEARCHED = "not searched (the reference loop's dead band at the left edge)"
    NO_TEXTURE = "no texture"
    TOO_NEAR = "too near"
    TOO_FAR = "too far"
    OUTSIDE = "outside the image"
    OUT_OF_FIT_RANGE = "out of disparity range"
    NO_METRIC_SCALE = "no metric scale"
    AMBIGUOUS = "ambiguous match"
    NEARER_EDGE = "plain surface beside a nearer edge"

    @classmethod
    def of(cls, text: str | None) -> Reason | None:
        """The member whose text is `text` (a reason read back from a file), None for none or
        for a text of no member."""
        try:
            return cls(text) if text else None
        except ValueError:
            return None

AMBIGUOUS_SHARE = 0.25  # a reading whose 95 % bound exceeds this share of its distance
# the parts of a reading's disparity uncertainty (1 sigma, px) that its refinement's own standard
# error does not see, measured on the simulated rig on walls and chessboards the tests and the
# benchmark do not use: a floor (interpolation in rectification and resampling), a share
# of the refinement's own correction (the rest of SGBM's bias towards whole pixels), a share of
# the disagreement between the 13 and 9 px windows (sharp, repeating or sparse texture), and,
# unrefined, SGBM's bias towards whole pixels
REFINED_FLOOR_PX = 0.02
REFINEMENT_MOVE_SHARE = 0.1
WINDOWS_SHARE = 3.0
PIXEL_LOCKING_PX = 0.19
# the alignment's standard error counts residuals as independent; neighbouring pixels' noise is
# not (both images are resampled: rectification, the alignment's own cubic interpolation), and
# on weak texture the error it leaves is this many times the standard error
STDERR_SCALE = 2.5
CORRELATED_STDERR_SCALE = STDERR_SCALE  # (see core.align.CORRELATION_LAG_PX)
MIN_VALID_FRACTION = 0.1  # share of the patch whose match must pass the checks
# a patch spread above this straddles surfaces (the rig's walls: at most 0.4 px; on a weak MJPG
# wall the map scatters more, which `one_surface` allows for)
EDGE_SPREAD_PX = 1.0
SCAN_MARGIN = 0.1  # correlation (NCC) by which a peak beyond the range must beat the estimate
# ... and the least correlation that peak needs to count at all: on a smooth wall whose texture
# is near the sensor noise every window's best correlation is 0.2-0.5, wherever it lies
SCAN_PEAK_MIN = 0.7
TEXTURE_MIN_STD = 3.0  # grey levels: below this a window holds little more than sensor noise
# (the check of presets without a second window; with one, a match is judged by the agreement)
# with one, a reading needs its aligned windows to correlate beyond what noise gives: the
# correlation's t statistic (correlation x sqrt(pixels), the pixels counted as STDERR_SCALE**2
# times fewer: resampled noise is not independent) at least this
TEXTURE_MIN_T = 3.0
# an alignment that runs off leaves the patch's own reading where at least this share of the
# patch matched on one surface and the click's window correlates at the map's estimate at least
# RICH_MIN_CORR (`bench --clicks`, 13 public scenes: 12 more clicks read, 10 of them right within
# 2 %; the rig's weak, quarter, MJPG and webcams walls, `bench --accuracy`: no reading changed)
RICH_MIN_SHARE = 0.5
RICH_MIN_CORR = 0.8


@dataclass(frozen=True)
class Measurement:
    """A distance reading at rectified pixel (x, y). Lengths in mm in the left rectified frame.

    `reason` says why `valid` is False. `spread_px` is the robust standard
    deviation of the disparities used; `expected_error_mm` is a 95 % bound of the error of Z:
    the disparity moved by `disparity_bound_px` (`disparity_bound_px()`) towards the far side,
    through triangulation or the fit in use. `method` is "triangulation" or the fitted model.
    """

    x: float
    y: float
    valid: bool
    reason: Reason | None = None
    disparity_px: float = float("nan")
    X_mm: float = float("nan")
    Y_mm: float = float("nan")
    Z_mm: float = float("nan")
    range_mm: float = float("nan")
    valid_fraction: float = 0.0
    spread_px: float = float("nan")
    expected_error_mm: float = float("nan")
    method: str = "triangulation"
    mode: str = "point"
    refined: bool = False
    raw_disparity_px: float = float("nan")  # the matcher's estimate before refinement
    disparity_bound_px: float = float("nan")  # 95 % bound of the disparity error, px

    def to_json_dict(self) -> dict[str, object]:
        """The fields of the `measure --json` contract (NaN -> None)."""
        def num(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "x": self.x, "y": self.y, "valid": self.valid,
            "reason": None if self.reason is None else str(self.reason),
            "disparity_px": num(self.disparity_px), "X_mm": num(self.X_mm), "Y_mm": num(self.Y_mm),
            "Z_mm": num(self.Z_mm), "range_mm": num(self.range_mm),
            "valid_fraction": float(self.valid_fraction),
            "expected_error_mm": num(self.expected_error_mm),
        }


def triangulate(calibration: StereoCalibration, x: float, y: float, d: float) -> tuple[float, float, float] | None:
    """(X, Y, Z) mm through Q for rectified pixel (x, y) with disparity d px; None at/behind infinity."""
    X, Y, Z, W = np.asarray(calibration.Q, np.float64) @ np.array([x, y, d, 1.0])
    if W <= 0 or not np.isfinite(W):
        return None
    return float(X / W), float(Y / W), float(Z / W)


def rematch_strip(result: PipelineResult, y: int, half: int) -> np.ndarray | None:
    """Full-resolution SGBM of a band of rows around y, checked as the preset checks its frame
    (with a second window: the two windows' agreement); float px (NaN invalid), band-sized.

    Returns the band's disparity (rows y-half .. y+half clipped), or None without a result.
    """
    p = result.params
    gl, gr = result.matched_gray()
    h = gl.shape[0]
    # rows beyond the patch give SGBM's vertical paths and the block window something to work on
    pad = half + 2 * max(p.block_size, p.check_block_size) + 8
    y0, y1 = max(0, y - pad), min(h, y + pad + 1)
    lo, hi = result.disparity_range_px
    lo_i = int(math.floor(lo))
    num = int(math.ceil((hi - lo_i + 1) / 16.0)) * 16
    sl, sr = gl[y0:y1], gr[y0:y1]
    if p.normalize_window:  # as the frame was matched, its window at full resolution
        window = max(3, int(round(p.normalize_window / result.match_scale)) | 1)
        sl, sr = local_contrast(sl, window), local_contrast(sr, window)

    def match(block: int) -> np.ndarray:
        area = (block / p.block_size) ** 2
        m = cv2.StereoSGBM.create(
            minDisparity=lo_i, numDisparities=num, blockSize=block, P1=round(p.p1_value * area),
            P2=round(p.p2_value * area), disp12MaxDiff=p.disp12_max_diff,
            preFilterCap=p.pre_filter_cap, uniquenessRatio=p.uniqueness_ratio,
            speckleWindowSize=p.speckle_window_size, speckleRange=p.speckle_range,
            mode=cv2.StereoSGBM_MODE_SGBM_3WAY)
        return compute_padded(m, sl, sr, lo_i + num if p.full_frame else 0, "left")

    d16 = match(p.block_size)
    if p.check_block_size:
        band = agreement(d16, match(p.check_block_size), lo_i, p.agree_px,
                         (lo_i + p.range_end_px, lo_i + num - 1 - p.range_end_px))
    else:
        band = fixed_to_px(d16, lo_i)
    if p.full_frame:
        band[unseen_mask(band, max(p.block_size, p.check_block_size) // 2 + 1)] = np.nan
    r0 = max(0, y - half) - y0
    r1 = min(h, y + half + 1) - y0
    return band[r0:r1]


def hidden_by_nearer(view_px: np.ndarray, x: int, y0: int, y1: int, d: float, tol: float
                     ) -> tuple[bool, float | None]:
    """Whether a reading of disparity `d` at column x (rows y0..y1 of its patch) is of a point the
    right camera cannot see: in most of the rows, a surface to its right nearer by more than
    `tol` px matches at the right image's column x - d or left of it (so the right camera sees
    that surface there, not the point). Second: where it is not, the disparity of the nearer
    surface that would hide the point in most of the rows if it went on under the empty run
    just left of it (None where none would).

    An empty run just left of a nearer surface is either the shadow that surface casts on the
    one behind (pixels of that surface the right camera cannot see: the point left of the shadow
    is seen) or that surface itself, unmatched. Where the run reaches into the nearer surface's
    own strip at the image's left edge (its match would fall left of the right image) it is
    taken as that surface, as the not-seen strip takes it: a wrong far match there, where the
    right camera sees nothing of the near surface, passes every check of its own, and even
    narrows the not-seen strip the views paint. Elsewhere the images decide (`measure_point`)."""
    h, w = view_px.shape
    if not 0 <= x < w - 1:
        return False, None
    u = x - d
    cols = np.arange(x + 1, w, dtype=np.float64)
    rows = view_px[max(0, y0):min(h, y1), x + 1:]
    hidden = 0
    under = []
    for row in rows:
        valued = np.isfinite(row)
        with np.errstate(invalid="ignore"):
            nearer = valued & (row > d + tol)
        if not nearer.any():
            continue
        j = int(np.argmax(nearer))
        before = np.flatnonzero(valued[:j])
        start = int(before[-1]) + 1 if before.size else 0  # the empty run before j begins here
        if x + 1 + start - float(row[j]) < 0:
            hidden += 1  # the run is the near surface's own unseen strip
        elif float(np.min(cols[nearer] - row[nearer])) <= u + 0.5:
            hidden += 1
        elif x + 1 + start - float(row[j]) <= u + 0.5:
            under.append(float(row[j]))
    n = max(1, len(rows))
    if 2 * hidden > n:
        return True, None
    return False, (float(np.median(under)) if 2 * (hidden + len(under)) > n else None)


def best_match_disparity(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int,
                         half: int) -> tuple[float, float, np.ndarray] | None:
    """Scan every disparity the image allows (0 .. x) for the window at (x, y) by normalised
    cross-correlation; return (best disparity px, its score, scores indexed by disparity).

    This is independent of the matcher's range, so it tells whether the surface lies beyond it.
    """
    h, w = left_gray.shape[:2]
    if not (0 <= x < w and 0 <= y < h):
        return None
    # the window clipped to the image: its disparities keep counting from the click's column
    y0, y1 = max(0, y - half), min(h, y + half + 1)
    x0, x1 = max(0, x - half), min(w, x + half + 1)
    tpl = left_gray[y0:y1, x0:x1]
    if tpl.size < 9 or float(tpl.std()) == 0.0:
        return None
    band = right_gray[y0:y1, 0:x1]
    scores = cv2.matchTemplate(band, tpl, cv2.TM_CCOEFF_NORMED)[0]  # index = x0 - d
    by_d = scores[::-1]  # index = disparity
    k = int(np.nanargmax(by_d))
    return float(k), float(by_d[k]), by_d


def _shows_nearer(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d: float,
                  nearer: float) -> bool:
    """Whether the REFINE_HALF_PX window at (x, y) matches the `nearer` surface's disparity at
    least about as well (within UNDER_MARGIN of correlation) as the reading's `d`: then the
    empty run between the point and that surface is that surface, unmatched, which hides the
    point; a point of the surface behind, seen left of the nearer one's shadow, matches its own
    disparity clearly better."""
    at_d, _ = window_correlation(left_gray, right_gray, x, y, d, REFINE_HALF_PX)
    # (the nearer surface's disparity is the map's where it begins: at the click it may lie up
    # to a pixel off, and on a weak wall the correlation's peak is narrower than that)
    best = max(window_correlation(left_gray, right_gray, x, y, nearer + s, REFINE_HALF_PX)
               for s in UNDER_SEARCH_PX)
    return best[1] > 0 and best[0] >= at_d - UNDER_MARGIN


def _centre_agrees(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int,
                   refinement: Refinement) -> bool:
    """Whether the REFINE_HALF_PX window at (x, y) correlates at the refined disparity about as
    well as the (larger) window the refinement aligned: at least SURROUND_CENTRE_MIN, and not
    more than SURROUND_CENTRE_DROP below it."""
    corr, _ = window_correlation(left_gray, right_gray, x, y, refinement.disparity_px,
                                 REFINE_HALF_PX)
    return corr >= max(SURROUND_CENTRE_MIN, refinement.correlation - SURROUND_CENTRE_DROP)


def _beyond_range(left_gray: np.ndarray, right_gray: np.ndarray, disp: np.ndarray, x: int, y: int,
                  d: float | None, half: int, span: tuple[float, float]) -> Reason | None:
    """TOO_NEAR or TOO_FAR when an exhaustive correlation scan puts the surface at (x, y) clearly
    beyond the matcher's `span` (px) and clearly better than at the estimate `d` (if any); else
    None.

    A small window on weak texture can correlate with a stretch of the right image far off by
    chance (MJPG's flat blocks do so at 0.7 and more), so a verdict beyond the range must hold
    for the largest window, up to the refinement's, over which the map shows one surface."""
    verdict = None
    for grown in (0,) + REFINE_GROWTH:
        h = max(half, 5, grown)
        if grown and verdict is None:
            break
        if grown and not one_surface(disp, x, y, h):
            continue
        scan = best_match_disparity(left_gray, right_gray, x, y, h)
        if scan is None:
            break
        d_best, score_best, by_d = scan
        k = -1 if d is None else int(round(d))
        at_estimate = (float(np.nanmax(by_d[max(0, k - 1):k + 2])) if 0 <= k < by_d.size
                       else -1.0)
        verdict = None
        if (score_best >= SCAN_PEAK_MIN and score_best > at_estimate + SCAN_MARGIN
                and not span[0] <= d_best <= span[1]):
            verdict = Reason.TOO_NEAR if d_best > span[1] else Reason.TOO_FAR
    return verdict


# ---- object mode ---------------------------------------------------------------------------
def surface_region(view_px: np.ndarray, x: int, y: int, window: int) -> np.ndarray | None:
    """Mask of the connected region around (x, y) that `view_px` (e.g. the WLS map) shows as one
    surface: a flood fill whose neighbour-to-neighbour tolerance comes from the map's own local
    smoothness (median step + 3 robust standard deviations of the steps near the click)."""
    h, w = view_px.shape
    if not np.isfinite(view_px[y, x]):
        return None
    y0, y1 = max(0, y - window), min(h, y + window + 1)
    x0, x1 = max(0, x - window), min(w, x + window + 1)
    local = view_px[y0:y1, x0:x1]
    steps = np.concatenate([np.abs(np.diff(local, axis=1)).ravel(), np.abs(np.diff(local, axis=0)).ravel()])
    steps = steps[np.isfinite(steps)]
    if steps.size:
        med = float(np.median(steps))
        tol = med + 3.0 * MAD_TO_SIGMA * float(np.median(np.abs(steps - med)))
    else:
        tol = 0.0
    tol = max(tol, QUANTUM_PX)
    img = np.nan_to_num(view_px, nan=-1e6).astype(np.float32)
    mask = np.zeros((h + 2, w + 2), np.uint8)
    cv2.floodFill(img, mask, (int(x), int(y)), 0, loDiff=tol, upDiff=tol,
                  flags=4 | cv2.FLOODFILL_MASK_ONLY | (1 << 8))
    return mask[1:-1, 1:-1].astype(bool)


def histogram_mode(values: np.ndarray) -> float:
    """Most frequent value with subpixel refinement: a parabola through the peak bin and its
    neighbours. Bin width by the Freedman-Diaconis rule, but not below the 1/16 px quantum."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return float("nan")
    q25, q75 = np.percentile(values, [25, 75])
    width = max(2.0 * (q75 - q25) / values.size ** (1.0 / 3.0), QUANTUM_PX)
    lo, hi = float(values.min()), float(values.max())
    nbins = max(1, int(math.ceil((hi - lo) / width)) + 1)
    counts, edges = np.histogram(values, bins=nbins, range=(lo - width / 2, lo - width / 2 + nbins * width))
    k = int(np.argmax(counts))
    centre = 0.5 * (edges[k] + edges[k + 1])
    if 0 < k < nbins - 1:
        c0, c1, c2 = counts[k - 1], counts[k], counts[k + 1]
        den = c0 - 2 * c1 + c2
        if den < 0:
            centre += 0.5 * (c0 - c2) / den * width
    return float(centre)


def reading_map(result: PipelineResult) -> np.ndarray:
    """The disparity map (px, NaN invalid) a reading takes its values from: the final map of a
    preset with a second window (checked by the two windows' agreement, what the views show
    and the exports write), else the matcher's raw map (checked by `consistent_pixels`)."""
    return result.final_px if result.params.check_block_size else result.disparity_px


def consistent_pixels(result: PipelineResult, y0: int, y1: int, x0: int, x1: int
                      ) -> np.ndarray | None:
    """Mask of the window's pixels of `reading_map` whose match passed the left-right check (the
    WLS filter's confidence above zero), or None when the map is checked already (a second
    window) or the preset has no right matcher to check with."""
    conf = result.wls_confidence
    if conf is None or result.params.check_block_size:
        return None
    return conf[y0:y1, x0:x1] > 0


def _frame_values_fit_around(result: PipelineResult, x: int, y: int, values: np.ndarray) -> bool:
    """Whether a patch's own values (`values`, px) lie on the surface the checked matches
    around it show (`surrounding_estimate`), within the frame's resolution: a reduced preset's
    values that its full-resolution strip could not confirm are read only so (a blob of wrong
    values in a dim MJPG corner read a wall at 0.5 m as 2.75 m; with this check 3 of 4 such
    readings on the rig's click scenes are refused, 256 of 310 right ones kept)."""
    # (with its check for an object the matcher missed, which needs the filled view: without
    # it, 2 of the 4 wrong readings, a wall at 0.5 m read as 1.15 m among them, passed)
    around = surrounding_estimate(result, x, y)
    return around is not None and abs(float(np.median(values)) - around) <= 2.0 / result.match_scale


SURROUND_GROWTH = (12, 24, 48)  # half-sizes of the region around a click whose patch is empty
SURROUND_MIN_SHARE = 0.1  # share of that region that must hold checked matches
SURROUND_INLIERS = 0.8  # share of those that must lie on one plane
SURROUND_FILL_PX = 2.0  # the filled view nearer than the surface by more than this: refused
# the click's own 13 px window must correlate at the reading at least this well, and not more
# than SURROUND_CENTRE_DROP below the window that aligned it (an object the matcher missed in
# front of the surface correlates about 0 there; measured: see the guide)
SURROUND_CENTRE_MIN = 0.25
UNDER_MARGIN = 0.1
UNDER_SEARCH_PX = tuple(np.arange(-1.0, 1.01, 0.25))
SURROUND_CENTRE_DROP = 0.35


# refusals of an empty patch that the surface around it may still answer: no match there, or the
# matches beside it put its match a few pixels inside the right image's edge (the images decide)
SURROUND_READS = (Reason.NO_VALID_PIXELS, Reason.TOO_FEW, Reason.NOT_SEEN)


def surrounding_estimate(result: PipelineResult, x: int, y: int) -> float | None:
    """Disparity (px) at (x, y) of the plane the checked matches around it lie on, from the
    smallest region (SURROUND_GROWTH) that holds enough of them on one plane; None when no region
    does. For a click whose own patch the matcher left empty: a starting estimate only, which
    the images must confirm (`refine_point`)."""
    fill = result.wls_px  # the filled view: without it, no check for a missed object (below)
    if fill is None:
        return None
    disp = reading_map(result)
    h, w = disp.shape
    for grown in SURROUND_GROWTH:
        y0, y1 = max(0, y - grown), min(h, y + grown + 1)
        x0, x1 = max(0, x - grown), min(w, x + grown + 1)
        win = disp[y0:y1, x0:x1]
        usable = np.isfinite(win)
        checked = consistent_pixels(result, y0, y1, x0, x1)
        if checked is not None:
            usable &= checked
        n = int(usable.sum())
        if n < max(9, SURROUND_MIN_SHARE * win.size):
            continue
        plane = fit_plane(win, usable, x0, y0, x, y, 3)
        resid, keep = plane.resid, plane.keep
        vx = np.nonzero(usable)[1]
        if not (keep.mean() >= SURROUND_INLIERS and robust_spread(resid[keep]) <= EDGE_SPREAD_PX):
            continue
        estimate = plane.at_point
        # the surface must lie on both sides of the click where either camera sees on: beside a
        # near object, the strip the object hides from the right camera has the object on one
        # side only (left of the click, the right camera sees nothing within `estimate` of the
        # image's edge)
        cols = vx[keep] + x0
        left_seen = x0 > 0 and x - grown > estimate
        if (left_seen and not (cols < x).any()) or (x1 < w and not (cols > x).any()):
            continue
        # the filled view (WLS: guided by the left image's edges, it spreads what the matcher
        # half-saw) shows nothing clearly nearer at the click: an object in front of the surface
        # that the checks threw out entirely still pulls the fill towards itself
        h6 = REFINE_HALF_PX
        near = fill[max(0, y - h6):y + h6 + 1, max(0, x - h6):x + h6 + 1]
        near = near[np.isfinite(near)]
        if near.size and float(np.median(near)) > estimate + SURROUND_FILL_PX:
            return None
        return estimate
    return None


# ---- the click's own region beside a nearer edge ----------------------------------------------
# A plain region (a painted wall, a white background) just beside a nearer object's edge: every
# window around the click holds the edge, the matcher's window aggregation carries the object's
# disparity a few pixels onto the plain side ("foreground fattening"), and the alignment follows
# the edge, the only detail there is. Its correlation is high and its bound small: a confident
# wrong reading (Shelves' wall above a paint can read at the can's 34 px against the wall's 28).
SEGMENT_TOL_GREY = 20.0  # grey levels from the click's own (3x3 smoothed) that are its region
SEGMENT_BORDER_PX = 2  # the blurred band at the region's border: the other side's structure
SEGMENT_MIN_SHARE = 0.3  # of the click's 13 px window: below it the click lies on texture
SEGMENT_REACH_PX = 48  # half the side of the area whose depth map tells the region's surface


def click_region(gray: np.ndarray, x: int, y: int, half: int) -> tuple[np.ndarray, int, int]:
    """The click's own region in the window of `half` around (x, y), clipped to the image: the
    pixels connected to the click through pixels within SEGMENT_TOL_GREY of its grey level (3x3
    smoothed), less a band of SEGMENT_BORDER_PX along the region's border. Returns the mask
    and the window's top-left corner (x0, y0)."""
    h, w = gray.shape[:2]
    y0, y1 = max(0, y - half), min(h, y + half + 1)
    x0, x1 = max(0, x - half), min(w, x + half + 1)
    crop = cv2.GaussianBlur(gray[y0:y1, x0:x1], (3, 3), 0)
    mask = np.zeros((y1 - y0 + 2, x1 - x0 + 2), np.uint8)
    cv2.floodFill(crop, mask, (x - x0, y - y0), 0, SEGMENT_TOL_GREY, SEGMENT_TOL_GREY,
                  4 | cv2.FLOODFILL_MASK_ONLY | cv2.FLOODFILL_FIXED_RANGE | (1 << 8))
    side = 2 * SEGMENT_BORDER_PX + 1
    region = cv2.erode(mask[1:-1, 1:-1], np.ones((side, side), np.uint8),
                       borderType=cv2.BORDER_REPLICATE)
    return region > 0, x0, y0


def _region_plane_at(disparity_px: np.ndarray, region: np.ndarray, x0: int, y0: int, x: int,
                     y: int) -> float | None:
    """The disparity at (x, y) of the plane the map's values over `region` (a mask of the window
    at x0, y0) lie on (least squares, three times with values off it by more than 3 robust sigma
    left out); None with fewer than 9 values."""
    win = disparity_px[y0:y0 + region.shape[0], x0:x0 + region.shape[1]]
    ok = region & np.isfinite(win)
    if int(ok.sum()) < 9:
        return None
    return fit_plane(win, ok, x0, y0, x, y, 3).at_point


def reads_nearer_edge(left_gray: np.ndarray, right_gray: np.ndarray, disparity_px: np.ndarray,
                      x: int, y: int, d: float, half: int) -> bool:
    """Whether a reading `d` (px) of the window of `half` around (x, y) is a nearer object's
    edge read beside a plain region of the click's own: the click lies in a region of one grey
    (`click_region`, at least SEGMENT_MIN_SHARE of its 13 px window) that does not fill the
    window and is plain (its pixels there spread less than TEXTURE_MIN_STD); the depth map over that region (SEGMENT_REACH_PX around) lies on a surface farther
    than `d` by more than SURFACE_BAND_PX at the click; and the region's own pixels in the
    window, aligned at `d`, share nothing with the right image that noise could not give
    (the texture check's statistic). Then the window's evidence is the edge, not the click's
    surface.

    A region of one grey on a textured surface (a plain square of a printed board) reads
    where its surroundings' texture puts it, on its own surface: the map over it agrees and the
    reading stands. A slanted region is judged by its plane, not its values' median."""
    reach = max(half, SEGMENT_REACH_PX)
    region, x0, y0 = click_region(left_gray, x, y, reach)
    c = REFINE_HALF_PX
    centre = region[max(0, y - y0 - c):y - y0 + c + 1, max(0, x - x0 - c):x - x0 + c + 1]
    if centre.size == 0 or float(centre.mean()) < SEGMENT_MIN_SHARE:
        return False  # the click lies on texture: the window is its own surface's
    # the window's part of the region
    wy0, wx0 = max(0, y - half) - y0, max(0, x - half) - x0
    own = region[wy0:y - y0 + half + 1, wx0:x - x0 + half + 1]
    if own.all():
        return False  # the window is all the click's region: the usual checks judge it
    ay0, ax0 = y0 + wy0, x0 + wx0
    left_own = left_gray[ay0:ay0 + own.shape[0], ax0:ax0 + own.shape[1]][own]
    if left_own.size >= 9 and float(np.std(left_own)) >= TEXTURE_MIN_STD:
        # a region of one grey on rich texture (a blob of it) holds texture of its own: not
        # plain (on the rig's textured boxes the rule refused 31 right readings beside edges)
        return False
    plane = _region_plane_at(disparity_px, region, x0, y0, x, y)
    if plane is None or plane >= d - SURFACE_BAND_PX:
        return False  # the region's surface is where the reading is (or nearer)
    w = left_gray.shape[1]
    cols = np.arange(ax0, ax0 + own.shape[1], dtype=np.float32)
    rows = np.arange(ay0, ay0 + own.shape[0], dtype=np.float32)
    own = own & ((cols - d >= 2) & (cols - d <= w - 3))[None, :]
    if int(own.sum()) < 9:
        return True
    map_x = np.tile(cols - np.float32(d), (rows.size, 1))
    map_y = np.repeat(rows[:, None], cols.size, axis=1)
    right = cv2.remap(right_gray, map_x, map_y, cv2.INTER_CUBIC,
                      borderMode=cv2.BORDER_REPLICATE)[own].astype(np.float32)
    left = left_gray[ay0:ay0 + own.shape[0], ax0:ax0 + own.shape[1]][own].astype(np.float32)
    a, b = left - left.mean(), right - right.mean()
    denom = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    corr = float((a * b).sum()) / denom if denom > 0 else 0.0
    return corr * math.sqrt(left.size) < TEXTURE_MIN_T * STDERR_SCALE


def has_texture(gray: np.ndarray, x: int, y: int, half: int) -> bool:
    """Whether the left window has anything to match: a spread of grey levels above what sensor
    noise alone gives (TEXTURE_MIN_STD)."""
    h, w = gray.shape[:2]
    win = gray[max(0, y - half):min(h, y + half + 1), max(0, x - half):min(w, x + half + 1)]
    return win.size > 0 and float(win.std()) >= TEXTURE_MIN_STD


def _estimate_from_right(result: PipelineResult, x: int, y: int, half: int) -> float | None:
    """The disparity of the nearest checked matches to the right of (x, y) in the window's rows
    (where a surface the right camera cannot see continues into view), or None."""
    disp = reading_map(result)
    h, w = disp.shape
    y0, y1 = max(0, y - half), min(h, y + half + 1)
    reach = int(math.ceil(result.disparity_range_px[1])) + 2 * half + 1
    x0, x1 = min(w, x + half + 1), min(w, x + half + 1 + reach)
    if x1 <= x0:
        return None
    band = disp[y0:y1, x0:x1]
    mask = np.isfinite(band)
    conf = consistent_pixels(result, y0, y1, x0, x1)
    if conf is not None:
        mask &= conf
    cols = np.flatnonzero(mask.any(axis=0))
    if cols.size == 0:
        return None
    first = cols[0]
    near = band[:, first:first + 2 * half + 1][mask[:, first:first + 2 * half + 1]]
    return float(np.median(near))


def is_blank(gray: np.ndarray, x: int, y: int) -> bool:
    """Whether the window around (x, y) holds nothing but sensor noise (`core.disparity.
    blank_mask`'s rule on the full-resolution image, for one window)."""
    h, w = gray.shape[:2]
    half = BLANK_HALF_PX
    y0, x0 = max(0, y - half), max(0, x - half)
    win = gray[y0:min(h, y + half + 1), x0:min(w, x + half + 1)]
    if win.shape[0] <= BLANK_LAG_PX or win.shape[1] <= BLANK_LAG_PX:
        return False
    mask = blank_mask(win, half, BLANK_LAG_PX)
    return bool(mask[y - y0, x - x0])


def _why_nothing(result: PipelineResult | None, x: int, y: int, half: int) -> Reason:
    """Reason for a patch without a usable match: the right camera cannot see the point, nothing
    to match, the surface beyond the range, or no match."""
    if result is None:
        return Reason.NO_VALID_PIXELS
    p = result.params
    if not p.full_frame and x < result.disparity_range_px[1] + 1 + p.block_size // 2:
        return Reason.NOT_SEARCHED
    gl, gr = result.matched_gray()
    d_est = _estimate_from_right(result, x, y, half)
    if d_est is not None and x - d_est < half:
        return Reason.NOT_SEEN
    if p.check_block_size and is_blank(gl, x, y):
        return Reason.NO_TEXTURE
    d_lo, d_hi = result.disparity_range_px
    step = 1.0 / result.match_scale
    beyond = _beyond_range(gl, gr, reading_map(result), x, y, None, half,
                           (d_lo - step, d_hi + step))
    return beyond or Reason.NO_VALID_PIXELS


def disparity_bound_px(refinement: Refinement | None, spread_px: float) -> float:
    """The 95 % bound of a reading's disparity error, px (see the guide, "How sure is a
    reading"). Refined: the alignment's own standard error, a floor for what it cannot see
    (interpolation in rectification and resampling) and a share of its own correction (the part
    of SGBM's bias towards whole pixels it leaves). Unrefined: the patch spread, with a floor
    for that bias. A patch whose disparities spread more than EDGE_SPREAD_PX straddles a depth
    edge: its spread counts too."""
    if refinement is not None:
        se = (CORRELATED_STDERR_SCALE * refinement.stderr_correlated_px
              if math.isfinite(refinement.stderr_correlated_px)
              else STDERR_SCALE * refinement.stderr_px)
        sigma = math.hypot(se, REFINED_FLOOR_PX,
                           REFINEMENT_MOVE_SHARE * refinement.moved_px,
                           WINDOWS_SHARE * refinement.windows_px)
        if spread_px > EDGE_SPREAD_PX:
            # the patch holds more than one surface (a depth edge): the reading may be either
            sigma = math.hypot(sigma, spread_px)
    else:
        sigma = math.hypot(spread_px, PIXEL_LOCKING_PX)
    return Z95 * sigma


def _depth_bound_mm(fb: float, d: float, bound_px: float) -> float:
    """The larger depth change of a disparity moved by +-bound (the far side is the larger)."""
    if not fb > 0:
        return float("nan")
    near = d - bound_px
    return fb / near - fb / d if near > 0 else float("inf")


# ---- the measurement -----------------------------------------------------------------------
@dataclass(frozen=True)
class _Click:
    """A click and its patch: (x, y) as given, the pixel (xi, yi) it falls in, the patch's side
    and half side, its rows y0:y1 and columns x0:x1 (cut at the image's edges), and the mode."""

    x: float
    y: float
    xi: int
    yi: int
    patch: int
    half: int
    y0: int
    y1: int
    x0: int
    x1: int
    mode: str

    @classmethod
    def at(cls, x: float, y: float, patch: int, mode: str, shape: tuple[int, ...]) -> _Click:
        h, w = shape[:2]
        xi, yi = int(round(x)), int(round(y))
        half = patch // 2
        return cls(x, y, xi, yi, patch, half, max(0, yi - half), min(h, yi + half + 1),
                   max(0, xi - half), min(w, xi + half + 1), mode)

    def invalid(self, reason: Reason, valid_fraction: float = 0.0) -> Measurement:
        """No reading, before the map gave a disparity."""
        return Measurement(self.x, self.y, False, reason, mode=self.mode,
                           valid_fraction=valid_fraction)


@dataclass(frozen=True)
class _MapReading:
    """What the map says at a click before the images are asked: the disparity `d` (the patch's
    median, the estimate from its surround, or the surface's most frequent value), the values
    it came from, the share of the patch (or surface) that held them, and why the patch itself
    held too few (`empty`, None when it held enough)."""

    d: float
    values: np.ndarray
    valid_fraction: float
    empty: Reason | None = None
    spread_px: float = field(init=False)  # the values' robust standard deviation, px

    def __post_init__(self) -> None:
        object.__setattr__(self, "spread_px", robust_spread(self.values))

    def refused(self, click: _Click, reason: Reason, d: float, method: str = "triangulation"
                ) -> Measurement:
        """No reading, with what the map gave (the disparity `d` so far)."""
        return Measurement(click.x, click.y, False, reason, disparity_px=d,
                           valid_fraction=self.valid_fraction, spread_px=self.spread_px,
                           method=method, mode=click.mode, raw_disparity_px=self.d)


def _check_request(patch: int, mode: str) -> None:
    if patch < 1:
        raise InputError(f"the patch size must be at least 1 px, not {patch}")
    if mode not in ("point", "object"):
        raise InputError(f"mode must be point or object, not {mode!r}")


def _inside(x: float, y: float, shape: tuple[int, ...]) -> bool:
    h, w = shape[:2]
    return 0 <= x <= w - 1 and 0 <= y <= h - 1


def measure_point(result: PipelineResult, x: float, y: float, patch: int = PATCH_PX,
                  mode: str = "point", calibration: StereoCalibration | None = None,
                  fit: FitResult | None = None, refine: bool = True, rematch: bool = True
                  ) -> Measurement:
    """Measure the distance at rectified pixel (x, y) of a processed frame: the patch's reading
    of the map (with a reduced-resolution preset, re-matched at full resolution:
    `_rematched`), refined to a fraction of a pixel and checked against the images (point mode:
    `_subpixel`, `_checked_in_images`), then located, with its bound (`_located`).
    `calibration`: instead of the frame's. `fit` is a regression.FitResult used instead of
    triangulation for Z. A bare disparity map: `measure_map`.
    """
    _check_request(patch, mode)
    disp = reading_map(result)
    calibration = calibration or result.calibration
    if calibration is None:
        raise InputError("a measurement on a bare disparity map needs the calibration")
    if not _inside(x, y, disp.shape):
        return Measurement(x, y, False, Reason.OUTSIDE, mode=mode)
    click = _Click.at(x, y, patch, mode, disp.shape)
    xi, yi = click.xi, click.yi
    if result.not_seen is not None and result.not_seen[yi, xi]:
        return click.invalid(Reason.NOT_SEEN)  # as every view shows it
    # (converted once: the checks below and the refinement all compare these)
    gl, gr = result.matched_gray()
    if not result.params.check_block_size and not has_texture(gl, xi, yi, click.half):
        return click.invalid(Reason.NO_TEXTURE)  # whatever matched there matched noise
    if mode == "point":
        read = _read_patch(result, disp, click, gl, gr, refine, rematch)
    else:
        read = _read_surface(result.final_px, disp, click, result)
    if isinstance(read, Measurement):
        return read
    d = read.d
    ref = None
    if refine and mode == "point":
        refined = _subpixel(gl, gr, disp, click, read)
        if isinstance(refined, Measurement):
            return refined
        ref = refined.refinement
        checked = _checked_in_images(gl, gr, disp, click, read, ref)
        if isinstance(checked, Measurement):
            return checked
        d = checked
    if xi - d < -0.5:
        return read.refused(click, Reason.NOT_SEEN, d)

    # the matcher cannot report disparities outside its range: a surface nearer than the range
    # allows gives a wrong match somewhere inside it. An exhaustive correlation scan of the
    # window, unlimited by the range, shows where the surface really is: clearly better beyond
    # the range than at the estimate. (Only clearly: on a repeating pattern, a chessboard say,
    # the pattern's period gives peaks nearly as high as the true one, and a wrong match inside
    # the range is what the left-right check is for.)
    d_lo, d_hi = result.disparity_range_px
    step = 1.0 / result.match_scale
    if mode == "point":
        beyond = _beyond_range(gl, gr, disp, xi, yi, d, click.half, (d_lo - step, d_hi + step))
        if beyond is not None:
            return read.refused(click, beyond, d)
    return _located(click, read, d, (d_lo, d_hi), step, disparity_bound_px(ref, read.spread_px),
                    calibration, fit, refined=ref is not None)


def measure_map(disparity_px: np.ndarray, x: float, y: float, patch: int = PATCH_PX,
                mode: str = "point", calibration: StereoCalibration | None = None,
                fit: FitResult | None = None) -> Measurement:
    """Measure the distance at pixel (x, y) of a bare disparity map (float px, NaN invalid):
    the patch's median (point mode) or its surface's most frequent value (object mode),
    triangulated through the calibration's Q (required) or `fit`; its bound is the patch's
    spread (at least SGBM's step). No images: no refinement."""
    _check_request(patch, mode)
    disp = np.asarray(disparity_px, np.float32)
    if calibration is None:
        raise InputError("a measurement on a bare disparity map needs the calibration")
    if not _inside(x, y, disp.shape):
        return Measurement(x, y, False, Reason.OUTSIDE, mode=mode)
    click = _Click.at(x, y, patch, mode, disp.shape)
    if mode == "point":
        window = disp[click.y0:click.y1, click.x0:click.x1]
        values = window[np.isfinite(window)]
        valid_fraction = values.size / window.size
        if valid_fraction < MIN_VALID_FRACTION:
            return click.invalid(Reason.NO_VALID_PIXELS if values.size == 0 else Reason.TOO_FEW,
                                 valid_fraction)
        read: _MapReading | Measurement = _MapReading(float(np.median(values)), values,
                                                      valid_fraction)
    else:
        read = _read_surface(disp, disp, click, None)
    if isinstance(read, Measurement):
        return read
    return _located(click, read, read.d, (-math.inf, math.inf), 1.0,
                    Z95 * max(read.spread_px, QUANTUM_PX), calibration, fit, refined=False)


# ---- the steps of a reading ----------------------------------------------------------------
def _read_patch(result: PipelineResult, disp: np.ndarray, click: _Click, gl: np.ndarray,
                gr: np.ndarray, refine: bool, rematch: bool) -> _MapReading | Measurement:
    """Point mode: the median of the patch's values that pass the frame's checks (re-matched at
    full resolution, `_rematched`), or, where too few do, the surface all around it
    (`surrounding_estimate`; only with `refine`, which must then confirm it); refused where a
    nearer surface hides the point from the right camera."""
    window = disp[click.y0:click.y1, click.x0:click.x1]
    usable = np.isfinite(window)
    checked = consistent_pixels(result, click.y0, click.y1, click.x0, click.x1)
    if checked is not None:
        usable &= checked
    if result.match_scale < 1.0 and rematch:
        window, usable = _rematched(result, click, window, usable)
    values = window[usable]
    valid_fraction = values.size / window.size
    empty = None
    if valid_fraction < MIN_VALID_FRACTION:
        # nothing, or a few pixels that passed where all around failed (an occlusion's
        # edge, a repeating pattern): no reading of the patch's own
        empty = (_why_nothing(result, click.xi, click.yi, click.half) if values.size == 0
                 else Reason.TOO_FEW)
        surround = None
        if empty in SURROUND_READS and refine:
            # the matcher found the surface all around: where the images confirm it
            # (below), the click reads it too
            surround = surrounding_estimate(result, click.xi, click.yi)
        if surround is None:
            return click.invalid(empty, valid_fraction)
        values = np.array([surround], np.float32)
    d = float(np.median(values))
    if result.params.full_frame:
        hidden, under = hidden_by_nearer(result.final_px, click.xi, click.y0, click.y1, d,
                                         max(1.0, 2.0 / result.match_scale))
        if hidden or (under is not None and _shows_nearer(
                gl, gr, click.xi, click.yi, d, under)):
            return click.invalid(Reason.NOT_SEEN, valid_fraction)
    return _MapReading(d, values, valid_fraction, empty)


def _rematched(result: PipelineResult, click: _Click, window: np.ndarray, usable: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The click re-match of a reduced-resolution frame: the patch's values (`window`, those
    `usable`) replaced by a full-resolution re-match of a strip around the clicked row
    (`rematch_strip`), counted where they agree with the frame's own (left-right checked)
    match to within its resolution."""
    band = rematch_strip(result, click.yi, click.half)
    if band is None:
        return window, usable
    band = band[:, click.x0:click.x1]
    # (where the strip found nothing at all, the frame's own values stand if they lie on the
    # surface around them: its reduced images hold the texture a full-resolution window of the
    # same size misses, and the refinement still checks them against the images. The strip's
    # values where the frame has none were tried and rejected: one right reading for one 50 %
    # off on the 13 scenes)
    own_only = (not np.isfinite(band).any() and usable.any()
                and _frame_values_fit_around(result, click.xi, click.yi, window[usable]))
    if own_only:
        return window, usable
    with np.errstate(invalid="ignore"):
        usable &= np.abs(band - window) <= 2.0 / result.match_scale
    usable &= np.isfinite(band)
    return band, usable


def _read_surface(view: np.ndarray, disp: np.ndarray, click: _Click,
                  result: PipelineResult | None) -> _MapReading | Measurement:
    """Object mode: the most frequent value of `disp` on the surface `view` shows around the
    click (`surface_region`)."""
    region = surface_region(view, click.xi, click.yi, window=max(4 * click.patch, 16))
    if region is None or not region.any():
        return click.invalid(_why_nothing(result, click.xi, click.yi, click.half))
    values = disp[region]
    values = values[np.isfinite(values)]
    valid_fraction = values.size / int(region.sum())
    if values.size == 0:
        return click.invalid(Reason.NO_VALID_PIXELS)
    return _MapReading(histogram_mode(values), values, valid_fraction)


@dataclass(frozen=True)
class _Subpixel:
    """The sub-pixel step's outcome: the alignment, or None where the patch is read unrefined."""

    refinement: Refinement | None


def _subpixel(gl: np.ndarray, gr: np.ndarray, disp: np.ndarray, click: _Click,
              read: _MapReading) -> _Subpixel | Measurement:
    """The sub-pixel step: the map's disparity refined by aligning the click's window
    (`refine_point`). A reading from the surround stands only where the alignment converges
    and the click's own window shows the same surface; an alignment that runs off contradicts
    the estimate (no reading) unless the patch is rich enough to be read unrefined."""
    xi, yi = click.xi, click.yi
    d = read.d
    ref = refine_point(gl, gr, xi, yi, d, click.half, surface=disp)
    if read.empty is not None:
        if ref is None or not ref.converged:
            return click.invalid(read.empty, read.valid_fraction)
        if not _centre_agrees(gl, gr, xi, yi, ref):
            # the click's own window does not show the surface the larger window aligned: an
            # object in front of it that the matcher missed, not that surface
            return click.invalid(read.empty, read.valid_fraction)
    if (ref is not None and not ref.converged and read.empty is None
            and read.valid_fraction >= RICH_MIN_SHARE and read.spread_px <= EDGE_SPREAD_PX
            and window_correlation(gl, gr, xi, yi, d, REFINE_HALF_PX)[0] >= RICH_MIN_CORR):
        # the alignment runs off, but the patch's matches agree on one surface and the
        # click's window matches there as only rich texture does: the map is right there
        # more often than not (a slanted or curved surface, a depth edge nearby, what a
        # window's one disparity cannot follow), and the patch is read unrefined, with an
        # unrefined reading's bound. On a weak wall, where the map's blobs are wrong and the
        # refusal earns its place, no window correlates so well
        ref = None
    if ref is not None and not ref.converged:
        # the images pull the match away from the matcher's estimate, and nowhere near it
        # do they settle: the estimate is contradicted, no reading
        return read.refused(click, Reason.AMBIGUOUS, d)
    return _Subpixel(ref)


def _checked_in_images(gl: np.ndarray, gr: np.ndarray, disp: np.ndarray, click: _Click,
                       read: _MapReading, ref: Refinement | None) -> float | Measurement:
    """The reading's disparity (refined, or the map's) where the aligned windows share more
    than noise could give them and the click's own plain region does not show that the window
    read a nearer edge."""
    xi, yi, half = click.xi, click.yi, click.half
    d = read.d
    if ref is not None:
        corr, pixels = ref.correlation, ref.pixels
        h_t = ref.half_px
    else:
        # not refined (no window converged): the match still has to show in the images,
        # over the largest window the refinement would have used on this surface
        h_t = max(half, REFINE_HALF_PX)
        for grown in REFINE_GROWTH:
            if not one_surface(disp, xi, yi, max(half, grown)):
                break
            h_t = max(half, grown)
        corr, pixels = window_correlation(gl, gr, xi, yi, d, h_t)
    if corr * math.sqrt(pixels) < TEXTURE_MIN_T * STDERR_SCALE:
        # the aligned windows share nothing the noise could not have given them
        return read.refused(click, Reason.NO_TEXTURE, d)
    if ref is not None:
        d = ref.disparity_px
    if reads_nearer_edge(gl, gr, disp, xi, yi, d, h_t):
        # the click's own plain region shows nothing; the window read a nearer edge
        return read.refused(click, Reason.NEARER_EDGE, d)
    return d


def _located(click: _Click, read: _MapReading, d: float, d_range: tuple[float, float],
             step: float, bound_px: float, calibration: StereoCalibration,
             fit: FitResult | None, refined: bool) -> Measurement:
    """Bounds into uncertainty: the reading at disparity `d` refused where the map's estimate
    lay at an end of the searched range `d_range` (within `step`), else located through
    the calibration's Q or `fit`, its disparity's 95 % bound (`bound_px`) turned into
    millimetres through the same, with the calibration's own uncertainty; refused where that
    bound spans too much of the distance."""
    d_lo, d_hi = d_range
    raw_d = read.d
    if raw_d >= d_hi - step:
        return read.refused(click, Reason.TOO_NEAR, d)
    if d_lo > 0 and raw_d <= d_lo + step:
        return read.refused(click, Reason.TOO_FAR, d)
    xyz = triangulate(calibration, click.x, click.y, d)
    if xyz is None:
        return read.refused(click, Reason.TOO_FAR, d)
    X, Y, Z = xyz
    method = "triangulation"
    if fit is not None:
        lo_s, hi_s = fit.disparity_span
        if not lo_s <= d <= hi_s:
            return read.refused(click, Reason.OUT_OF_FIT_RANGE, d, method=fit.model)
        z_fit = float(fit.predict(d))
        k = z_fit / Z
        X, Y, Z = X * k, Y * k, z_fit
        method = fit.model
        # the fit's own slope turns the disparity's uncertainty into millimetres
        expected = max(abs(float(fit.predict(d + s * bound_px)) - z_fit) for s in (-1.0, 1.0))
    elif not calibration.metric:
        # Hartley's rectification has no scale: triangulation would give a number in unknown
        # units; a regression fitted on true distances gives millimetres
        return read.refused(click, Reason.NO_METRIC_SCALE, d)
    else:
        expected = _depth_bound_mm(calibration.focal_px * calibration.rectified_baseline_mm, d,
                                   bound_px) * (Z / _z_of(calibration, d))
        expected = with_calibration_uncertainty(expected, calibration, click.x, click.y, d)
    if not (math.isfinite(expected) and expected <= AMBIGUOUS_SHARE * abs(Z)):
        # the match fits so loosely that its 95 % bound spans a large part of the distance
        # (texture near the sensor noise, shading both cameras share, a match into the strip
        # the right camera cannot see): a number that says so little is no reading
        return read.refused(click, Reason.AMBIGUOUS, d, method=method)
    rng = math.sqrt(X * X + Y * Y + Z * Z)
    return Measurement(click.x, click.y, True, None, disparity_px=d, X_mm=X, Y_mm=Y, Z_mm=Z,
                       range_mm=rng, valid_fraction=read.valid_fraction,
                       spread_px=read.spread_px, expected_error_mm=expected, method=method,
                       mode=click.mode, refined=refined, raw_disparity_px=raw_d,
                       disparity_bound_px=bound_px)


def _z_of(calibration: StereoCalibration, d: float) -> float:
    """f*B/d: the depth the Q matrix gives a disparity d on the optical axis (for scaling a
    bound to a Q with a principal-point offset)."""
    fb = calibration.focal_px * calibration.rectified_baseline_mm
    return fb / d if d > 0 and fb > 0 else float("nan")


def with_calibration_uncertainty(bound_mm: float, calibration: StereoCalibration, x: float,
                                 y: float, d: float) -> float:
    """A reading's 95 % bound with the calibration's own uncertainty at that pixel and disparity
    added: bound + 1.96 sigma_calibration (core.uncertainty.depth_sigma_mm). A calibration
    without an uncertainty (older files, rectified:F,B) keeps the bound as it is.

    Added, not in quadrature: the calibration's error is the same for every reading made with
    it (systematic), so a bound that must hold for the calibration at hand cannot let the
    random matching part average it away: in quadrature the bound falls short for a calibration
    whose focal lengths came out a little high, added it holds, for a bound only slightly
    wider."""
    if calibration.uncertainty is None or not math.isfinite(bound_mm):
        return bound_mm
    sigma = depth_sigma_mm(calibration, x, y, d)
    return bound_mm + Z95 * sigma if math.isfinite(sigma) else bound_mm
