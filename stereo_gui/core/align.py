"""The alignment behind a reading: a window of the left image aligned with the right one to a
fraction of a pixel (a 1-D Lucas-Kanade fit of disparity, gain, offset and the rows' offset, along
the plane the depth map shows where a surface is slanted), the window grown on weak texture while
the map holds one surface, and the standard error of what it finds. `core.measure` reads a click
through it; nothing here knows of clicks, calibrations or reasons."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from stereo_gui.core.disparity import DISP_SCALE
from stereo_gui.core.uncertainty import Z95

QUANTUM_PX = 1.0 / DISP_SCALE  # SGBM's step: no estimate is better than that unrefined
MAD_TO_SIGMA = 1.4826  # median absolute deviation -> standard deviation for normal noise

# the bound uses the standard error that counts the residuals' correlation up to
# CORRELATION_LAG_PX apart (a JPEG block's size: MJPG webcams leave 8 x 8 blocks whose errors the
# independent count misses), with the same scale (on the rig's usual and weak walls it is 0.84-1.05
# times the independent one, on MJPG walls about 1.5 times; `bench --accuracy`: the +- covers the
# truth on MJPG walls at 95-97 % of the points, at 82-90 % with the independent count)
CORRELATION_LAG_PX = 8
REFINE_MAX_SHIFT_PX = 2.0  # how far the refinement may move from the matcher's estimate
REFINE_HALF_PX = 6  # the refinement aligns a 13 x 13 window around the point
# ... and where that is not precise to REFINE_PRECISE_PX (weak texture), windows of these halves
# (up to 193 x 193: on MJPG walls the error is shared within 8 x 8 blocks, and only many blocks
# average it out; `bench --accuracy`, MJPG at 3 m: RMS 1.17 % with 49 x 49, 0.61-0.64 % with
# 97 x 97, 0.44-0.45 % with 193 x 193; two webcams' wall at 0.5-3 m: RMS 0.44-0.49 % with 97 x 97,
# 0.26-0.29 % with 193 x 193)
REFINE_GROWTH = (12, 24, 48, 96)
REFINE_PRECISE_PX = 0.03
# a smaller window that settled further than this from the matcher's estimate is where a larger
# window starts again when it does not settle from the estimate
REFINE_RESTART_PX = 0.5
# Gauss-Newton steps an alignment may take: on weak MJPG texture a 49 px window closes in on its
# minimum slowly (each step a fifth of the way), and one stopped at 20 steps was taken for
# unsettled while the wrong smaller window stood
REFINE_ITERATIONS = 60
# a real rig's rectification leaves its rows this far apart at most (Middlebury 2014's scenes:
# 0.2 px on average, 0.4 px at most); the alignment finds the offset of each window's rows
MAX_ROW_SHIFT_PX = 1.0
ROW_MARGIN_PX = 4  # rows of the right image beyond the window, for that offset and the kernel
# a grown window is aligned along the slope of the plane the map shows in it (a slanted or
# curved surface) where that plane departs from its centre's disparity by SLOPE_MIN_PX or more at
# the window's edge (less: a wall facing the rig, whose map's slopes are its noise), by at most
# SLANT_REACH_PX
SLOPE_MIN_PX = 1.0
SLANT_REACH_PX = 8
SLOPE_FIT_SHARE = 0.5  # ... and the plane leaves its values at most half as scattered
# a window of the map holds one surface when this share of its values lies within this distance
# of their median (`one_surface`)
SURFACE_SHARE = 0.8
SURFACE_BAND_PX = 2.0


def robust_spread(values: np.ndarray) -> float:
    """Robust standard deviation (scaled median absolute deviation), px."""
    if values.size < 2:
        return 0.0
    return float(MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))))


def _mad_about_zero(resid: np.ndarray) -> float:
    return MAD_TO_SIGMA * float(np.median(np.abs(resid)))


@dataclass(frozen=True)
class PlaneFit:
    """A plane of disparity through a window's values: its value at the point it was fitted
    about (px), its slopes along x and y (px per px), each value's residual, and which values it
    kept (those within 3 robust sigma of it at the last round)."""

    at_point: float
    gx: float
    gy: float
    resid: np.ndarray
    keep: np.ndarray


def fit_plane(win: np.ndarray, ok: np.ndarray, x0: int, y0: int, x: int, y: int, rounds: int,
              about_median: bool = False) -> PlaneFit:
    """Least squares plane through the values `win[ok]` (a window whose top-left pixel is
    (x0, y0)) about the point (x, y), `rounds` times with the values off it by more than 3 robust
    sigma left out: the residuals' median absolute deviation about zero, or about their median
    (`about_median`), never below SGBM's step."""
    vy, vx = np.nonzero(ok)
    A = np.column_stack([np.ones(vx.size), vx + x0 - x, vy + y0 - y]).astype(np.float64)
    b = win[ok].astype(np.float64)
    keep = np.ones(b.size, bool)
    spread = robust_spread if about_median else _mad_about_zero
    for _ in range(rounds):
        sol, *_ = np.linalg.lstsq(A[keep], b[keep], rcond=None)
        resid = b - A @ sol
        keep = np.abs(resid) <= 3.0 * max(spread(resid[keep]), QUANTUM_PX)
    return PlaneFit(float(sol[0]), float(sol[1]), float(sol[2]), resid, keep)


