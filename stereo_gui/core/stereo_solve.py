"""One solve of a stereo calibration from target detections (Bouguet), as `core.calibrate` runs
it for a set of pairs: each camera's own calibration (calibrateCameraExtended, or
cv2.fisheye.calibrate; the rational model from the pinhole one), the rig's pose with both
cameras' intrinsics fixed (stereoCalibrate), then the joint refinement of everything
(core.bundle). Pairs whose cameras took their two pictures at different moments (the board moved
between them) are told by the transfer of each pair's board from one camera to the other; then
each camera keeps its own fit and the pose is the pairs' mean, with the uncertainty and the
warning that says so.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.bundle import BundleResult, View, refine_stereo
from stereo_gui.core.detect import PairDetection
from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.jobs import Cancel, ProgressCallback, check_cancel, report_progress
from stereo_gui.core.lens import (
    DIST_COUNT,
    HIGHER_TERMS,
    ROUND_TRIP_PX,
    check_model,
    distortion_names,
    project_points,
    round_trip_px,
)
from stereo_gui.core.uncertainty import Z95, CalibrationUncertainty, CalibrationWarning

log = logging.getLogger(__name__)


_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-6)


@dataclass(frozen=True, eq=False)
class Solve:
    names: list[str]
    M1: np.ndarray
    D1: np.ndarray
    M2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray
    E: np.ndarray
    F: np.ndarray
    rms_left: float
    rms_right: float
    rms_stereo: float
    rms_stereo_fixed: float
    errors: list[tuple[float, float]]  # per pair (left, right) RMS px, from the final model
    bundle: BundleResult
    mono_sigmas: tuple[np.ndarray | None, np.ndarray | None]  # calibrateCameraExtended's
    # per pair: how far the right camera's corners lie (RMS px) from the left camera's view of
    # the board carried over by the rig's pose (the median of the pairs'), each camera with its
    # own fit: a pair whose board moved between the two pictures lands far off
    transfer_px: list[float]
    own_px: list[float]  # per pair: the worse of the two cameras' errors of their own fits
    # the cameras took most pairs at different moments (`_unsynchronised`): each camera kept
    # its own fit's intrinsics, the joint refinement was not run
    unsynchronised: bool = False
    # each pair's own view of the rig's pose: R_right_left as a Rodrigues vector (rad) and
    # T_right_left (mm), (n, 6)
    pair_poses: np.ndarray | None = None

    @property
    def pair_baselines_mm(self) -> np.ndarray:
        return (np.linalg.norm(self.pair_poses[:, 3:], axis=1) if self.pair_poses is not None
                else np.zeros(0))


# OpenCV's flags that hold a distortion coefficient (OpenCV 5 gives cv2.fisheye the same values)
_HOLD_FLAGS = {"k1": cv2.CALIB_FIX_K1, "k2": cv2.CALIB_FIX_K2, "k3": cv2.CALIB_FIX_K3,
               "k4": cv2.CALIB_FIX_K4, "k5": cv2.CALIB_FIX_K5, "k6": cv2.CALIB_FIX_K6,
               "p1": cv2.CALIB_ZERO_TANGENT_DIST, "p2": cv2.CALIB_ZERO_TANGENT_DIST}


def held_ladder(model: str, fix_k3: bool = False) -> list[tuple[str, ...]]:
    """The distortion terms held at zero, from the full model down to the simplest tried when
    the lens model folds over inside the image: none, k3 and the higher terms, then k2 too,
    then every term (`no_distortion`: a lens without distortion cannot fold); starting at the
    second with `fix_k3`."""
    higher = HIGHER_TERMS[model]
    ladder = [(), higher, ("k2", *higher), distortion_names(model)]
    return ladder[1:] if fix_k3 else ladder


def no_distortion(model: str, held: Sequence[str]) -> bool:
    """Whether `held` holds every distortion term of `model` (the pinhole of the lens alone)."""
    return set(distortion_names(model)) <= set(held)


def _mono_flags(model: str, held: Sequence[str]) -> int:
    flags = 0
    if model == "rational":
        flags |= cv2.CALIB_RATIONAL_MODEL
    if model == "fisheye":
        flags |= cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
    for name in held:
        flags |= _HOLD_FLAGS[name]
    return flags


# one camera's calibration: rms px, M, D (1xN), each view's board pose (rvec, tvec) and the
# intrinsics' standard deviations (None where OpenCV gives none)
_Mono = tuple[float, np.ndarray, np.ndarray, Sequence[np.ndarray], Sequence[np.ndarray],
              np.ndarray | None]


def _calibrate_mono(objs: list[np.ndarray], imgs: list[np.ndarray], image_size: tuple[int, int],
                    model: str, held: Sequence[str] = ()) -> _Mono:
    """One camera: (rms, M, D (1xN), rvecs, tvecs, standard deviations of the intrinsics or None);
    the distortion terms `held` stay at zero.

    The rational model starts from the pinhole solution with k4..k6 at zero: OpenCV's own
    rational calibration wanders along the model's flat valley (very different coefficients
    for the same lens, different from run to run), and the joint refinement takes it from
    there (core.bundle)."""
    if model == "rational":
        pinhole = tuple(n for n in held if n in distortion_names("pinhole"))
        rms, M, D, rv, tv, _ = _calibrate_mono(objs, imgs, image_size, "pinhole", pinhole)
        return rms, M, np.concatenate([D.reshape(1, -1), np.zeros((1, 3))], axis=1), rv, tv, None
    flags = _mono_flags(model, held)
    try:
        if model == "fisheye":
            # (cv2.fisheye wants each view as a 1xN row of points)
            # (OpenCV's stubs want the output matrices passed in; None asks it to make them)
            rms, M, D, rv, tv = cv2.fisheye.calibrate(  # type: ignore[call-overload]
                [o.reshape(1, -1, 3).astype(np.float64) for o in objs],
                [i.reshape(1, -1, 2).astype(np.float64) for i in imgs], image_size, None, None,
                flags=flags, criteria=_CRITERIA)
            return float(rms), M, np.asarray(D).reshape(1, -1), rv, tv, None
        rms, M, D, rv, tv, std, _, _ = cv2.calibrateCameraExtended(  # type: ignore[call-overload]
            [o.astype(np.float32) for o in objs], [i.reshape(-1, 1, 2).astype(np.float32) for i in imgs],
            image_size, None, None, flags=flags, criteria=_CRITERIA)
    except cv2.error as exc:
        raise CalibrationError(f"the {model} camera calibration failed: "
                               f"{str(exc).strip().splitlines()[-1]}") from None
    nd = DIST_COUNT[model]
    D = np.asarray(D, np.float64).reshape(-1)[:nd].reshape(1, -1)
    return float(rms), M, D, rv, tv, np.asarray(std, np.float64).reshape(-1)


def _relative_pose(rv_l: Sequence[np.ndarray], tv_l: Sequence[np.ndarray],
                   rv_r: Sequence[np.ndarray], tv_r: Sequence[np.ndarray]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """R_right_left, T_right_left from the board poses both cameras saw (the mean over views)."""
    rs, ts = [], []
    for a, b, c, d in zip(rv_l, tv_l, rv_r, tv_r):
        Rl, Rr = cv2.Rodrigues(np.asarray(a, np.float64))[0], cv2.Rodrigues(np.asarray(c, np.float64))[0]
        Rk = Rr @ Rl.T
        rs.append(cv2.Rodrigues(Rk)[0].reshape(3))
        ts.append(np.asarray(d, np.float64).reshape(3) - Rk @ np.asarray(b, np.float64).reshape(3))
    R = cv2.Rodrigues(np.median(np.array(rs), axis=0).reshape(3, 1))[0]
    return R, np.median(np.array(ts), axis=0).reshape(3, 1)


def solve(pairs: list[PairDetection], board: BoardSpec, image_size: tuple[int, int],
           joint: bool, progress: ProgressCallback | None, cancel: Cancel, step0: int,
           total: int, model: str = "pinhole", held: Sequence[str] = ()) -> Solve:
    pts = _PairPoints.of(pairs, board)
    report_progress(progress, step0, total, "calibrating the left camera")
    _, M1, D1, rv1, tv1, std1 = _calibrate_mono(pts.obj_left, pts.img_left, image_size, model,
                                                held)
    check_cancel(cancel)
    report_progress(progress, step0 + 1, total, "calibrating the right camera")
    _, M2, D2, rv2, tv2, std2 = _calibrate_mono(pts.obj_right, pts.img_right, image_size, model,
                                                held)
    check_cancel(cancel)
    report_progress(progress, step0 + 2, total, "calibrating the pair")
    # the relative pose with both cameras' intrinsics fixed: the start of the joint refinement
    rms_fixed = float("nan")
    R, T = _relative_pose(rv1, tv1, rv2, tv2)
    transfer = [_transfer_px(model, pts.obj_right[k], pts.img_right[k], rv1[k], tv1[k], R, T,
                             M2, D2) for k in range(len(pairs))]
    own = [max(rms_px(model, pts.obj_left[k], pts.img_left[k], rv1[k], tv1[k], M1, D1),
               rms_px(model, pts.obj_right[k], pts.img_right[k], rv2[k], tv2[k], M2, D2))
           for k in range(len(pairs))]
    unsynchronised = _unsynchronised(transfer, own)
    poses = _pair_poses(rv1, tv1, rv2, tv2)
    if unsynchronised:
        # a joint refinement would bend both lenses to make boards that moved meet (on the rig
        # with the right camera 50 ms late: the rotation off by 1.7-8.8 deg, fx by 5 %); each
        # camera's own fit is what the pairs say of its lens
        log.info("the board moved between the two pictures of most pairs (median %.2f px, "
                 "each camera's own fit %.2f px): each camera keeps its own intrinsics",
                 float(np.median(transfer)), float(np.median(own)))
        joint = False
        # each pair is one independent look at the rig's pose, off by its board's motion:
        # their mean is the pose (a least-squares fit over every corner weighs the pairs
        # unequally and read the baseline 2.3 mm RMS off on the rig 50 ms apart, the mean
        # 0.9 mm); its scatter is what `unsync_uncertainty` adds
        mean = poses.mean(axis=0)
        R, T = cv2.Rodrigues(mean[:3].reshape(3, 1))[0], mean[3:].reshape(3, 1)
    else:
        fixed = _pose_with_fixed_intrinsics(pts, model, M1, D1, M2, D2, image_size)
        if fixed is not None:
            rms_fixed, R, T = fixed
    check_cancel(cancel)
    # every point each camera saw, the left camera's board poses as the start
    views = [View(pts.obj_left[k], pts.img_left[k].reshape(-1, 2), pts.obj_right[k],
                  pts.img_right[k].reshape(-1, 2)) for k in range(len(pairs))]
    bundle = refine_stereo(views, model, M1, D1, M2, D2, R, T, rv1, tv1, fixed=tuple(held),
                           max_iterations=100 if joint else 0)
    if joint:
        M1, D1, M2, D2, R, T = bundle.M1, bundle.D1, bundle.M2, bundle.D2, bundle.R, bundle.T
    errors = list(bundle.errors)
    rl = float(np.sqrt(np.nanmean([e[0] ** 2 for e in errors])))
    rr = float(np.sqrt(np.nanmean([e[1] ** 2 for e in errors])))
    E, F = _essential_and_fundamental(M1, M2, R, T)
    return Solve([p.name for p in pairs], M1, D1.reshape(1, -1), M2, D2.reshape(1, -1), R,
                  T.reshape(3, 1), E, F, rl, rr, float(bundle.rms), rms_fixed, errors, bundle,
                  (std1, std2), transfer, own, unsynchronised, poses)


@dataclass(frozen=True, eq=False)
class _PairPoints:
    """The pairs' board points (mm) and where each camera saw them (px), per pair; and the
    corners both cameras saw (`common`: PairDetection.common()) with their board points."""

    obj_left: list[np.ndarray]
    img_left: list[np.ndarray]
    obj_right: list[np.ndarray]
    img_right: list[np.ndarray]
    common: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    obj_common: list[np.ndarray]

    @classmethod
    def of(cls, pairs: list[PairDetection], board: BoardSpec) -> _PairPoints:
        obj_all = board.object_points_mm()
        common = [p.common() for p in pairs]
        sides = [p.sides() for p in pairs]
        return cls([left.object_points(board) for left, _ in sides],
                   [left.corners for left, _ in sides],
                   [right.object_points(board) for _, right in sides],
                   [right.corners for _, right in sides],
                   common, [obj_all[c[0]] for c in common])


def _pose_with_fixed_intrinsics(pts: _PairPoints, model: str, M1: np.ndarray, D1: np.ndarray,
                                M2: np.ndarray, D2: np.ndarray,
                                image_size: tuple[int, int]
                                ) -> tuple[float, np.ndarray, np.ndarray] | None:
    """OpenCV's stereo calibration with both cameras' intrinsics fixed, over the corners both
    saw: (its RMS px, R, T), or None where it fails (the joint refinement then starts from the
    board poses)."""
    oc, common = pts.obj_common, pts.common
    try:
        if model == "fisheye":
            out = cv2.fisheye.stereoCalibrate(
                [o.reshape(1, -1, 3).astype(np.float64) for o in oc],
                [c[1].reshape(1, -1, 2).astype(np.float64) for c in common],
                [c[2].reshape(1, -1, 2).astype(np.float64) for c in common],
                M1, D1.reshape(4, 1), M2, D2.reshape(4, 1), image_size,
                flags=cv2.CALIB_FIX_INTRINSIC, criteria=_CRITERIA)
            return float(out[0]), out[5], np.asarray(out[6]).reshape(3, 1)
        flags = cv2.CALIB_FIX_INTRINSIC | (cv2.CALIB_RATIONAL_MODEL if model == "rational" else 0)
        # (OpenCV's stubs want R and T passed in; None asks it to make them)
        out = cv2.stereoCalibrateExtended(  # type: ignore[call-overload]
            [o.astype(np.float32) for o in oc],
            [c[1].reshape(-1, 1, 2).astype(np.float32) for c in common],
            [c[2].reshape(-1, 1, 2).astype(np.float32) for c in common],
            M1, D1, M2, D2, image_size, None, None, flags=flags, criteria=_CRITERIA)
        return float(out[0]), out[5], out[6].reshape(3, 1)
    except cv2.error as exc:
        log.info("stereo calibration with fixed intrinsics failed (%s); starting the joint "
                 "refinement from the board poses", str(exc).strip().splitlines()[-1])
        return None


def _essential_and_fundamental(M1: np.ndarray, M2: np.ndarray, R: np.ndarray, T: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray]:
    """E = [T]x R and F = M2^-T E M1^-1 (normalised to F[2,2] = 1 where it is not ~0)."""
    tx = np.asarray(T, np.float64).reshape(3)
    Tx = np.array([[0, -tx[2], tx[1]], [tx[2], 0, -tx[0]], [-tx[1], tx[0], 0]], np.float64)
    E = Tx @ R
    F = np.linalg.inv(M2).T @ E @ np.linalg.inv(M1)
    F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
    return E, F


def _pair_poses(rv_l: Sequence[np.ndarray], tv_l: Sequence[np.ndarray],
                rv_r: Sequence[np.ndarray], tv_r: Sequence[np.ndarray]) -> np.ndarray:
    """Each pair's own view of the rig's pose, (n, 6): the Rodrigues vector of R_right_left
    (rad) and T_right_left (mm) that its two board poses put the cameras at."""
    out = []
    for a, b, c, d in zip(rv_l, tv_l, rv_r, tv_r):
        Rk = (cv2.Rodrigues(np.asarray(c, np.float64))[0]
              @ cv2.Rodrigues(np.asarray(a, np.float64))[0].T)
        t = np.asarray(d, np.float64).reshape(3) - Rk @ np.asarray(b, np.float64).reshape(3)
        out.append(np.concatenate([cv2.Rodrigues(Rk)[0].reshape(3), t]))
    return np.array(out, np.float64).reshape(-1, 6)


def unsync_uncertainty(sol: Solve, model: str) -> CalibrationUncertainty:
    """The parameters' covariance of a calibration from pairs taken at different moments:
    the bundle's, scaled to the noise of the cameras' own fits (the residuals of boards that
    moved are no measure of how well a lens is known), with the scatter of the pairs' own views
    of the rig's pose (its variance over the pairs, divided by their count) added to the pose's
    rows: what the moving board leaves unknown."""
    bundle = sol.bundle
    own = float(np.median(sol.own_px)) / np.sqrt(2.0)  # RMS of 2-D errors -> per coordinate
    scale = (own / bundle.sigma_px) ** 2 if bundle.sigma_px > 0 else 1.0
    cov = np.asarray(bundle.covariance, np.float64) * scale
    poses = sol.pair_poses
    if poses is not None and len(poses) > 1:
        scatter = np.var(poses, axis=0, ddof=1) / len(poses)
        names = list(bundle.names)
        for k, name in enumerate(("rvec.x", "rvec.y", "rvec.z", "T.x", "T.y", "T.z")):
            if name in names:
                i = names.index(name)
                cov[i, i] += scatter[k]
    return CalibrationUncertainty(tuple(bundle.names), cov, own, "jacobian", check_model(model))


# cameras that do not take a pair's two pictures at the same moment, with a board held by hand:
# most pairs' transfer error (below) is above both of these. Synchronised sets lie at 1.2x
# (the real 9x6 webcams, 0.31 px) and 2-3.3x (the simulated rig, 0.10-0.17 px); the rig with
# its right camera 50 ms late at 40-77x (2.0-3.8 px)
UNSYNC_FACTOR = 5.0  # times the median pair's own fit
UNSYNC_FLOOR_PX = 0.5
OUTLIER_FACTOR = 3.0  # a pair's error above both of these is an outlier (`calibrate_stereo`)
OUTLIER_FLOOR_PX = 1.0


def _unsynchronised(transfer: list[float], own: list[float]) -> bool:
    """Whether the board moved between the two pictures of most pairs: the median transfer
    error far above the median of the cameras' own fits. Not while a pair's own fit is an
    outlier (`_outliers`' rule): corners one camera found badly in one pair bend that camera's
    own lens, and with it every pair's transfer (one pair's corners 3 px off put the rig's at
    0.5-3.8 px); the set is judged again once that pair is left out."""
    t, o = float(np.median(transfer)), float(np.median(own))
    if max(own) > max(OUTLIER_FACTOR * o, OUTLIER_FLOOR_PX):
        return False
    return t > max(UNSYNC_FACTOR * o, UNSYNC_FLOOR_PX)


def rms_px(model: str, obj: np.ndarray, img: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
            M: np.ndarray, D: np.ndarray) -> float:
    """RMS px between corners `img` and the board's points `obj` seen from (rvec, tvec)."""
    d = project_points(model, obj, rvec, tvec, M, D) - np.asarray(img, np.float64).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


