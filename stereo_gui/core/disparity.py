"""Disparity maps between the matcher and the final map: OpenCV's x16 fixed point divided out
(`fixed_to_px`, the one place), the matcher run on padded images, the local contrast
normalisation before matching, and after it the masks and filters: the two windows' agreement,
occlusion, blank surfaces, what the right camera cannot see, enlargement of a reduced map, and
the tests the hole filling applies.

Units: float32 px of the map's own images, NaN where invalid, unless said otherwise.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

DISP_SCALE = 16  # OpenCV stereo matchers return disparity x16 (4 fractional bits)


def fixed_to_px(disp16: np.ndarray, min_disparity: float, factor: float = 1.0) -> np.ndarray:
    """The one place where OpenCV's x16 fixed point becomes float pixels.

    Values below `min_disparity` (in the map's own pixels; OpenCV marks invalid pixels with
    (minDisparity-1)*16) become NaN. `factor` converts to full-resolution px (1/scale).
    """
    out = disp16.astype(np.float32)
    out *= np.float32(factor / DISP_SCALE)
    out[disp16 < min_disparity * DISP_SCALE] = np.nan
    return out


@functools.lru_cache(maxsize=8)
def _nan_image(h: int, w: int) -> np.ndarray:
    img = np.full((h, w), np.nan, np.float32)
    img.setflags(write=False)
    return img


def blank(disparity_px: np.ndarray, mask: np.ndarray, cols: int | None = None) -> None:
    """Set the pixels of a float32 H x W map where `mask` (bool or uint8) is set to NaN, in
    place (cv2.copyTo: many times faster than numpy's boolean assignment at 1280x720, the more so
    the more pixels are set). `cols`: the mask is set only in the leftmost `cols` columns (only
    those are looked at)."""
    if cols is not None and cols < disparity_px.shape[1]:
        disparity_px, mask = disparity_px[:, :max(0, cols)], mask[:, :max(0, cols)]
    if not (disparity_px.flags.c_contiguous or _rows_contiguous(disparity_px)) \
            or disparity_px.dtype != np.float32:
        disparity_px[mask.astype(bool, copy=False)] = np.nan  # (OpenCV would write a copy)
        return
    if mask.dtype == np.bool_:
        mask = mask.view(np.uint8)
    h, w = disparity_px.shape
    cv2.copyTo(_nan_image(h, w), mask, disparity_px)


def _rows_contiguous(a: np.ndarray) -> bool:
    """Each row of `a` contiguous and the rows evenly spaced (a column slice of a C-contiguous
    array): OpenCV then writes into it in place."""
    return a.ndim == 2 and a.strides[1] == a.itemsize and a.strides[0] >= a.shape[1] * a.itemsize


# `fill_scale` fills only the pixels of a hole at least this far from the final map's values
# (full-resolution px): at a hole's rim the larger windows carry a nearer surface past its edge.
# `stereo-gui bench --scenes` (13 scenes), quality with fill_scale 0.5: filling every hole
# raised the mean bad-2 from 8.7 % to 11.7 % and left 7 scenes outside their margins (2
# before); from 3 px in, 9.3 % at 1.2 points more density, every scene's verdict unchanged.
# That is for a fill on images at half the full resolution; on smaller ones the windows cover
# more of the scene and carry a surface as much farther past its edge (`fill_depth_px`)
FILL_DEPTH_PX = 3.0


def fill_depth_px(total_scale: float) -> float:
    """How far inside a hole (full-resolution px) a fill on images at `total_scale` of the full
    resolution may write: FILL_DEPTH_PX at a half, twice that at a quarter."""
    return FILL_DEPTH_PX * max(1.0, 0.5 / total_scale)

# a window is blank (nothing but sensor noise) when its pixels correlate with their neighbours
# BLANK_LAG_PX away by less than BLANK_MIN_CORRELATION, over windows of BLANK_HALF_PX (full-
# resolution px; both shrink with a preset's scale, the lag to no less than 1). On 49 x 49
# windows that is 7 standard deviations of what noise alone gives (3 with the correlation the
# rectification's interpolation leaves between neighbours)
BLANK_HALF_PX = 24
BLANK_LAG_PX = 2
BLANK_MIN_CORRELATION = 0.15
BLANK_NOISE_RATIO = 3.0  # ... and whose spread is at most this many times the noise level
SENSOR_NOISE_MAX = 4.0  # grey levels


def sensor_noise(gray: np.ndarray) -> float:
    """The image's noise level, grey levels (1 sigma): Immerkaer's estimate from a second-
    difference kernel's response, its robust median so that texture and edges (a minority of a
    frame) do not count. Resampled images (rectified, shrunk) come out lower than the sensor's:
    their noise is smoothed."""
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    if gray.dtype == np.uint8 and min(gray.shape[:2]) > 2:
        # a uint8 image's response is a whole number within +-4080: its median from a count of
        # each value (a fifth of np.median's time on a frame, the same value)
        response = cv2.filter2D(gray, cv2.CV_16S, kernel)[1:-1, 1:-1]
        counts = np.cumsum(np.bincount(np.abs(response).ravel()))
        n = int(counts[-1])
        ranks = np.array([(n - 1) // 2, n // 2]) + 1  # the middle one or two, counted from 1
        median = float(np.searchsorted(counts, ranks).mean())
    else:
        response = cv2.filter2D(gray.astype(np.float32), -1, kernel)[1:-1, 1:-1]
        median = float(np.median(np.abs(response)))
    return 1.4826 * median / 6.0  # (6: the kernel's norm)


def blank_mask(gray: np.ndarray, half: int, lag: int = BLANK_LAG_PX,
               min_correlation: float = BLANK_MIN_CORRELATION) -> np.ndarray:
    """Pixels whose window (of `half` around them) holds nothing but sensor noise: a grey-level
    spread within BLANK_NOISE_RATIO of the image's noise level (`sensor_noise`), and pixels
    that correlate with their neighbours `lag` px away (right and below) by less than
    `min_correlation`: texture at any contrast is smoother than noise, and a texture as fine as
    noise but stronger shows in the spread. Bool mask, the size of `gray`."""
    f = gray.astype(np.float32)
    k = (2 * half + 1, 2 * half + 1)
    h, w = f.shape
    mean = cv2.boxFilter(f, -1, k)
    spread2 = cv2.boxFilter(f * f, -1, k) - mean * mean
    # (a frame covered by a texture as fine as noise would give that texture's spread: no
    # camera's noise is larger than SENSOR_NOISE_MAX)
    limit = BLANK_NOISE_RATIO * min(max(sensor_noise(gray), 0.25), SENSOR_NOISE_MAX)
    weak = spread2 < np.float32(limit * limit)
    if not weak.any():
        return weak
    corr = np.zeros((h, w), np.float32)
    for a, b in ((f[:, :-lag], f[:, lag:]), (f[:-lag, :], f[lag:, :])):
        ma, mb = cv2.boxFilter(a, -1, k), cv2.boxFilter(b, -1, k)
        cov = cv2.boxFilter(a * b, -1, k) - ma * mb
        va = cv2.boxFilter(a * a, -1, k) - ma * ma
        vb = cv2.boxFilter(b * b, -1, k) - mb * mb
        r = cov / np.sqrt(np.maximum(va * vb, np.float32(1e-6)))
        corr[:r.shape[0], :r.shape[1]] += np.float32(0.5) * r
    return weak & (corr < np.float32(min_correlation))


NORMALIZED_SPREAD = 32.0  # grey levels one local standard deviation becomes
NORMALIZE_FLOOR = 16.0  # grey levels added to the local spread: a blank window stays flat


def local_contrast(gray: np.ndarray, window: int) -> np.ndarray:
    """A uint8 image's local contrast normalisation: 128 + NORMALIZED_SPREAD * (I - mean) /
    (spread + NORMALIZE_FLOOR), mean and spread over `window` x `window` (box filters),
    clipped to uint8. Gain, offset and any shading slower than the window leave it unchanged."""
    f = gray.astype(np.float32)
    k = (window, window)
    mean = cv2.boxFilter(f, -1, k)
    dev = cv2.subtract(f, mean)
    spread = cv2.sqrt(cv2.boxFilter(cv2.multiply(dev, dev), -1, k))
    out = cv2.divide(dev, cv2.add(spread, NORMALIZE_FLOOR), scale=NORMALIZED_SPREAD)
    normalized: np.ndarray = np.clip(out + np.float32(128.0), 0, 255).astype(np.uint8)
    return normalized


def agreement(d16: np.ndarray, d16_second: np.ndarray, min_disparity: int, agree_px: float,
              keep_px: tuple[float, float]) -> np.ndarray:
    """The final map of two windows' SGBM maps (x16 fixed point, same size, both searched from
    `min_disparity`): their mean in float px of those maps where both found a match, they agree
    within `agree_px` and the mean lies within `keep_px` = (smallest, largest) disparity kept;
    NaN elsewhere (a map's "no match" is NaN already, and the mean keeps it)."""
    a = fixed_to_px(d16, min_disparity)
    b = fixed_to_px(d16_second, min_disparity)
    out = cv2.addWeighted(a, 0.5, b, 0.5, 0.0)
    lo, hi = keep_px
    with np.errstate(invalid="ignore"):
        bad = (np.abs(a - b) > np.float32(agree_px)) | (out < np.float32(lo)) | \
            (out > np.float32(hi))
    blank(out, bad)
    return out


def occluded(disparity_px: np.ndarray, tolerance_px: float = 1.0, reach_px: int = 0
             ) -> np.ndarray:
    """Pixels of a left disparity map (px, NaN invalid) whose match in the right image is taken
    by a nearer surface: the right camera sees at column u = x - d only the nearest surface
    there, so a pixel is hidden from it when a pixel further right in the same row, more than
    `tolerance_px` nearer, matches at u or left of it (within half a pixel). SGBM's own
    left-right check compares only the winners of one cost volume, so a wrong far match just
    left of a surface can pass it. Bool mask.

    A surface is taken to go on under the `reach_px` pixels without a value left of it (the
    matching window's half and the edge margin leave them empty although they are the same
    surface), so that it hides what it would hide there.

    Pixels of one surface (disparities within the tolerance) cannot trigger this beyond the
    next `skip` - 1 columns (their matches move right with them), so the test looks at the
    columns from x + skip on: one running minimum of u from the right."""
    h, w = disparity_px.shape
    skip = int(math.floor(tolerance_px + 0.5)) + 1
    out = np.zeros((h, w), np.bool_)
    if w <= skip:
        return out
    cols = np.arange(w, dtype=np.float32)[None, :]
    d = disparity_px
    if reach_px > 0:
        # each empty pixel takes the disparity of the next valued pixel to its right, if that
        # lies within reach
        valued = ~np.isnan(d)
        nxt = next_valued_column(valued)
        near = (~valued) & (nxt - np.arange(w)[None, :] <= reach_px) & (nxt < w)
        rows = np.nonzero(near)
        d = d.copy()
        d[rows] = disparity_px[rows[0], nxt[rows]]
    u = cols - d
    u[np.isnan(u)] = np.inf
    right_min = np.minimum.accumulate(u[:, ::-1], axis=1)[:, ::-1]
    out[:, :-skip] = u[:, :-skip] + np.float32(0.5) >= right_min[:, skip:]
    return out


def enlarge(disparity: np.ndarray, size: tuple[int, int], smooth_px: float) -> np.ndarray:
    """A float map (NaN invalid) enlarged to `size` (w, h) without inventing values: linear
    interpolation where the four source pixels around a target pixel are all valid and the
    interpolated value stays within `smooth_px` of the nearest one (one surface), the nearest
    source pixel elsewhere (edges keep their step; a hole stays a hole). Values unchanged
    (multiply by the scale for full-resolution disparities)."""
    valid = cv2.compare(disparity, disparity, cv2.CMP_EQ)  # 255 where not NaN
    nearest = cv2.resize(disparity, size, interpolation=cv2.INTER_NEAREST)
    filled = disparity.copy()
    cv2.copyTo(np.zeros_like(disparity), cv2.bitwise_not(valid), filled)  # NaN -> 0 to interpolate
    linear = cv2.resize(filled, size, interpolation=cv2.INTER_LINEAR)
    # (OpenCV's stubs take no number for the second operand of divide and compare; cv2 does)
    support = cv2.resize(cv2.divide(valid, 255, dtype=cv2.CV_32F),  # type: ignore[call-overload]
                         size, interpolation=cv2.INTER_LINEAR)  # 1 where all four are valid
    # (OpenCV's element-wise operations, not numpy's: half the time on a frame; a comparison
    # with NaN is false in both)
    inside = cv2.compare(support, float(np.float32(0.999)),  # type: ignore[call-overload]
                         cv2.CMP_GT)
    smooth = cv2.compare(cv2.absdiff(linear, nearest),  # type: ignore[call-overload]
                         float(np.float32(smooth_px)), cv2.CMP_LE)
    use = cv2.bitwise_and(inside, smooth)
    cv2.copyTo(linear, use, nearest)
    return nearest


def compute_padded(matcher: cv2.StereoMatcher, reference: np.ndarray, other: np.ndarray, pad: int, side: str
                   ) -> np.ndarray:
    """`matcher.compute(reference, other)` with both images widened by `pad` black columns on
    `side` ("left" for a left matcher, "right" for a right matcher) and the result cropped back
    to the images' width (x16 fixed point, C-contiguous)."""
    if pad <= 0:
        return matcher.compute(reference, other)
    w = reference.shape[1]
    left, right = (pad, 0) if side == "left" else (0, pad)
    border = (0, 0, left, right, cv2.BORDER_CONSTANT)
    d = matcher.compute(cv2.copyMakeBorder(reference, *border, value=0),
                        cv2.copyMakeBorder(other, *border, value=0))
    return np.ascontiguousarray(d[:, left:left + w])


def next_valued_column(valued: np.ndarray) -> np.ndarray:
    """Each pixel's column of the nearest valued pixel at or right of it in its row (the row's
    width where there is none)."""
    w = valued.shape[1]
    nxt = np.where(valued, np.arange(w, dtype=np.int32)[None, :], np.int32(w))
    return np.minimum.accumulate(nxt[:, ::-1], axis=1)[:, ::-1]


def nearest_value_after(disparity_px: np.ndarray) -> np.ndarray:
    """Each pixel's nearest value at or right of it in its row (NaN where there is none)."""
    d = np.ascontiguousarray(disparity_px)
    h, w = d.shape
    nxt = next_valued_column(~np.isnan(d))
    flat = np.minimum(nxt, w - 1) + (np.arange(h, dtype=np.int32) * w)[:, None]
    out: np.ndarray = d.ravel()[flat.ravel()].reshape(h, w)
    out[nxt == w] = np.nan
    return out


def nearest_source(size: int, source_size: int) -> np.ndarray:
    """For each of `size` pixels along an axis, the pixel of `source_size` that a nearest-
    neighbour resize (cv2.INTER_NEAREST) takes it from."""
    index = np.arange(source_size, dtype=np.float32)[None, :]
    source: np.ndarray = cv2.resize(index, (size, 1), interpolation=cv2.INTER_NEAREST)[0]
    return source.astype(np.intp)


def sunk(values: np.ndarray, disparity_px: np.ndarray, tolerance_px: float) -> np.ndarray:
    """Where `values` lie farther (smaller) by more than `tolerance_px` than the nearest values of
    the map `disparity_px` (NaN holes) on both sides: left and right in the row, or above and
    below in the column. Bool mask."""
    def along_rows(v: np.ndarray, m: np.ndarray) -> np.ndarray:
        out = np.zeros(v.shape, np.bool_)
        rows = np.flatnonzero((~np.isnan(v)).any(axis=1))  # (only the rows with a value to test)
        if len(rows):
            v, m = v[rows], m[rows]
            before = nearest_value_after(m[:, ::-1])[:, ::-1]
            after = nearest_value_after(m)
            out[rows] = (before - v > tolerance_px) & (after - v > tolerance_px)
        return out

    with np.errstate(invalid="ignore"):  # (NaN compares False: no value on a side)
        farther: np.ndarray = (along_rows(values, disparity_px)
                               | along_rows(values.T, disparity_px.T).T)
        return farther


def unseen_columns(largest_disparity_px: float, margin_px: float, width: int) -> int:
    """How many columns from the left edge `unseen_mask` and `unseen_strip` can mark in a map
    whose disparities are at most `largest_disparity_px` (full-resolution px): a pixel the right
    camera cannot see has x < d + margin. (Two columns more than that, for rounding.)"""
    return int(min(width, max(0, math.floor(largest_disparity_px + margin_px) + 2)))


def unseen_strip(disparity_px: np.ndarray, margin_px: float = 0.0, cols: int | None = None
                 ) -> np.ndarray:
    """The strip at the left edge that the right camera cannot see, row by row: left of each
    row's first valid pixel, the columns x < d + margin with d that pixel's disparity (the
    surface there continues into the strip; nearer surfaces would only widen it).

    `cols` (`unseen_columns` of the map's largest disparity) limits the search to the columns
    where the strip can be; the mask returned is the same."""
    h, w = disparity_px.shape
    c = w if cols is None else max(0, min(w, cols))
    out = np.zeros((h, w), np.bool_)
    if c == 0:
        return out
    finite = np.isfinite(disparity_px[:, :c])
    first = np.argmax(finite, axis=1)  # 0 where a row has none in the band
    rows = np.arange(h)
    has = finite[rows, first]
    d = np.where(has, disparity_px[rows, first], 0.0)
    later = np.flatnonzero(~has) if c < w else ()
    if len(later):  # the row's first valid pixel lies right of the band: it sets the strip
        rest = np.isfinite(disparity_px[later, c:])
        at = np.argmax(rest, axis=1)
        found = rest[np.arange(len(later)), at]
        rows_f, at_f = later[found], at[found] + c
        first[rows_f], has[rows_f], d[rows_f] = at_f, True, disparity_px[rows_f, at_f]
    limit = np.minimum(first, np.ceil(d + margin_px - 0.5)).astype(np.int64)
    limit[~has] = 0
    out[:, :c] = np.arange(c)[None, :] < np.minimum(limit, c)[:, None]
    return out


def unseen_mask(disparity_px: np.ndarray, margin_px: float = 0.0, cols: int | None = None
                ) -> np.ndarray:
    """Pixels whose match x - d lies left of the right image (the right camera cannot see them),
    or within `margin_px` of its edge, where the matching block overlaps the padding and the
    image's border itself is what matches (full-resolution px). `cols`: as for `unseen_strip`
    (only those columns are computed; the rest cannot be set)."""
    h, w = disparity_px.shape
    if cols is not None and cols < w:
        out = np.zeros((h, w), np.bool_)
        out[:, :max(0, cols)] = unseen_mask(disparity_px[:, :max(0, cols)], margin_px)
        return out
    cols_x = np.arange(w, dtype=np.float32)[None, :]
    with np.errstate(invalid="ignore"):
        unseen: np.ndarray = (cols_x - disparity_px) < np.float32(margin_px - 0.5)
        return unseen