@dataclass(frozen=True)
class Refinement:
    """A refined disparity (px), its standard error from the fit's residuals (px, 1 sigma),
    whether it converged, and how far it moved from the starting estimate (px)."""

    disparity_px: float
    stderr_px: float
    converged: bool
    moved_px: float = 0.0
    # correlation of the left window with the aligned right one, and the window's pixel count
    correlation: float = float("nan")
    pixels: int = 0
    windows_px: float = 0.0  # how far the patch's own window disagrees (refine_point)
    # the standard error with the residuals' correlation between neighbouring pixels counted
    # (`correlated_stderr`): what the bound uses; NaN where not computed
    stderr_correlated_px: float = float("nan")
    # the alignment moved further than it may from the starting estimate: the images put the
    # surface elsewhere than the matcher did
    ran_off: bool = False
    half_px: int = 0  # half the side of the window aligned
    # where the growth stopped at a window holding two surfaces while still imprecise: how far
    # the next larger window over one surface settles from this reading, beyond what the two
    # windows' noise explains (`_beyond_two_surfaces`); 0 where it agrees or was not looked at
    beyond_px: float = 0.0


def refine_disparity(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d0: float,
                     half: int, max_shift_px: float | None = None,
                     iterations: int | None = None,
                     slope: tuple[float, float] = (0.0, 0.0)) -> Refinement:
    """1-D Lucas-Kanade alignment of the left window centred on (x, y) with the right image.

    Model: L(u, v) = a * R(u - d, v + e) + b over the window (a, b absorb gain and offset
    differences between the cameras; e, a vertical offset of at most MAX_ROW_SHIFT_PX, what a
    real rig's rectification leaves between its rows), solved by Gauss-Newton for d starting at
    d0, with bicubic resampling of the right image. With a `slope` (gx, gy) the window is aligned
    along a plane of disparity, d + gx (u - x) + gy (v - y), and d is its value at the centre.
    Returns the disparity and its standard error from the fit's residuals. `max_shift_px`
    (default: half the window) bounds how far it may move from d0.
    """
    if iterations is None:
        iterations = REFINE_ITERATIONS
    if max_shift_px is None:
        max_shift_px = float(half)
    # right-image strip that can hold every shifted window, with a margin for the cubic kernel
    margin = int(math.ceil(max_shift_px)) + 3 + int(
        math.ceil((abs(slope[0]) + abs(slope[1])) * half))
    win = _Windows.around(left_gray, right_gray, x, y, d0, half, margin)
    if win is None:
        return Refinement(d0, float("inf"), False)
    fit = _gauss_newton(win, x, y, d0, slope, max_shift_px, iterations)
    if isinstance(fit, Refinement):
        return fit
    Rc = fit.Rc
    if fit.e != 0.0:
        # the texture's evidence is judged without the row offset's fit: a free offset lets
        # noise correlate a little better, and weak texture at the threshold would pass on it
        map_y = np.repeat(win.vs[:, None], fit.map_x.shape[1], axis=1)
        Rc = cv2.remap(win.R, fit.map_x, map_y, cv2.INTER_CUBIC,
                       borderMode=cv2.BORDER_REPLICATE)[1:-1, 1:-1]
    Lf = win.Lf
    rc = Rc.reshape(-1).astype(np.float64)
    denom = float(np.std(rc) * np.std(Lf))
    corr = float(np.mean((rc - rc.mean()) * (Lf - Lf.mean())) / denom) if denom > 0 else 0.0
    correlated = (correlated_stderr(fit.A, fit.resid, win.L.shape) / abs(fit.a) if fit.converged
                  else float("nan"))
    return Refinement(fit.d, fit.stderr, fit.converged, abs(fit.d - d0), corr, int(Lf.size),
                      stderr_correlated_px=correlated, half_px=half)


