"""Calibration health from the scene: have the cameras moved since calibration? And a repair.

Webcam heads turn. After rectification a point must lie on the same row in both images; sparse
feature matches between the rectified images show how far they are off. The health figure is
the median |y_left - y_right| of those matches (px): a few tenths of a pixel right after
calibration, more once a camera has turned (0.3 degrees of tilt is about 4 px at 750 px focal
length). Matches with the wrong sign of disparity (the scene lies "behind infinity") mean the
cameras are swapped.

`refine_rotation` re-estimates the relative rotation from matches in a scene pair, keeping both
cameras' intrinsics and the right camera's centre (so the baseline, and with it the metric scale,
stay as calibrated): R' = dR R, T' = dR T for a small rotation dR of the right camera, chosen to
make the matches row-aligned after rectification again. A turn about the vertical axis (a pan)
moves points along the rows, so it shows only weakly in the rows (through the image's edges);
the refinement estimates it too, and says how well it is determined.
"""

from __future__ import annotations

import datetime
import math
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.lens import stereo_rectify, undistort_points
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.uncertainty import CalibrationUncertainty
from stereo_gui.core.util import mutual_ratio_matches, to_gray

DRIFT_WARN_PX = 0.5  # above this median vertical disparity the cameras moved since calibration
MIN_MATCHES = 30
# the live check finds its features on images at most this wide and places them on the full-size
# ones: SIFT's cost falls about with the pixel count while the figure stays the same to a few
# hundredths of a pixel (tests/core/test_health.py)
HEALTH_DETECT_WIDTH = 320


def health_detect_scale(width_px: int) -> float:
    """The scale the live check finds its features at, for images `width_px` wide."""
    return min(1.0, HEALTH_DETECT_WIDTH / max(1, int(width_px)))


# the optical flow that confirms a SIFT match: its window, pyramid levels and stopping rule
_LK_WINDOW = (15, 15)
_LK_LEVELS = 2
_LK_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.005)


@dataclass(frozen=True)
class CalibrationHealth:
    """How well the live rectified pair is row-aligned: the median |y_left - y_right| of
    `matches` sparse feature matches (px), and the share of matches with a negative disparity."""

    vertical_px: float
    matches: int
    negative_share: float

    @property
    def measured(self) -> bool:
        return self.matches >= MIN_MATCHES and math.isfinite(self.vertical_px)

    @property
    def drifted(self) -> bool:
        return self.measured and self.vertical_px > DRIFT_WARN_PX

    @property
    def swapped(self) -> bool:
        """Most matches lie 'behind infinity': the left and right cameras are exchanged."""
        return self.matches >= MIN_MATCHES and self.negative_share > 0.6

    def text(self) -> str:
        if not self.measured:
            return (f"Calibration health: too few feature matches ({self.matches}) to tell; "
                    "point the cameras at something with texture")
        head = (f"Calibration health: {self.vertical_px:.2f} px vertical disparity "
                f"(median of {self.matches} matches)")
        if self.swapped:
            return (head + f" — {100 * self.negative_share:.0f} % of matches have the wrong sign "
                    "of disparity: the cameras are swapped (Calibration tab: Swap the cameras "
                    "and recalibrate)")
        if self.drifted:
            return (head + f" — above {DRIFT_WARN_PX} px: the cameras moved since calibration. "
                    "Refine rectification from the scene, or recalibrate")
        return head + " — OK"


