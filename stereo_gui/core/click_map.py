"""What the frame's disparity map says around a click: the map a reading reads
(`reading_map`), its checked pixels, the surface around an empty patch, a nearer surface that
hides a point from the right camera, how far a patch scatters about its plane, the surface
region of object mode, and a full-resolution re-match of the rows around a click for a
reduced-resolution preset. Disparities are float32 px of the full-resolution rectified left
image, NaN invalid. `core.measure` reads a click from
these; nothing here decides a reading.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stereo_gui.core.align import (
    MAD_TO_SIGMA,
    QUANTUM_PX,
    REFINE_HALF_PX,
    fit_plane,
    robust_spread,
    window_values,
)
from stereo_gui.core.disparity import (
    agreement,
    compute_padded,
    fixed_to_px,
    local_contrast,
    unseen_mask,
)
from stereo_gui.core.matching import PipelineResult

# a patch spread above this straddles surfaces (the rig's walls: at most 0.4 px; on a weak MJPG
# wall the map scatters more, which `one_surface` allows for)
EDGE_SPREAD_PX = 1.0


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


# a patch with fewer checked values than this shows no plane to scatter about
PLANE_MIN_VALUES = 6


def plane_scatter_px(window: np.ndarray, usable: np.ndarray, x0: int, y0: int, x: int, y: int
                     ) -> float:
    """How far a patch's checked values (`window[usable]`, its top-left pixel at (x0, y0))
    scatter about the plane of disparity through them, px: the robust spread of the residuals
    of a least squares plane about (x, y), so that a floor's or a wall's slant is not counted.
    0 where fewer than PLANE_MIN_VALUES values show no plane."""
    if int(usable.sum()) < PLANE_MIN_VALUES:
        return 0.0
    return robust_spread(fit_plane(window, usable, x0, y0, x, y, 1).resid)


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


SURROUND_GROWTH = (12, 24, 48)  # half-sizes of the region around a click whose patch is empty
SURROUND_MIN_SHARE = 0.1  # share of that region that must hold checked matches
SURROUND_INLIERS = 0.8  # share of those that must lie on one plane
SURROUND_FILL_PX = 2.0  # the filled view nearer than the surface by more than this: refused
# ... unless a reduced preset's fill lies that far off the surface's own matches too and its
# disparity is at most this many times the surface's (`_fill_off_all_over`)
SURROUND_FILL_RATIO = 1.5


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
        near = window_values(fill, x, y, REFINE_HALF_PX)
        filled = float(np.median(near)) if near.size else -math.inf
        if filled > estimate + SURROUND_FILL_PX and not _fill_off_all_over(
                result, fill[y0:y1, x0:x1][usable][keep], filled, estimate):
            return None
        return estimate
    return None


def _fill_off_all_over(result: PipelineResult, fill_on_matches: np.ndarray, filled: float,
                       estimate: float) -> bool:
    """Whether a reduced preset's filled view, `filled` px at the click, lies as far off the
    surface's checked matches over the whole region (the fill there, `fill_on_matches`) as at
    the click, and no more than SURROUND_FILL_RATIO times the surface's disparity `estimate`:
    then the fill shows no object at the click. The filter runs on the reduced images with a
    right matcher at a smaller size still, and beside an edge its fill can lie 9-40 % off
    matches that are right all over a region (Adirondack's bottom right; the rig's demo
    scenes). There a click the matcher left empty reads the surface: `bench --clicks`, 13
    public scenes, 2 more read, both within 0.5 %; the rig's click scenes (6 seeds, 6,696
    clicks), 46 more, 41 within 2 %, 5 within 3 %, none beyond. Where the fill lies 68-246 %
    off, the matches are a wrong blob on a near wall (the rig's 0.5 m webcams wall, read
    130-380 % off without the ratio). At full resolution no right reading came of it, and one
    5 % off: not there."""
    values = fill_on_matches[np.isfinite(fill_on_matches)]
    return (result.match_scale < 1.0 and values.size > 0
            and filled <= float(np.median(values)) + SURROUND_FILL_PX
            and filled <= SURROUND_FILL_RATIO * estimate)


def estimate_from_right(result: PipelineResult, x: int, y: int, half: int) -> float | None:
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
