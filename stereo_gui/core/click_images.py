"""What the rectified images say at a click: the best match of the click's window over every
disparity, whether the images show a nearer surface or the surface a larger window aligned,
the click's own plain region beside a nearer edge, texture and blank windows. Images are the
matched grey images at full resolution (PipelineResult.matched_gray). `core.measure` reads a
click with these; nothing here decides a reading.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stereo_gui.core.align import (
    REFINE_HALF_PX,
    SURFACE_BAND_PX,
    Refinement,
    fit_plane,
    window_correlation,
)
from stereo_gui.core.disparity import BLANK_HALF_PX, BLANK_LAG_PX, blank_mask

# the alignment's standard error counts residuals as independent; neighbouring pixels' noise is
# not (both images are resampled: rectification, the alignment's own cubic interpolation), and
# on weak texture the error it leaves is this many times the standard error
STDERR_SCALE = 2.5
TEXTURE_MIN_STD = 3.0  # grey levels: below this a window holds little more than sensor noise
# (the check of presets without a second window; with one, a match is judged by the agreement)
# with one, a reading needs its aligned windows to correlate beyond what noise gives: the
# correlation's t statistic (correlation x sqrt(pixels), the pixels counted as STDERR_SCALE**2
# times fewer: resampled noise is not independent) at least this
TEXTURE_MIN_T = 3.0


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


def shows_nearer(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d: float,
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


# the click's own 13 px window must correlate at the reading at least this well, and not more
# than SURROUND_CENTRE_DROP below the window that aligned it (an object the matcher missed in
# front of the surface correlates about 0 there; measured: see the guide)
SURROUND_CENTRE_MIN = 0.25
UNDER_MARGIN = 0.1
UNDER_SEARCH_PX = tuple(np.arange(-1.0, 1.01, 0.25))
SURROUND_CENTRE_DROP = 0.35


def centre_agrees(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int,
                   refinement: Refinement) -> bool:
    """Whether the REFINE_HALF_PX window at (x, y) correlates at the refined disparity about as
    well as the (larger) window the refinement aligned: at least SURROUND_CENTRE_MIN, and not
    more than SURROUND_CENTRE_DROP below it."""
    corr, _ = window_correlation(left_gray, right_gray, x, y, refinement.disparity_px,
                                 REFINE_HALF_PX)
    return corr >= max(SURROUND_CENTRE_MIN, refinement.correlation - SURROUND_CENTRE_DROP)


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