def _transfer_px(model: str, obj: np.ndarray, img: np.ndarray, rvec_left: np.ndarray,
                 tvec_left: np.ndarray, R: np.ndarray, T: np.ndarray, M2: np.ndarray,
                 D2: np.ndarray) -> float:
    """RMS px between the right camera's corners `img` and the board as the left camera's pose
    (`rvec_left`, `tvec_left`) and the rig's (R, T) put it in the right image."""
    Rl = cv2.Rodrigues(np.asarray(rvec_left, np.float64).reshape(3, 1))[0]
    rvec = cv2.Rodrigues(R @ Rl)[0]
    tvec = R @ np.asarray(tvec_left, np.float64).reshape(3, 1) + np.asarray(T).reshape(3, 1)
    return rms_px(model, obj, img, rvec, tvec, M2, D2)


def unsync_warning(sol: Solve) -> CalibrationWarning:
    """What a calibration from pairs taken at different moments is, and what it costs."""
    b = np.asarray(sol.pair_baselines_mm, np.float64)
    spread = float(np.std(b, ddof=1)) if b.size > 1 else float("nan")
    sure = Z95 * spread / np.sqrt(b.size) if b.size > 1 else float("nan")
    return CalibrationWarning(
        "unsynchronised",
        f"The board moved between the left and right pictures of most pairs (carried from one "
        f"camera to the other it lands a median {float(np.median(sol.transfer_px)):.2f} px off, "
        f"while each camera fits its own pictures within "
        f"{float(np.median(sol.own_px)):.2f} px): the cameras do not take their pictures at the "
        f"same moment. Each camera's lens was calibrated on its own pictures, and the rig's pose "
        f"is the one the pairs agree on; the pairs' baselines spread by {spread:.1f} mm, so the "
        f"baseline is known to about +-{sure:.1f} mm. Hold the board still for a moment at each "
        "pose (or capture pairs where it rests), or use cameras that take their pictures "
        "together.", "capture")