@dataclass(frozen=True, eq=False)
class _Windows:
    """What an alignment compares: the left window (`L`, rows y0:y1, columns x0:x1; `Lf` its
    pixels as float64, row by row) and the strip of the right image that holds every shifted
    window (`R`, from column rx0 and row ry0); `vs` the window's rows and one beyond each side
    in the strip's row coordinates."""

    L: np.ndarray
    Lf: np.ndarray
    R: np.ndarray
    x0: int
    x1: int
    y0: int
    y1: int
    rx0: int
    vs: np.ndarray

    @classmethod
    def around(cls, left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d0: float,
               half: int, margin: int) -> _Windows | None:
        """The windows around (x, y) at disparity d0, or None where too little of the window
        is left or its strip leaves the right image."""
        h, w = left_gray.shape[:2]
        y0, y1 = max(0, y - half), min(h, y + half + 1)
        # near the edges of the right image the window keeps only the columns whose match (with
        # the margin) stays inside it, so that a point the right camera sees close to its edge
        # is still refined (with a narrower window) instead of being read off the matcher's
        # whole pixels
        x0 = max(0, x - half, int(math.ceil(d0 + margin)))
        x1 = min(w, x + half + 1, int(math.floor(w + d0 - margin)))
        # (a point the right camera sees within the margin of its edge is refined on the
        # window's columns beside it: the same surface, a few pixels over)
        if not x0 - margin <= x < x1:
            return None
        L = left_gray[y0:y1, x0:x1].astype(np.float32)
        if L.size < 9 or x1 - x0 < 3:
            return None
        rx0 = int(math.floor(x0 - d0 - margin))
        rx1 = int(math.ceil(x1 - d0 + margin))
        if rx0 < 0 or rx1 > w:
            return None
        ry0, ry1 = max(0, y0 - ROW_MARGIN_PX), min(h, y1 + ROW_MARGIN_PX)
        R = right_gray[ry0:ry1, rx0:rx1].astype(np.float32)
        vs = np.arange(y0 - 1, y1 + 1, dtype=np.float32) - ry0  # a row beyond each side: d/dv
        return cls(L, L.reshape(-1).astype(np.float64), R, x0, x1, y0, y1, rx0, vs)


@dataclass(frozen=True, eq=False)
class _Fit:
    """Where the Gauss-Newton iterations stopped: disparity `d` and row offset `e`, the
    disparity's standard error, whether the steps settled, and the last step's remap (`map_x`),
    resampled right window (`Rc`), design matrix, residuals and gain `a`."""

    d: float
    e: float
    stderr: float
    converged: bool
    map_x: np.ndarray
    Rc: np.ndarray
    A: np.ndarray
    resid: np.ndarray
    a: float


