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
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np

from stereo_gui.core.align import (
    QUANTUM_PX,
    REFINE_GROWTH,
    REFINE_HALF_PX,
    Refinement,
    one_surface,
    refine_point,
    robust_spread,
    window_correlation,
)
from stereo_gui.core.click_images import (
    STDERR_SCALE,
    TEXTURE_MIN_STD,
    TEXTURE_MIN_T,
    best_match_disparity,
    centre_agrees,
    has_texture,
    is_blank,
    reads_nearer_edge,
    shows_nearer,
)
from stereo_gui.core.click_map import (
    EDGE_SPREAD_PX,
    consistent_pixels,
    estimate_from_right,
    hidden_by_nearer,
    histogram_mode,
    plane_scatter_px,
    reading_map,
    rematch_strip,
    surface_region,
    surrounding_estimate,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.reading_bound import (
    MAP_SCATTER_FLOOR_PX,
    depth_bound_mm,
    disparity_bound_px,
    with_calibration_uncertainty,
    with_map_scatter,
)
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration, triangulate
from stereo_gui.core.uncertainty import Z95

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
    NEARER_HIDES = "the nearer surface beside it would hide it"
    NOT_CONFIRMED = "not confirmed at full resolution"

    @classmethod
    def of(cls, text: str | None) -> Reason | None:
        """The member whose text is `text` (a reason read back from a file), None for none or
        for a text of no member."""
        try:
            return cls(text) if text else None
        except ValueError:
            return None

AMBIGUOUS_SHARE = 0.25  # a reading whose 95 % bound exceeds this share of its distance
MIN_VALID_FRACTION = 0.1  # share of the patch whose match must pass the checks
# a reduced preset's full-resolution strip whose values that agree with none of the frame's cover
# less than this share of the patch found little there (a few windows matched noise): the frame's
# own values stand as where it found nothing at all, whether or not a few of the strip's agree
# with them. Agreeing with none (live, the webcams wall, seeds 100-109): the worst seed read
# 89.0 -> 90.0 %, its worst error and RMS unchanged; the rig's click scenes (6 seeds): 42 more
# read (38 within 2 %, 1 at 2.2 %), 1 right lost. A few agreeing: the webcams wall read 93.5 ->
# 94.8 % (worst seed 90.0 -> 91.9 %), errors unchanged; the click scenes 39 more, all within 2 %;
# 13 public scenes 1 more, 40 % off (Midd1's white wall, where the map and the strip agree on a
# wrong value: plain OpenCV has none there, the quality preset refuses it)
STRIP_SCATTER_SHARE = 0.25
SCAN_MARGIN = 0.1  # correlation (NCC) by which a peak beyond the range must beat the estimate
# ... and the least correlation that peak needs to count at all: on a smooth wall whose texture
# is near the sensor noise every window's best correlation is 0.2-0.5, wherever it lies
SCAN_PEAK_MIN = 0.7
# an alignment that runs off leaves the patch's own reading where at least this share of the
# patch matched on one surface and the click's window correlates at the map's estimate at least
# RICH_MIN_CORR (`bench --clicks`, 13 public scenes: 12 more clicks read, 10 of them right within
# 2 %; the rig's weak, quarter, MJPG and webcams walls, `bench --accuracy`: no reading changed)
RICH_MIN_SHARE = 0.5
RICH_MIN_CORR = 0.8
# a refined reading is refused (unless rich) where the window past the second surface that
# stopped its growth settles further from it than this share of its disparity, beyond the two
# windows' noise (`Refinement.beyond_px`). Measured where it fired: wrong readings 1.9-5.3 % of
# the disparity apart (4.2-6.3 % off), right ones 0.1-1.9 % (rig walls, 10 seeds; the rig's
# click scenes, 6 seeds; the 13 public scenes)
BEYOND_SHARE = 0.015


@dataclass(frozen=True)
class Measurement:
    """A distance reading at rectified pixel (x, y). Lengths in mm in the left rectified frame.

    `reason` says why `valid` is False. `spread_px` is the robust standard
    deviation of the disparities used; `expected_error_mm` is a 95 % bound of the error of Z:
    the disparity moved by `disparity_bound_px` (`core.reading_bound`) towards the far side,
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


def _beyond_range(left_gray: np.ndarray, right_gray: np.ndarray, disp: np.ndarray, x: int, y: int,
                  d: float | None, half: int, span: tuple[float, float]) -> Reason | None:
    """TOO_NEAR or TOO_FAR when an exhaustive correlation scan puts the surface at (x, y) clearly
    beyond the matcher's `span` (px) and clearly better than at the estimate `d` (if any); else
    None.

    The matcher cannot report disparities outside its range: a surface nearer than the range
    allows gives a wrong match somewhere inside it. An exhaustive correlation scan of the window,
    unlimited by the range, shows where the surface really is: clearly better beyond the range
    than at the estimate. (Only clearly: on a repeating pattern, a chessboard say, the pattern's
    period gives peaks nearly as high as the true one, and a wrong match inside the range is what
    the left-right check is for.)

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


# refusals of an empty patch that the surface around it may still answer: no match there, or the
# matches beside it put its match a few pixels inside the right image's edge (the images decide)
SURROUND_READS = (Reason.NO_VALID_PIXELS, Reason.TOO_FEW, Reason.NOT_SEEN, Reason.NOT_CONFIRMED)


def _why_nothing(result: PipelineResult | None, x: int, y: int, half: int) -> Reason:
    """Reason for a patch without a usable match: the right camera cannot see the point, nothing
    to match, the surface beyond the range, or no match."""
    if result is None:
        return Reason.NO_VALID_PIXELS
    p = result.params
    if not p.full_frame and x < result.disparity_range_px[1] + 1 + p.block_size // 2:
        return Reason.NOT_SEARCHED
    gl, gr = result.matched_gray()
    d_est = estimate_from_right(result, x, y, half)
    if d_est is not None and x - d_est < half:
        return Reason.NOT_SEEN
    if p.check_block_size and is_blank(gl, x, y):
        return Reason.NO_TEXTURE
    d_lo, d_hi = result.disparity_range_px
    step = 1.0 / result.match_scale
    beyond = _beyond_range(gl, gr, reading_map(result), x, y, None, half,
                           (d_lo - step, d_hi + step))
    return beyond or Reason.NO_VALID_PIXELS


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
    # the values' robust spread about their plane of disparity, px (`plane_scatter_px`; 0 where
    # the patch held too few of its own)
    plane_scatter_px: float = 0.0
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

    # (a surface beyond the matcher's range gives a wrong match inside it: `_beyond_range`)
    d_lo, d_hi = result.disparity_range_px
    step = 1.0 / result.match_scale
    if mode == "point":
        beyond = _beyond_range(gl, gr, disp, xi, yi, d, click.half, (d_lo - step, d_hi + step))
        if beyond is not None:
            return read.refused(click, beyond, d)
    return _with_map_scatter(_settled(result, click, read, d, ref, (gl, gr, disp),
                                      (d_lo, d_hi), step, calibration, fit),
                             read, click, calibration, fit)


def _with_map_scatter(m: Measurement, read: _MapReading, click: _Click,
                      calibration: StereoCalibration, fit: FitResult | None) -> Measurement:
    """A refined reading with the scatter of the map's patch about its plane added to its
    bound (`with_map_scatter`). Added here, after every decision: the refusals and the patch's
    overruling judge the alignment's own bound. An unrefined reading's bound is the patch's
    spread already."""
    if not (m.valid and m.refined and read.plane_scatter_px > MAP_SCATTER_FLOOR_PX):
        return m
    bound_px = with_map_scatter(m.disparity_bound_px, read.plane_scatter_px)
    return replace(m, disparity_bound_px=bound_px,
                   expected_error_mm=_z_bound_mm(click, m.disparity_px, bound_px, calibration,
                                                 fit))


def _settled(result: PipelineResult, click: _Click, read: _MapReading, d: float,
             ref: Refinement | None, images: tuple[np.ndarray, np.ndarray, np.ndarray],
             d_range: tuple[float, float], step: float, calibration: StereoCalibration,
             fit: FitResult | None) -> Measurement:
    """The reading at disparity `d` located with its bound (`_located`). A refined reading whose
    bound spans too much of the distance falls back on the map's patch where that is rich
    (`_rich`); a refined one on a plain window that departs from the surface around it
    (`departs_on_plain_window`) is refused; one a rich patch overrules (`_patch_overrules`)
    reads the patch's median, with the alignment's wider bound."""
    gl, gr, disp = images
    located = _located(click, read, d, d_range, step, disparity_bound_px(ref, read.spread_px),
                       calibration, fit, refined=ref is not None)
    if ref is None:
        return located
    if located.reason is Reason.AMBIGUOUS and read.empty is None and _rich(read, gl, gr,
                                                                           click.xi, click.yi):
        # the alignment fits loosely (a slanted or curved surface, repeating texture, a depth
        # edge nearby), but the patch's matches agree on one surface and its window matches
        # there as only rich texture does: the patch is read unrefined, its bound widened by
        # the alignment's disagreement with it. Judged on `bench --clicks`, 13 public scenes:
        # 30 clicks read that were refused, 16 right within 2 %, 6 within 5 %, 8 beyond (where
        # the map itself is wrong: tsukuba's far wall, Plastic, Vintage's glare); the rig's
        # click scenes (6 seeds, 6,696 clicks a preset): 2 more read, both right
        bound_px = math.hypot(disparity_bound_px(None, read.spread_px), Z95 * abs(d - read.d))
        return _unrefined(click, read, images, d_range, step, bound_px, calibration, fit)
    if located.valid and departs_on_plain_window(result, gl, click.xi, click.yi, d):
        return read.refused(click, Reason.AMBIGUOUS, d)
    if located.valid and read.empty is None and _patch_overrules(read, d, located, gl, gr,
                                                                  click):
        patch = _unrefined(click, read, images, d_range, step, located.disparity_bound_px,
                           calibration, fit)
        return patch if patch.valid else located
    return located


def _unrefined(click: _Click, read: _MapReading,
               images: tuple[np.ndarray, np.ndarray, np.ndarray], d_range: tuple[float, float],
               step: float, bound_px: float, calibration: StereoCalibration,
               fit: FitResult | None) -> Measurement:
    """The patch's median read unrefined with `bound_px`, where the images bear it out
    (`_checked_in_images`)."""
    gl, gr, disp = images
    checked = _checked_in_images(gl, gr, disp, click, read, None)
    if isinstance(checked, Measurement):
        return checked
    return _located(click, read, read.d, d_range, step, bound_px, calibration, fit,
                    refined=False)


def _patch_overrules(read: _MapReading, d: float, located: Measurement, gl: np.ndarray,
                     gr: np.ndarray, click: _Click) -> bool:
    """Whether a rich patch (`_rich`) is surer than the alignment that refined it to `d` and
    contradicts it: the refined reading's bound is wider than an unrefined one's, and the two
    lie further apart than that narrower bound. The alignment fits loosely there (a slanted or
    curved surface its windows disagree on) and the map's patch lies nearer the truth: on the 13
    public scenes (`bench --clicks`) it changes 36 of live's and 49 of quality's readings, a
    median 0.65-0.77 px from the truth refined and 0.24-0.33 px unrefined (14 more within 1 %,
    8 and 6 more within 2 %). Where the two agree within the patch's bound the alignment stands
    (it undoes SGBM's bias towards whole pixels: a rig wall's corner read 0.01 % off refined,
    0.4 % unrefined); on a weak wall no patch is rich."""
    patch_bound = disparity_bound_px(None, read.spread_px)
    return (located.disparity_bound_px > patch_bound and abs(d - read.d) > patch_bound
            and _rich(read, gl, gr, click.xi, click.yi))


# a window with no texture beyond the noise (TEXTURE_MIN_STD) reads only the surface the checked
# matches around it show: a reading more than this share of that surface's disparity away (and
# more than two matched pixels) matched what the images do not hold. The rig's webcams walls
# (quality, 10 seeds kept aside): a 3 m wall read 1.39 m +- 32 mm in a dark MJPG corner, where
# the window's blocks correlate at 0.61 at the wrong disparity and 0.25 at the right one. The
# rule stops it and 3 more such readings (54-320 % off in distance) on the rig's click scenes,
# and refuses none of the right readings there, on the 13 public scenes or on the weak and
# quarter walls. (It needs the filled view, as `surrounding_estimate` does.)
PLAIN_DEPART_SHARE = 0.1


def departs_on_plain_window(result: PipelineResult, left_gray: np.ndarray, x: int, y: int,
                            d: float) -> bool:
    """Whether a reading of disparity `d` at (x, y) lies on a window of the left image that holds
    no texture beyond the noise (its REFINE_HALF_PX window spreads less than TEXTURE_MIN_STD
    grey levels) and departs from the surface the checked matches around it show
    (`surrounding_estimate`) by more than PLAIN_DEPART_SHARE of that surface's disparity and
    two matched pixels."""
    h = REFINE_HALF_PX
    window = left_gray[max(0, y - h):y + h + 1, max(0, x - h):x + h + 1]
    if float(window.std()) >= TEXTURE_MIN_STD:
        return False
    around = surrounding_estimate(result, x, y)
    return around is not None and abs(d - around) > max(2.0 / result.match_scale,
                                                         PLAIN_DEPART_SHARE * abs(around))


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
    frame_had = int(usable.sum()) >= MIN_VALID_FRACTION * usable.size
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
        if frame_had and empty in (Reason.NO_VALID_PIXELS, Reason.TOO_FEW):
            # the frame's map has values here (the views show them), but the re-match at
            # full resolution does not bear them out: say so, not that there is no match
            empty = Reason.NOT_CONFIRMED
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
        if hidden or (under is not None and shows_nearer(
                gl, gr, click.xi, click.yi, d, under)):
            # the map's nearer surface beside the click and the patch's farther reading cannot
            # both be right where the right camera sees the point: the point is hidden, or one
            # of the two is wrong. Not "not seen": on the 13 public scenes (`bench --clicks`)
            # both cameras saw the point at all 21 of these refusals; the patch's reading lay
            # within 2 % at 6 of them and was off at 15 (the refusal stays: it stops more wrong
            # readings than right)
            return click.invalid(Reason.NEARER_HIDES, valid_fraction)
    scatter = (plane_scatter_px(window, usable, click.x0, click.y0, click.xi, click.yi)
               if empty is None else 0.0)
    return _MapReading(d, values, valid_fraction, empty, scatter)


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
    # (the strip's values where the frame has none were tried and rejected: one right reading
    # for one 50 % off on the 13 scenes)
    found = np.isfinite(band)
    tol = 2.0 / result.match_scale
    with np.errstate(invalid="ignore"):
        agree = usable & found & (np.abs(band - window) <= tol)
    if int(agree.sum()) >= MIN_VALID_FRACTION * agree.size or not usable.any():
        return band, agree  # the strip confirms the frame (or the frame has nothing)
    if (found & ~agree).mean() >= STRIP_SCATTER_SHARE:
        return band, agree  # the strip contradicts the frame over much of the patch
    # The strip found little there: nothing, or a few values that agree with the frame's, and
    # any that do not cover less than STRIP_SCATTER_SHARE of the patch. The reduced
    # images hold the texture a full-resolution window of the same size misses (on a weak wall
    # it matches noise, often near the range's far end), and the frame's own values stand where
    # they lie on the surface the checked matches around show (`surrounding_estimate`, within
    # the frame's resolution; a blob of wrong values in a dim MJPG corner read a wall at 0.5 m
    # as 2.75 m: with this check 3 of 4 such readings on the rig's click scenes are refused,
    # 256 of 310 right ones kept); the refinement still checks them against the images
    around = surrounding_estimate(result, click.xi, click.yi)
    if around is None or abs(float(np.median(window[usable])) - around) > tol:
        return band, agree
    return window, usable


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
    the estimate (no reading) unless the patch is rich enough to be read unrefined, and so
    does a window that a larger one past a second surface contradicts (`beyond_px`)."""
    xi, yi = click.xi, click.yi
    d = read.d
    ref = refine_point(gl, gr, xi, yi, d, click.half, surface=disp)
    if read.empty is not None:
        if ref is None or not ref.converged:
            return click.invalid(read.empty, read.valid_fraction)
        if not centre_agrees(gl, gr, xi, yi, ref):
            # the click's own window does not show the surface the larger window aligned: an
            # object in front of it that the matcher missed, not that surface
            return click.invalid(read.empty, read.valid_fraction)
    if ref is not None and not ref.converged and read.empty is None and _rich(read, gl, gr, xi, yi):
        # the alignment runs off, but the patch's matches agree on one surface and the
        # click's window matches there as only rich texture does: the map is right there
        # more often than not (a slanted or curved surface, a depth edge nearby, what a
        # window's one disparity cannot follow), and the patch is read unrefined, with an
        # unrefined reading's bound. On a weak wall, where the map's blobs are wrong and the
        # refusal earns its place, no window correlates so well
        ref = None
    if (ref is not None and ref.converged and read.empty is None
            and ref.beyond_px > BEYOND_SHARE * ref.disparity_px
            and not _rich(read, gl, gr, xi, yi)):
        # past the second surface that stopped the window's growth, the surface is aligned
        # elsewhere than this window read it: a blob of wrong matches on a weak wall that the
        # small window followed (the patch is not rich enough to be read unrefined)
        return read.refused(click, Reason.AMBIGUOUS, d)
    if ref is not None and not ref.converged:
        # the images pull the match away from the matcher's estimate, and nowhere near it
        # do they settle: the estimate is contradicted, no reading
        return read.refused(click, Reason.AMBIGUOUS, d)
    return _Subpixel(ref)


def _rich(read: _MapReading, gl: np.ndarray, gr: np.ndarray, x: int, y: int) -> bool:
    """Whether the patch's matches agree on one surface (RICH_MIN_SHARE of it, spread within
    EDGE_SPREAD_PX) and the click's window correlates at the map's estimate as only rich texture
    does (RICH_MIN_CORR): where the map is right more often than an alignment that runs off or
    fits loosely."""
    return (read.valid_fraction >= RICH_MIN_SHARE and read.spread_px <= EDGE_SPREAD_PX
            and window_correlation(gl, gr, x, y, read.d, REFINE_HALF_PX)[0] >= RICH_MIN_CORR)


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
        # the aligned windows share nothing the noise could not have given them: the window
        # has nothing to match, or, where it has texture, the two views differ there too much
        # to bear the match out (on the 13 public scenes: teddy, tsukuba and Aloe, 8 windows of
        # 8-21 grey levels' spread correlating 0.3-0.58 even at the true disparity)
        reason = Reason.AMBIGUOUS if has_texture(gl, xi, yi, half) else Reason.NO_TEXTURE
        return read.refused(click, reason, d)
    if ref is not None:
        d = ref.disparity_px
    if reads_nearer_edge(gl, gr, disp, xi, yi, d, h_t):
        # the click's own plain region shows nothing; the window read a nearer edge
        return read.refused(click, Reason.NEARER_EDGE, d)
    return d


def _z_bound_mm(click: _Click, d: float, bound_px: float, calibration: StereoCalibration,
                fit: FitResult | None) -> float:
    """A disparity bound at the click turned into millimetres of Z: through the fit's own slope,
    or the calibration's triangulation with its own uncertainty added."""
    if fit is not None:
        z_fit = float(fit.predict(d))
        return max(abs(float(fit.predict(d + s * bound_px)) - z_fit) for s in (-1.0, 1.0))
    expected = depth_bound_mm(calibration, click.x, click.y, d, bound_px)
    return with_calibration_uncertainty(expected, calibration, click.x, click.y, d)


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
    elif not calibration.metric:
        # Hartley's rectification has no scale: triangulation would give a number in unknown
        # units; a regression fitted on true distances gives millimetres
        return read.refused(click, Reason.NO_METRIC_SCALE, d)
    expected = _z_bound_mm(click, d, bound_px, calibration, fit)
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