# a pair whose board moved between its two pictures (cameras that are not synchronised): its
# transfer error is above both of these. On the real 9x6 webcam set the pairs lie at 0.7-1.9x
# the median (0.20-0.57 px), on the simulated rig at most 2.2x (0.17 px); boards moved by about
# a degree and 4 mm land at 2.3-11.5x and 2.3-7.5 px
MOVED_FACTOR = 2.0  # times the median pair's
MOVED_FLOOR_PX = 1.0
# ... and its cameras each fit their own view of it well (at most this share of the transfer
# error): corners found badly in one image (noise, a wrong corner) are an outlier, not a move
MOVED_OWN_SHARE = 1.0 / 3.0


def moved_pairs(transfer: list[float], own: list[float], factor: float = MOVED_FACTOR,
           floor_px: float = MOVED_FLOOR_PX) -> list[int]:
    """Indexes of pairs whose board moved between the left and right pictures: far off when
    carried from one camera to the other (`transfer`, px), though each camera fits its own view
    (`own`: the worse of the two single-camera errors, px)."""
    t = np.asarray(transfer, np.float64)
    limit = max(factor * float(np.median(t)), floor_px)
    moved = (t > limit) & (np.asarray(own, np.float64) <= MOVED_OWN_SHARE * t)
    return [int(i) for i in np.flatnonzero(moved)]