def _gauss_newton(win: _Windows, x: int, y: int, d0: float, slope: tuple[float, float],
                  max_shift_px: float, iterations: int) -> _Fit | Refinement:
    """The alignment's iterations (see `refine_disparity`); an unconverged Refinement where the
    gain vanishes, the disparity runs further than `max_shift_px` from d0 (`ran_off`) or the
    fit is singular."""
    L, Lf, R, rx0, vs = win.L, win.Lf, win.R, win.rx0, win.vs
    d = float(d0)
    e = 0.0
    stderr = float("inf")
    converged = False
    ones = np.ones(L.size, np.float64)
    gx, gy = slope
    u_ext = np.arange(win.x0 - 1, win.x1 + 1, dtype=np.float32)
    v_ext = np.arange(win.y0 - 1, win.y1 + 1, dtype=np.float32)
    du, dv = u_ext[None, :] - np.float32(x), v_ext[:, None] - np.float32(y)
    for _ in range(iterations):
        disparity = np.float32(d) + np.float32(gx) * du + np.float32(gy) * dv
        map_x = (u_ext[None, :] - disparity - np.float32(rx0)).astype(np.float32)
        map_y = np.repeat((vs + np.float32(e))[:, None], map_x.shape[1], axis=1)
        Rw = cv2.remap(R, map_x, map_y, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        G = (Rw[1:-1, 2:] - Rw[1:-1, :-2]) * 0.5  # d/du of R(u - d)
        Rc = Rw[1:-1, 1:-1]
        columns = [Rc.reshape(-1), ones,
                   ((Rw[2:, 1:-1] - Rw[:-2, 1:-1]) * 0.5).reshape(-1)]  # d/dv of R(v + e)
        columns.append(G.reshape(-1))
        A = np.column_stack(columns).astype(np.float64)
        sol, *_ = np.linalg.lstsq(A, Lf, rcond=None)
        a, c = sol[0], sol[-1]
        if abs(a) < 1e-6:
            return Refinement(d0, float("inf"), False)
        # L = a R(u - d) + b + c G  with  R(u - d - delta) ~ R(u - d) - delta G  ->  delta = -c / a
        delta = -c / a
        d += delta
        # L = a (R(v + e) + eps Gv) + ...  ->  eps = (coefficient of Gv) / a
        step_e = float(np.clip(e + sol[2] / a, -MAX_ROW_SHIFT_PX, MAX_ROW_SHIFT_PX)) - e
        e += step_e
        if abs(d - d0) > max_shift_px:
            return Refinement(d0, float("inf"), False, ran_off=True)
        resid = Lf - A @ sol
        dof = max(1, L.size - A.shape[1])
        s2 = float(resid @ resid) / dof
        try:
            cov = s2 * np.linalg.inv(A.T @ A)
            stderr = float(math.sqrt(max(cov[-1, -1], 0.0)) / abs(a))
        except np.linalg.LinAlgError:
            return Refinement(d0, float("inf"), False)
        if abs(delta) < 1e-3 and abs(step_e) < 1e-3:
            converged = True
            break
    return _Fit(d, e, stderr, converged, map_x, Rc, A, resid, a)


def correlated_stderr(A: np.ndarray, resid: np.ndarray, shape: tuple[int, int],
                      lag: int = CORRELATION_LAG_PX) -> float:
    """Standard error of the last coefficient of the least-squares fit `A` (pixels of a window of
    `shape`, row by row) whose residuals `resid` may be correlated between pixels up to `lag` px
    apart in either direction (a Bartlett-weighted sandwich estimate: each pixel's influence on
    the coefficient, paired with its neighbours' within the lag). Independent residuals give
    about the usual standard error; residuals that share a JPEG block or a resampling kernel give
    more, as much as their correlation makes the coefficient less certain."""
    try:
        inv = np.linalg.inv(A.T @ A)
    except np.linalg.LinAlgError:
        return float("inf")
    influence = ((A @ inv[-1]) * resid).reshape(shape).astype(np.float32)
    taper = 1.0 - np.abs(np.arange(-lag, lag + 1, dtype=np.float32)) / (lag + 1)
    paired = cv2.filter2D(influence, -1, np.outer(taper, taper), borderType=cv2.BORDER_CONSTANT)
    variance = float(np.sum(influence.astype(np.float64) * paired))
    dof = max(1, A.shape[0] - A.shape[1])
    return math.sqrt(max(variance, 0.0) * A.shape[0] / dof)


def refine_point(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d0: float,
                 half: int, surface: np.ndarray | None = None) -> Refinement | None:
    """The reading's refinement: the alignment of a REFINE_HALF_PX window (larger than the patch:
    more texture, measured to be more accurate on walls and on the chessboard), checked against
    the same alignment of the patch's own window; `windows_px` is how far the two disagree (on a
    surface that matches cleanly they agree to a few hundredths of a pixel; on sharp, repeating
    or sparse texture they do not, and the bound says so).

    Where the texture is weak (the alignment's standard error above REFINE_PRECISE_PX, or no
    convergence at all) the window grows (REFINE_GROWTH) as long as the disparity map `surface`
    (px, NaN invalid) holds one surface in it (`one_surface`), and the surest window (the least
    standard error) is the reading: a window no surer than a smaller one does not stop the
    growth, since on MJPG blocks the next may gather enough. A larger window that does not
    settle from `d0` starts again where the smaller one settled. A grown window's `windows_px`
    is the part of its disagreement with the surest smaller window that that one's own noise
    does not explain. Where a second surface stops the growth while the reading is still
    imprecise, `beyond_px` says how far the next window over the reading's own surface puts it
    (`_beyond_two_surfaces`).

    None when no window converges; an unconverged Refinement with `ran_off` when none converges
    and one was pulled further than REFINE_MAX_SHIFT_PX from `d0` (the images contradict it), or
    when a wider window is pulled that far from `d0` and, allowed twice as far, settles (the
    images put the surface elsewhere than the smaller window did)."""
    best, ran_off = _first_windows(left_gray, right_gray, x, y, d0, half, surface)
    for grown in REFINE_GROWTH:
        if surface is None or (best is not None and best.stderr_px <= REFINE_PRECISE_PX):
            break
        h = max(half, grown)
        if not one_surface(surface, x, y, h):
            if best is not None and best.stderr_px > REFINE_PRECISE_PX:
                best = _beyond_two_surfaces(left_gray, right_gray, x, y, half, grown, surface,
                                            best)
            break
        # (on a slanted or curved surface one disparity for a window this large is wrong: the
        # window is aligned along the plane the map shows there)
        tilt = map_slope(surface, x, y, h)
        wider = _wider_window(left_gray, right_gray, x, y, d0, h, tilt, best)
        if not (wider.converged and math.isfinite(wider.stderr_px)):
            if best is None:
                ran_off = ran_off or wider.ran_off
                continue  # texture too weak for this window too: a larger one may hold enough
            if wider.ran_off:
                # where does the wider window settle, allowed twice as far? Anywhere: the
                # images put the surface somewhere else than the smaller window did (that one
                # fitted a wrong place, or a depth edge the map does not show is near), and the
                # reading is refused. Nowhere: the wider window reached onto another surface or
                # into nothing, and the smaller one stands.
                again = refine_disparity(left_gray, right_gray, x, y, d0, h,
                                         max_shift_px=2 * REFINE_MAX_SHIFT_PX, slope=tilt)
                if again.converged and math.isfinite(again.stderr_px):
                    return Refinement(d0, float("inf"), False, ran_off=True)
            break
        best = _surer(best, wider)
    if best is None and ran_off:
        # no window converged near the estimate, and one was pulled away from it
        return Refinement(d0, float("inf"), False, ran_off=True)
    return best


def _first_windows(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d0: float,
                   half: int, surface: np.ndarray | None) -> tuple[Refinement | None, bool]:
    """The REFINE_HALF_PX window's alignment checked against the patch's own (`windows_px`),
    None where it does not converge; and whether it ran off."""
    h0 = max(half, REFINE_HALF_PX)
    # (a slanted surface, a floor or a table seen obliquely, is aligned along the plane the map
    # shows there, as a grown window is: one disparity for the window ran off on such surfaces)
    tilt0 = map_slope(surface, x, y, h0) if surface is not None else (0.0, 0.0)
    big = refine_disparity(left_gray, right_gray, x, y, d0, h0,
                           max_shift_px=REFINE_MAX_SHIFT_PX, slope=tilt0)
    best = None
    if big.converged and math.isfinite(big.stderr_px):
        small = refine_disparity(left_gray, right_gray, x, y, d0, max(half, 3),
                                 max_shift_px=REFINE_MAX_SHIFT_PX, slope=tilt0)
        apart = (abs(big.disparity_px - small.disparity_px) if small.converged
                 else big.moved_px)  # the small window alone found nothing: as unsure as the move
        best = replace(big, windows_px=apart)
    return best, big.ran_off


def _wider_window(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d0: float,
                  h: int, tilt: tuple[float, float], best: Refinement | None) -> Refinement:
    """The alignment of the window of half side `h` along `tilt`, from d0, or where it does not
    settle and the surest smaller window (`best`) moved away from d0, from where that one
    settled (if it settles there)."""
    wider = refine_disparity(left_gray, right_gray, x, y, d0, h,
                             max_shift_px=REFINE_MAX_SHIFT_PX, slope=tilt)
    if (not wider.converged and best is not None
            and abs(best.disparity_px - d0) > REFINE_RESTART_PX):
        # the matcher's estimate was off (a blob of wrong matches on a weak MJPG wall: 3 px
        # at 2 m) and the smaller window has moved away from it: the wider one starts where
        # that one settled
        restarted = refine_disparity(left_gray, right_gray, x, y, best.disparity_px, h,
                                     max_shift_px=REFINE_MAX_SHIFT_PX, slope=tilt)
        if restarted.converged:
            wider = replace(restarted, moved_px=abs(restarted.disparity_px - d0))
    return wider


def _beyond_two_surfaces(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int,
                         half: int, grown: int, surface: np.ndarray,
                         best: Refinement) -> Refinement:
    """`best` with `beyond_px` set: where the growth met a window holding two surfaces (`grown`,
    the map's blobs of wrong matches on a weak MJPG wall do that as a depth edge does), the next
    larger window over which the map holds one surface again is aligned from where `best`
    settled, and how far it settles from `best` beyond Z95 times the two windows' standard errors
    is kept. A window whose one surface is another than the reading's (its median more than
    SURFACE_BAND_PX away: a background around a leaf) checks nothing and `best` is left as it is.
    On the webcams wall the surest small window lay on such a blob, 1.8 px (6 %) off at 3 m,
    where the windows past the blob read within 1.5 %; taking the larger window's value instead
    read real scenes' slanted and curved surfaces wrong (a depth edge the map does not show), so
    the disagreement only marks the reading as uncertain (`measure` decides)."""
    for larger in (g for g in REFINE_GROWTH if g > grown):
        h = max(half, larger)
        if not one_surface(surface, x, y, h):
            continue
        if abs(float(np.median(window_values(surface, x, y, h)))
               - best.disparity_px) > SURFACE_BAND_PX:
            return best
        wider = refine_disparity(left_gray, right_gray, x, y, best.disparity_px, h,
                                 max_shift_px=REFINE_MAX_SHIFT_PX,
                                 slope=map_slope(surface, x, y, h))
        if wider.converged and math.isfinite(wider.stderr_px):
            apart = abs(wider.disparity_px - best.disparity_px)
            noise = Z95 * (best.stderr_px + wider.stderr_px)
            return replace(best, beyond_px=max(0.0, apart - noise))
        return best
    return best


def _surer(best: Refinement | None, wider: Refinement) -> Refinement:
    """The surer of the surest smaller window and a wider one that converged, the wider one's
    `windows_px` the part of their disagreement the smaller one's noise does not explain."""
    if best is None:
        # no smaller window to check it against: as unsure as its own correction
        return replace(wider, windows_px=wider.moved_px)
    if not wider.stderr_px < best.stderr_px:
        return best  # no surer than the smaller window: the next larger one may be
    unexplained = max(0.0, abs(wider.disparity_px - best.disparity_px)
                      - Z95 * best.stderr_px)
    return replace(wider, windows_px=unexplained)


def map_slope(disparity_px: np.ndarray, x: int, y: int, half: int) -> tuple[float, float]:
    """The slopes (px of disparity per px, along x and y) of the plane the map's valid values
    in the window of `half` around (x, y) lie on (least squares, twice with the values off it by
    more than 3 robust sigma left out); (0, 0) with too few values, slopes under SLOPE_MIN_PX
    across the window (a wall facing the rig: no slope to model), or a plane that leaves the
    values not clearly less scattered than their median does."""
    y0, x0 = max(0, y - half), max(0, x - half)
    win = disparity_px[y0:y + half + 1, x0:x + half + 1]
    ok = np.isfinite(win)
    if int(ok.sum()) < max(9, win.size // 4):
        return 0.0, 0.0
    plane = fit_plane(win, ok, x0, y0, x, y, 2, about_median=True)
    gx, gy, resid, keep = plane.gx, plane.gy, plane.resid, plane.keep
    b = win[ok].astype(np.float64)
    if (abs(gx) + abs(gy)) * half < SLOPE_MIN_PX:
        return 0.0, 0.0
    # a slope the map's values show only in their noise (blobs of wrong matches on an MJPG
    # wall tilt a plane as much as a turned surface does) leaves them about as scattered about
    # the plane as about their median
    if robust_spread(resid[keep]) > SLOPE_FIT_SHARE * robust_spread(b - np.median(b)):
        return 0.0, 0.0
    reach = (abs(gx) + abs(gy)) * half
    if reach > SLANT_REACH_PX:
        gx, gy = gx * SLANT_REACH_PX / reach, gy * SLANT_REACH_PX / reach
    return gx, gy


def one_surface(disparity_px: np.ndarray, x: int, y: int, half: int) -> bool:
    """Whether the map's valid disparities in the window of `half` around (x, y) (clipped to
    the map) lie on one surface: at least SURFACE_SHARE of them within SURFACE_BAND_PX of their
    median. (Not their spread: on a weak MJPG wall the map is one surface whose values scatter
    by a robust 1-1.2 px in blobs of wrong matches; a second surface more than SURFACE_BAND_PX
    away that fills more than a fifth of the window breaks the share wherever it lies.)"""
    values = window_values(disparity_px, x, y, half)
    if values.size < 9:
        return False
    near = np.abs(values - np.median(values)) <= SURFACE_BAND_PX
    return float(near.mean()) >= SURFACE_SHARE


def window_values(disparity_px: np.ndarray, x: int, y: int, half: int) -> np.ndarray:
    """The map's valid (finite) disparities in the window of `half` around (x, y), clipped to
    the map, as a flat array."""
    window = disparity_px[max(0, y - half):y + half + 1, max(0, x - half):x + half + 1]
    return np.asarray(window[np.isfinite(window)])


def window_correlation(left_gray: np.ndarray, right_gray: np.ndarray, x: int, y: int, d: float,
                       half: int) -> tuple[float, int]:
    """Correlation of the left window at (x, y) (clipped to the image) with the right image
    shifted by disparity `d` (bicubic), and the window's pixel count; (0, 0) where the shifted
    window leaves the right image or either window is flat."""
    h, w = left_gray.shape[:2]
    y0, y1 = max(0, y - half), min(h, y + half + 1)
    x0, x1 = max(0, x - half, int(math.ceil(d + 2))), min(w, x + half + 1, int(w + d - 2))
    if x1 - x0 < 3 or y1 - y0 < 1:
        return 0.0, 0
    left = left_gray[y0:y1, x0:x1].astype(np.float32)
    map_x = np.tile(np.arange(x0, x1, dtype=np.float32) - np.float32(d), (y1 - y0, 1))
    map_y = np.repeat(np.arange(y0, y1, dtype=np.float32)[:, None], x1 - x0, axis=1)
    right = cv2.remap(right_gray, map_x, map_y, cv2.INTER_CUBIC,
                      borderMode=cv2.BORDER_REPLICATE).astype(np.float32)
    a, b = left - left.mean(), right - right.mean()
    denom = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    return (float((a * b).sum()) / denom if denom > 0 else 0.0), int(left.size)