def feature_matches(left: np.ndarray, right: np.ndarray, max_features: int = 1500,
                    ratio: float = 0.75, detect_scale: float = 1.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Matched points of two images, (N, 2) px each: SIFT with Lowe's ratio test and a mutual
    check, each match then placed to a fraction of a pixel by Lucas-Kanade from the left
    image to the right one (SIFT's own positions are good to a few tenths only). With
    `detect_scale` < 1 SIFT runs on images shrunk by that factor (about 1/scale^2 less work);
    Lucas-Kanade still places every match on the full-resolution images."""
    gl, gr = to_gray(left), to_gray(right)
    sl, sr = gl, gr
    if detect_scale < 1.0:
        size = (max(1, round(gl.shape[1] * detect_scale)), max(1, round(gl.shape[0] * detect_scale)))
        sl = cv2.resize(gl, size, interpolation=cv2.INTER_AREA)
        sr = cv2.resize(gr, size, interpolation=cv2.INTER_AREA)
    sift = cv2.SIFT.create(nfeatures=max_features)
    kl, dl = sift.detectAndCompute(sl, None)
    kr, dr = sift.detectAndCompute(sr, None)
    if dl is None or dr is None or len(kl) < 2 or len(kr) < 2:
        return np.zeros((0, 2)), np.zeros((0, 2))
    il, ir = mutual_ratio_matches(dl, dr, ratio)
    if not il.size:
        return np.zeros((0, 2)), np.zeros((0, 2))
    up = np.float32(1.0 / detect_scale) if detect_scale < 1.0 else np.float32(1.0)
    # (a shrunk image's pixel centres: x_full + 0.5 = (x_small + 0.5) / scale)
    pl = ((np.array([kl[i].pt for i in il], np.float32) + 0.5) * up - 0.5).reshape(-1, 1, 2)
    pr = ((np.array([kr[j].pt for j in ir], np.float32) + 0.5) * up - 0.5).reshape(-1, 1, 2)
    refined, st, _ = cv2.calcOpticalFlowPyrLK(gl, gr, pl, pr.copy(), winSize=_LK_WINDOW,
                                              maxLevel=_LK_LEVELS, criteria=_LK_CRITERIA,
                                              flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
    ok = st.reshape(-1).astype(bool)
    moved = np.linalg.norm(refined.reshape(-1, 2) - pr.reshape(-1, 2), axis=1)
    ok &= moved < 1.5 * up  # LK must confirm the SIFT match, not wander off to another one
    return pl.reshape(-1, 2)[ok].astype(np.float64), refined.reshape(-1, 2)[ok].astype(np.float64)


def _robust(dy: np.ndarray) -> np.ndarray:
    """Mask of the matches that agree with the bulk (gross mismatches left out)."""
    med = float(np.median(dy))
    mad = float(np.median(np.abs(dy - med))) * 1.4826
    return np.abs(dy - med) <= max(3.0 * mad, 1.0)


def calibration_health(left_rect: np.ndarray, right_rect: np.ndarray,
                       detect_scale: float = 1.0) -> CalibrationHealth:
    """The health figure of a rectified pair (see the module docstring); `detect_scale`: see
    `feature_matches` (the live check uses health_detect_scale)."""
    pl, pr = feature_matches(left_rect, right_rect, detect_scale=detect_scale)
    if len(pl) < 8:
        return CalibrationHealth(float("nan"), len(pl), 0.0)
    # rectified matches lie near one row: a match many rows off is a mismatch, not drift
    near = np.abs(pl[:, 1] - pr[:, 1]) < 25.0
    pl, pr = pl[near], pr[near]
    if len(pl) < 8:
        return CalibrationHealth(float("nan"), len(pl), 0.0)
    dy = pl[:, 1] - pr[:, 1]
    keep = _robust(dy)
    d = pl[keep, 0] - pr[keep, 0]
    return CalibrationHealth(float(np.median(np.abs(dy[keep]))), int(keep.sum()),
                             float(np.mean(d < -1.0)) if d.size else 0.0)


# ---- refinement --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Refinement:
    """A refined calibration and what the refinement saw: the epipolar error (median |dy|, px)
    of the matches before and after, how many, and the rotation applied to the right camera
    (Rodrigues vector, degrees, in its own frame) with its 1-sigma spread per axis."""

    calibration: StereoCalibration
    before_px: float
    after_px: float
    matches: int
    turn_deg: tuple[float, float, float]
    turn_sigma_deg: tuple[float, float, float]


def _vertical(calib: StereoCalibration, R: np.ndarray, T: np.ndarray, ul: np.ndarray,
              ur: np.ndarray) -> np.ndarray:
    R1, R2, P1, P2, _ = stereo_rectify(calib.model, calib.M1, calib.D1, calib.M2, calib.D2,
                                       calib.image_size, R, T, calib.alpha)
    a = undistort_points(calib.model, ul, calib.M1, calib.D1, R=R1, P=P1)
    b = undistort_points(calib.model, ur, calib.M2, calib.D2, R=R2, P=P2)
    dy: np.ndarray = a[:, 1] - b[:, 1]
    return dy


def refine_rotation(calib: StereoCalibration, left: np.ndarray, right: np.ndarray,
                    source: str = "") -> Refinement:
    """Re-estimate R_right_left from a raw scene pair (see the module docstring); the result is
    a new calibration whose origin says where it came from. Raises CalibrationError when the
    scene gives too few matches."""
    if not calib.metric:
        raise CalibrationError("only a metric calibration can be refined from the scene")
    left, right = calib.ordered(left, right)
    ul, ur = feature_matches(left, right)
    if len(ul) < MIN_MATCHES:
        raise CalibrationError(f"only {len(ul)} feature matches in the scene; at least "
                               f"{MIN_MATCHES} are needed (point the cameras at texture)")
    R0 = np.asarray(calib.R, np.float64)
    T0 = np.asarray(calib.T, np.float64).reshape(3, 1)
    dy = _vertical(calib, R0, T0, ul, ur)
    keep = _robust(dy) & (np.abs(dy) < 40.0)
    before = float(np.median(np.abs(dy[keep]))) if keep.any() else float("nan")
    ul, ur = ul[keep], ur[keep]
    if len(ul) < MIN_MATCHES:
        raise CalibrationError(f"only {len(ul)} consistent feature matches in the scene")
    delta, r, J = _solve_turn(calib, R0, T0, ul, ur)
    cov, turn_sigma = _turn_covariance(r, J)
    R, T = _turned(R0, T0, delta)
    R1, R2, P1, P2, Q = stereo_rectify(calib.model, calib.M1, calib.D1, calib.M2, calib.D2,
                                       calib.image_size, R, T, calib.alpha)
    tx = T.reshape(3)
    Tx = np.array([[0, -tx[2], tx[1]], [tx[2], 0, -tx[0]], [-tx[1], tx[0], 0]], np.float64)
    E = Tx @ R
    F = np.linalg.inv(calib.M2).T @ E @ np.linalg.inv(calib.M1)
    F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
    after = float(np.median(np.abs(_vertical(calib, R, T, ul, ur))))
    turn = (math.degrees(float(delta[0])), math.degrees(float(delta[1])),
            math.degrees(float(delta[2])))
    parent = calib.created or "unknown time"
    origin = (f"refined from the scene ({len(ul)} feature matches{', ' + source if source else ''})"
              f" from the calibration of {parent}"
              + (f" ({calib.origin})" if calib.origin else "")
              + f": right camera turned by {math.degrees(np.linalg.norm(delta)):.3f} deg; "
              "intrinsics and baseline kept")
    refined = calib.with_updates(
        R=R, T=T, E=E, F=F, R1=R1, R2=R2, P1=P1, P2=P2, Q=Q, epipolar_error_px=after,
        uncertainty=_with_turn(calib.uncertainty, cov if np.all(np.isfinite(turn_sigma)) else None),
        warnings=(), origin=origin,
        created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
    return Refinement(refined, before, after, int(len(ul)), turn, turn_sigma)


def _turned(R0: np.ndarray, T0: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The right camera's pose turned by the small rotation `delta` (Rodrigues vector, rad):
    R' = dR R0, T' = dR T0."""
    dR = cv2.Rodrigues(np.asarray(delta, np.float64).reshape(3, 1))[0]
    return dR @ R0, dR @ T0


def _solve_turn(calib: StereoCalibration, R0: np.ndarray, T0: np.ndarray, ul: np.ndarray,
                ur: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The turn (Rodrigues vector, rad) that row-aligns the matches `ul`, `ur` best
    (Levenberg-Marquardt on central differences), their rows' differences after it, and the
    last Jacobian."""
    delta = np.zeros(3)
    h = 1e-5
    lam = 1e-3
    r = _vertical(calib, *_turned(R0, T0, delta), ul, ur)
    cost = float(r @ r)
    J = np.zeros((len(ul), 3))
    for _ in range(30):
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            J[:, k] = (_vertical(calib, *_turned(R0, T0, delta + e), ul, ur)
                       - _vertical(calib, *_turned(R0, T0, delta - e), ul, ur)) / (2 * h)
        A = J.T @ J
        g = J.T @ r
        step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), -g)
        cand = delta + step
        rn = _vertical(calib, *_turned(R0, T0, cand), ul, ur)
        cn = float(rn @ rn)
        if cn < cost:
            delta, r, cost, lam = cand, rn, cn, lam / 10
            if np.abs(step).max() < 1e-8:
                break
        else:
            lam *= 10
            if lam > 1e6:
                break
    return delta, r, J


def _turn_covariance(r: np.ndarray, J: np.ndarray
                     ) -> tuple[np.ndarray | None, tuple[float, float, float]]:
    """The turn's covariance (rad^2; None where singular) over the matches that agree, and its
    1-sigma spread per axis in degrees (inf where singular)."""
    # the matches that still disagree (moving objects, mismatches) should not steer the result
    inl = np.abs(r - np.median(r)) < max(3 * 1.4826 * np.median(np.abs(r - np.median(r))), 0.5)
    sigma2 = float(r[inl] @ r[inl]) / max(int(inl.sum()) - 3, 1)
    try:
        cov = np.linalg.inv(J[inl].T @ J[inl]) * sigma2
    except np.linalg.LinAlgError:
        return None, (float("inf"), float("inf"), float("inf"))
    sx, sy, sz = (math.degrees(math.sqrt(max(float(v), 0.0))) for v in np.diag(cov))
    return cov, (sx, sy, sz)


def _with_turn(u: CalibrationUncertainty | None, turn_cov: np.ndarray | None
               ) -> CalibrationUncertainty | None:
    """The calibration's uncertainty after a refinement: the intrinsics and the baseline as they
    were; the rotation's as it was plus the refinement's own (its rotation dR is applied on the
    left of R, which for the nearly parallel cameras of a rig is, to first order, added to R's
    rotation vector). Without the refinement's, the uncertainty is dropped: not known."""
    if u is None or turn_cov is None:
        return None
    cov = np.array(u.covariance, np.float64)
    rows = [i for i in (u.index(f"rvec.{a}") for a in "xyz") if i is not None]
    if len(rows) < 3:
        return None
    cov[np.ix_(rows, rows)] += turn_cov
    return CalibrationUncertainty(u.names, cov, u.sigma_px, u.method + "+scene", u.model)