def outlier_pairs(errors: list[tuple[float, float]], factor: float, floor_px: float) -> list[int]:
    """Indexes of pairs whose worse-camera error is far above the median of all pairs."""
    worst = np.array([max(e) for e in errors])
    limit = max(factor * float(np.median(worst)), floor_px)
    return [int(i) for i in np.flatnonzero(worst > limit)]


@dataclass(frozen=True)
class Fold:
    """Where a camera's lens model folds over inside its image."""

    side: str  # "left" or "right"
    pixel: tuple[float, float]
    off_px: float  # how far that pixel comes back from undistorting and distorting again

    def where(self) -> str:
        return (f"pixel ({self.pixel[0]:.0f}, {self.pixel[1]:.0f}) comes back "
                f"{self.off_px:.3g} px away" if np.isfinite(self.off_px) else
                "OpenCV cannot apply it")

    def text(self) -> str:
        return f"the {self.side} camera's lens model folds over inside its image ({self.where()})"


def folding(sol: Solve, model: str, image_size: tuple[int, int]) -> Fold | None:
    """The first camera whose fitted lens model does not map its own image's pixels to rays
    and back (the pairs did not hold it at the image's edges), or None."""
    if not (np.any(sol.D1) or np.any(sol.D2)):
        return None  # no distortion: the pinhole maps every pixel to one ray and back
    for side, M, D in (("left", sol.M1, sol.D1), ("right", sol.M2, sol.D2)):
        off, pixel = round_trip_px(model, M, D, image_size)
        if not off <= ROUND_TRIP_PX:
            return Fold(side, pixel, off)
    return None
