"""Stereo calibration from target detections (Bouguet) or matched points (Hartley).

The Bouguet flow keeps the original scripts' steps, so that their figures can be compared:
`calibrateCamera` per camera (calibrateCameraExtended, or cv2.fisheye.calibrate for the fisheye
model), `getOptimalNewCameraMatrix` (alpha 1, kept as optimal_M1/2 and shown as those scripts
showed it), `stereoCalibrate` with fixed intrinsics; then a joint refinement of all parameters
started from that solution (core.bundle: every point each camera saw, also the ChArUco corners
only one camera saw, and the covariance of the result), because it recovers the relative
rotation, the principal points and the intrinsics more accurately (scripts/bench_calibration.py;
figures in docs/guide.md), and `stereoRectify` (CALIB_ZERO_DISPARITY, alpha configurable).
Pairs whose reprojection error is far above the median are dropped and the calibration is
repeated; they are reported as rejected. One solve of a set of pairs is core.stereo_solve's;
this module decides which pairs, which lens terms, and rectifies the result.

Hartley's method (`stereoRectifyUncalibrated`) needs only matched points and gives row-aligned
images but no metric scale: its results carry method="hartley", a unit baseline and a note.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.board import TARGET_NAMES, BoardSpec
from stereo_gui.core.coverage import uncovered_regions
from stereo_gui.core.detect import PairDetection, PairInput
from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.jobs import Cancel, ProgressCallback, check_cancel, report_progress
from stereo_gui.core.lens import (
    HIGHER_TERMS,
    LENS_MODELS,
    check_model,
    optimal_new_camera,
    stereo_rectify,
    undistort_points,
)
from stereo_gui.core.shading import measure_pair_shading
from stereo_gui.core.stereo_calibration import PairError, StereoCalibration, alpha_problem
from stereo_gui.core.stereo_solve import (
    OUTLIER_FACTOR,
    OUTLIER_FLOOR_PX,
    Solve,
    folding,
    held_ladder,
    moved_pairs,
    no_distortion,
    outlier_pairs,
    rms_px,
    solve,
    unsync_uncertainty,
    unsync_warning,
)
from stereo_gui.core.uncertainty import (
    CalibrationWarning,
    calibration_warnings,
    join_names,
    uncertainty_from_bundle,
)
from stereo_gui.core.util import mutual_ratio_matches, to_gray

log = logging.getLogger(__name__)

DEFAULT_MIN_PAIRS = 5
METHODS = ("bouguet", "hartley")
HARTLEY_NOTE = ("Hartley's method (uncalibrated rectification): images are row-aligned but the "
                "rig has no metric scale; baseline, depths and distances are NOT in millimetres "
                "(the baseline is set to 1 unit).")


@dataclass(frozen=True)
class RejectedPair:
    """A pair left out of the calibration, and why."""

    name: str
    reason: str


@dataclass(frozen=True)
class CalibrationReport:
    """What went into a calibration and how good it is (pixels unless the name says mm/deg)."""

    pairs_found: int  # pairs examined
    pairs_used: int
    used: tuple[str, ...]  # names of the pairs used
    rejected: tuple[RejectedPair, ...]
    rms_left: float
    rms_right: float
    rms_stereo: float
    epipolar_error_px: float
    baseline_mm: float  # for Hartley in units of the nominal baseline, not mm
    relative_rotation_deg: float
    method: str
    notes: tuple[str, ...] = ()
    rms_stereo_fixed_intrinsics: float = float("nan")  # stereoCalibrate's, before joint refinement
    warnings: tuple[CalibrationWarning, ...] = ()  # what a person should know (core.uncertainty)


@dataclass(frozen=True)
class CalibrationResult:
    calibration: StereoCalibration
    report: CalibrationReport


def epipolar_error_px(left_pts: Sequence[np.ndarray], right_pts: Sequence[np.ndarray],
                      M1: np.ndarray, D1: np.ndarray, R1: np.ndarray, P1: np.ndarray,
                      M2: np.ndarray, D2: np.ndarray, R2: np.ndarray, P2: np.ndarray,
                      model: str = "pinhole") -> float:
    """Mean |y_left - y_right| of corresponding points after rectification, px."""
    if not left_pts:
        return float("nan")
    a = np.concatenate([np.asarray(p, np.float64).reshape(-1, 2) for p in left_pts])
    b = np.concatenate([np.asarray(p, np.float64).reshape(-1, 2) for p in right_pts])
    ra = undistort_points(model, a, M1, D1, R=R1, P=P1)
    rb = undistort_points(model, b, M2, D2, R=R2, P=P2)
    return float(np.mean(np.abs(ra[:, 1] - rb[:, 1])))


def _held_words(held: Sequence[str]) -> str:
    return f"{join_names(list(held))} held at zero"


def _origin_held(model: str, held: Sequence[str]) -> str:
    """What a calibration's origin says of the terms held: ", k3 fixed" as it always has for
    k3 and the higher terms, else the terms."""
    if not held:
        return ""
    if no_distortion(model, held):
        return ", no distortion"
    return ", k3 fixed" if tuple(held) == HIGHER_TERMS[model] else f", {join_names(list(held))} fixed"


# ---- Bouguet --------------------------------------------------------------------------------
def calibrate_stereo(detections: Sequence[PairDetection], board: BoardSpec,
                     image_size: tuple[int, int] | None = None, alpha: float = 0.0,
                     method: str = "bouguet", progress: ProgressCallback | None = None,
                     cancel: Cancel = None, min_pairs: int = DEFAULT_MIN_PAIRS,
                     reject_outliers: bool = True, outlier_factor: float = OUTLIER_FACTOR,
                     outlier_floor_px: float = OUTLIER_FLOOR_PX, joint_refinement: bool = True,
                     model: str = "pinhole", fix_k3: bool = False, origin: str = ""
                     ) -> CalibrationResult:
    """Calibrate a stereo rig from target detections of pairs.

    `method` "bouguet" gives a metric calibration (mm); "hartley" rectifies from the same corners
    without metric scale (see calibrate_hartley). `model` is the lens model (core.lens:
    pinhole, rational, fisheye); `fix_k3` holds k3 and the higher terms at zero. Pairs with an
    error above max(outlier_factor x median, outlier_floor_px) are dropped once and the solve
    is repeated. A lens model that folds over inside the image is fitted again at once with
    fewer terms (`held_ladder`, down to no distortion at all), said in a "refit" warning with
    its remedy. The result carries the parameters' uncertainty and warnings
    (core.uncertainty).
    `origin` names where the pairs came from (recorded in the calibration's origin).
    Raises CalibrationError when no target was found or too few pairs are usable.
    """
    _check_arguments(method, model, alpha)
    detections = list(detections)
    n = len(detections)
    if n == 0:
        raise CalibrationError("no image pairs to calibrate from")
    min_pairs = max(1, int(min_pairs))
    if image_size is None:
        image_size = detections[0].image_size
    image_size = (int(image_size[0]), int(image_size[1]))
    usable, rejected = _usable_pairs(detections, board, image_size, min_pairs)
    if method == "hartley":
        return calibrate_hartley(usable, board, image_size, alpha=alpha, n_found=n,
                                 rejected=rejected, progress=progress, cancel=cancel)

    total = 8
    check_cancel(cancel)
    solve = _Solver(board, image_size, joint_refinement, progress, cancel, total, model)
    ladder = held_ladder(model, fix_k3)
    held = ladder[0]
    sol = solve(usable, 0, held)
    if reject_outliers and len(usable) > min_pairs:
        dropped = _dropped_pairs(sol, usable, min_pairs, outlier_factor, outlier_floor_px)
        if dropped:
            rejected.extend(dropped.values())
            usable = [p for i, p in enumerate(usable) if i not in dropped]
            log.info("dropped %d outlier pairs, calibrating again", len(dropped))
            sol = solve(usable, 3, held)
    check_cancel(cancel)
    # a lens model that folds over inside the image (the pairs left its corners free) is fitted
    # again with fewer terms at once: saving it would be refused, and the work lost
    sol, held, refits = _unfolded(sol, usable, solve, ladder)
    check_cancel(cancel)
    report_progress(progress, 6, total, "rectifying")
    calib = _rectified(sol, usable, board, image_size, alpha, model, held, origin)
    result = _with_warnings(calib, sol, usable, detections, rejected, refits, bool(held))
    report_progress(progress, total, total, "done")
    return result


def _with_warnings(calib: StereoCalibration, sol: Solve, usable: list[PairDetection],
                   detections: list[PairDetection], rejected: list[RejectedPair],
                   refits: list[CalibrationWarning], held: bool) -> CalibrationResult:
    """The calibration with its warnings (refits, unsynchronised cameras, core.uncertainty's)
    and the pairs left out (in the order they came), and its report."""
    regions = uncovered_regions(usable, calib.image_size)
    unsync = (unsync_warning(sol),) if sol.unsynchronised else ()
    warnings = (*refits, *unsync, *calibration_warnings(calib, regions, held))
    order = {p.name: i for i, p in enumerate(detections)}
    rejected = sorted(rejected, key=lambda r: order.get(r.name, 0))
    calib = calib.with_updates(warnings=warnings,
                               left_out=tuple((r.name, r.reason) for r in rejected))
    report = CalibrationReport(
        pairs_found=len(detections), pairs_used=len(usable), used=tuple(sol.names),
        rejected=tuple(rejected),
        rms_left=sol.rms_left, rms_right=sol.rms_right, rms_stereo=sol.rms_stereo,
        epipolar_error_px=calib.epipolar_error_px, baseline_mm=calib.baseline_mm,
        relative_rotation_deg=calib.relative_rotation_deg, method="bouguet",
        rms_stereo_fixed_intrinsics=sol.rms_stereo_fixed, warnings=warnings)
    return CalibrationResult(calib, report)


def _check_arguments(method: str, model: str, alpha: float) -> None:
    if method not in METHODS:
        raise CalibrationError(f"unknown calibration method {method!r}; use bouguet or hartley")
    if model not in LENS_MODELS:
        raise CalibrationError(f"unknown lens model {model!r}; use one of {', '.join(LENS_MODELS)}")
    if (why := alpha_problem(alpha)) is not None:
        raise CalibrationError(why)


@dataclass(frozen=True)
class _Solver:
    """What every solve of one calibration shares: `solve(pairs, step0, held)` is `solve` of
    those pairs, its progress counted from step0, with the distortion terms `held` at zero."""

    board: BoardSpec
    image_size: tuple[int, int]
    joint: bool
    progress: ProgressCallback | None
    cancel: Cancel
    total: int
    model: str

    def __call__(self, pairs: list[PairDetection], step0: int, held: Sequence[str]) -> Solve:
        return solve(pairs, self.board, self.image_size, self.joint, self.progress,
                      self.cancel, step0, self.total, self.model, held)


def _usable_pairs(detections: list[PairDetection], board: BoardSpec,
                  image_size: tuple[int, int], min_pairs: int
                  ) -> tuple[list[PairDetection], list[RejectedPair]]:
    """The pairs of `image_size` whose board was found in both images, and the others with why;
    CalibrationError when none is, or fewer than `min_pairs`."""
    rejected: list[RejectedPair] = []
    usable: list[PairDetection] = []
    for p in detections:
        if tuple(p.image_size) != image_size:
            rejected.append(RejectedPair(p.name, f"image size {p.image_size[0]}x{p.image_size[1]} "
                                         f"differs from {image_size[0]}x{image_size[1]}"))
        elif not p.found:
            rejected.append(RejectedPair(p.name, p.reason))
        else:
            usable.append(p)
    if not usable:
        n = len(detections)
        what = (f"{board.cols}x{board.rows} inner corners" if board.target == "chessboard" else
                board.label())
        raise CalibrationError(f"no {TARGET_NAMES[board.target]} ({what}) found in "
                               f"any of {n} pair{'s' if n != 1 else ''}")
    if len(usable) < min_pairs:
        raise CalibrationError(f"only {len(usable)} usable pair{'s' if len(usable) != 1 else ''} "
                               f"(board found in both images), at least {min_pairs} are needed")
    return usable, rejected


def _dropped_pairs(sol: Solve, usable: list[PairDetection], min_pairs: int, factor: float,
                   floor_px: float) -> dict[int, RejectedPair]:
    """The pairs of a first solve to leave out, by index in `usable` (in order), with why: the
    board moved between the two pictures (`_moved`), or an outlier's error (`_outliers`); never
    so many that fewer than `min_pairs` stay (the best of the bad ones are kept)."""
    moved = set(moved_pairs(sol.transfer_px, sol.own_px))
    bad = sorted(moved | set(outlier_pairs(sol.errors, factor, floor_px)))
    bad = sorted(bad, key=lambda i: -max(sol.errors[i]))[: len(usable) - min_pairs]
    if not bad:
        return {}
    med = float(np.median([max(e) for e in sol.errors]))
    med_t = float(np.median(sol.transfer_px))
    dropped: dict[int, RejectedPair] = {}
    for i in sorted(bad):
        el, er = sol.errors[i]
        if i in moved:
            reason = (f"the board moved between the left and right pictures: the left "
                      f"camera's view of it, carried over by the rig's pose, lands "
                      f"{sol.transfer_px[i]:.2f} px from where the right camera saw it "
                      f"(the median pair {med_t:.2f} px), while each camera fits its "
                      f"own view within {sol.own_px[i]:.2f} px; the cameras did not take "
                      "the pair at the same moment")
        else:
            reason = (f"reprojection error {max(el, er):.2f} px is far above the "
                      f"median {med:.2f} px (outlier)")
        dropped[i] = RejectedPair(usable[i].name, reason)
    return dropped


def _unfolded(sol: Solve, usable: list[PairDetection], solve: _Solver,
              ladder: list[tuple[str, ...]]
              ) -> tuple[Solve, tuple[str, ...], list[CalibrationWarning]]:
    """`sol` (solved with `ladder[0]` held), or where a lens model folds over inside its image,
    the solve again with each simpler step of the ladder until none does: the solve, the terms
    it held, and a "refit" warning per step taken. The ladder's last step, a lens without
    distortion, cannot fold: the work of a calibration is never refused for its lens model."""
    model, image_size = solve.model, solve.image_size
    held = ladder[0]
    refits: list[CalibrationWarning] = []
    fold = folding(sol, model, image_size)
    for simpler in ladder[1:]:
        if fold is None:
            break
        text = (f"The {fold.side} camera's lens model, with "
                f"{_held_words(held) if held else 'every distortion term free'}, folded over "
                f"inside its image ({fold.where()})")
        words = "no lens distortion" if no_distortion(model, simpler) else _held_words(simpler)
        log.info("%s: calibrating again with %s", text, words)
        report_progress(solve.progress, 5, solve.total, f"the {fold.side} lens model folds over: "
                                                        f"calibrating again with {words}")
        folded_rms = max(sol.rms_left, sol.rms_right)
        held = simpler
        sol = solve(usable, 5, held)
        refits.append(_refit_warning(text, model, held, folded_rms, sol))
        fold = folding(sol, model, image_size)
    return sol, held, refits


def _refit_warning(text: str, model: str, held: tuple[str, ...], folded_rms: float,
                   sol: Solve) -> CalibrationWarning:
    """The "refit" warning of one step down the ladder: what folded, what was fitted instead,
    and the remedy (pairs that hold the lens at the image's edges)."""
    if not no_distortion(model, held):
        return CalibrationWarning(
            "refit", f"{text}: the pairs do not hold the lens at the image's edges. It was "
                     f"calibrated again with {_held_words(held)}. To fit the full model, capture "
                     "pairs with the board in the image's corners.", "capture")
    rms = max(sol.rms_left, sol.rms_right)
    return CalibrationWarning(
        "refit", f"{text}: even its simplest model folds, so the pairs do not hold the lens at "
                 "the image's edges at all. It was calibrated again with no lens distortion: "
                 f"that cannot fold, but it does not follow the lens either (reprojection error "
                 f"{rms:.2f} px, the folded fit's {folded_rms:.2f} px), and distances away from "
                 "the image's centre are less accurate. To model the lens, capture pairs with "
                 "the board in the image's corners and along its edges, then calibrate again.",
        "capture")


def _rectified(sol: Solve, usable: list[PairDetection], board: BoardSpec,
               image_size: tuple[int, int], alpha: float, model: str, held: tuple[str, ...],
               origin: str) -> StereoCalibration:
    """The calibration of a solve: rectified at `alpha`, with its epipolar error over the
    pairs' common corners, per-pair errors, the parameters' uncertainty and its origin."""
    R1, R2, P1, P2, Q = stereo_rectify(model, sol.M1, sol.D1, sol.M2, sol.D2, image_size, sol.R,
                                       sol.T, alpha)
    opt1 = optimal_new_camera(model, sol.M1, sol.D1, image_size)
    opt2 = optimal_new_camera(model, sol.M2, sol.D2, image_size)
    commons = [p.common() for p in usable]
    epi = epipolar_error_px([c[1] for c in commons], [c[2] for c in commons],
                            sol.M1, sol.D1, R1, P1, sol.M2, sol.D2, R2, P2, model)
    per_pair = tuple(PairError(name, float(el), float(er))
                     for name, (el, er) in zip(sol.names, sol.errors))
    unc = (unsync_uncertainty(sol, model) if sol.unsynchronised
           else uncertainty_from_bundle(sol.bundle, model, bool(held), sol.mono_sigmas))
    return StereoCalibration(
        image_size=image_size, M1=sol.M1, D1=sol.D1, M2=sol.M2, D2=sol.D2, R=sol.R, T=sol.T,
        E=sol.E, F=sol.F, R1=R1, R2=R2, P1=P1, P2=P2, Q=Q, board=board,
        rms_left=sol.rms_left, rms_right=sol.rms_right, rms_stereo=sol.rms_stereo,
        epipolar_error_px=epi, per_pair=per_pair, method="bouguet", alpha=float(alpha),
        optimal_M1=opt1, optimal_M2=opt2, model=check_model(model), uncertainty=unc,
        origin=f"calibrated from {len(usable)} pairs{' in ' + origin if origin else ''} "
               f"({board.label()}, {model} model{_origin_held(model, held)})")


# ---- lens shading ---------------------------------------------------------------------------
def with_measured_shading(calibration: StereoCalibration, detections: Sequence[PairDetection],
                          inputs: Sequence[PairInput], board: BoardSpec | None
                          ) -> StereoCalibration:
    """`calibration` with the lens shading measured on the pairs it was made from (`detections`
    and the `inputs` (core.detect.PairInput) they came from, by name), when the board is a
    chessboard; unchanged otherwise or when it cannot be measured."""
    if board is None or board.target != "chessboard" or calibration.method != "bouguet":
        return calibration
    used = {p.name for p in calibration.per_pair}
    by_name = {i.name: i for i in inputs}

    def loader(x: np.ndarray | Callable[[], np.ndarray]) -> Callable[[], np.ndarray]:
        return x if callable(x) else (lambda: x)

    pairs = [(d, loader(by_name[d.name].left), loader(by_name[d.name].right))
             for d in detections if d.found and d.name in used and d.name in by_name]
    shading = measure_pair_shading(pairs, board.cols, board.rows)
    if shading is None:
        log.info("lens shading not measured (too few white squares far enough from the centre)")
        return calibration
    return calibration.with_updates(lens_shading=shading)


# ---- Hartley --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Hartley:
    """A Hartley rectification's calibration fields (T a unit direction: no metric scale), the
    share of the matches that were inliers and those inliers, undistorted px (N, 2)."""

    F: np.ndarray
    E: np.ndarray
    R: np.ndarray
    T: np.ndarray
    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Q: np.ndarray
    inliers: float
    ul: np.ndarray
    ur: np.ndarray


def _hartley_from_points(pts_l: np.ndarray, pts_r: np.ndarray, image_size: tuple[int, int],
                         M1: np.ndarray, D1: np.ndarray, M2: np.ndarray, D2: np.ndarray,
                         alpha: float) -> _Hartley:
    """Rectifying homographies from matched raw pixel points (N, 2); the calibration fields."""
    # Work on undistorted pixel coordinates so the homographies act after undistortion.
    ul = cv2.undistortPoints(pts_l.reshape(-1, 1, 2).astype(np.float64), M1, D1, P=M1).reshape(-1, 2)
    ur = cv2.undistortPoints(pts_r.reshape(-1, 1, 2).astype(np.float64), M2, D2, P=M2).reshape(-1, 2)
    F, mask = cv2.findFundamentalMat(ul, ur, cv2.FM_RANSAC, 1.0, 0.999)
    if F is None or F.shape != (3, 3):
        raise CalibrationError("could not estimate the fundamental matrix from the matched points")
    inl = mask.reshape(-1).astype(bool)
    ok, H1, H2 = cv2.stereoRectifyUncalibrated(ul[inl], ur[inl], F, image_size)
    if not ok:
        raise CalibrationError("stereoRectifyUncalibrated failed on the matched points")
    # One rectified camera matrix for both sides; R1/R2 are then the homographies expressed in
    # normalised coordinates, which initUndistortRectifyMap and undistortPoints accept as they are.
    Mn = M1.copy()
    R1 = np.linalg.inv(Mn) @ H1 @ M1
    R2 = np.linalg.inv(Mn) @ H2 @ M2
    f, cx, cy = float(Mn[0, 0]), float(Mn[0, 2]), float(Mn[1, 2])
    baseline = 1.0  # nominal: there is no metric scale
    P1 = np.hstack([Mn, np.zeros((3, 1))])
    P2 = np.hstack([Mn, np.array([[-f * baseline], [0.0], [0.0]])])
    Q = np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, 1.0 / baseline, 0]],
                 np.float64)
    E = M2.T @ F @ M1
    Rr, t = _recover_pose(E, ul[inl], ur[inl], M1, M2)
    return _Hartley(F=F, E=E, R=Rr, T=t.reshape(3, 1) * baseline, R1=R1, R2=R2, P1=P1, P2=P2,
                    Q=Q, inliers=float(inl.mean()), ul=ul[inl], ur=ur[inl])


def _recover_pose(E: np.ndarray, ul: np.ndarray, ur: np.ndarray, M1: np.ndarray, M2: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Relative rotation and unit translation direction from E and undistorted pixel points."""
    nl = cv2.undistortPoints(ul.reshape(-1, 1, 2), M1, None).reshape(-1, 2)
    nr = cv2.undistortPoints(ur.reshape(-1, 1, 2), M2, None).reshape(-1, 2)
    _, R, t, _ = cv2.recoverPose(E, nl, nr, np.eye(3))
    return R, t


def calibrate_hartley(pairs: Sequence[PairDetection], board: BoardSpec,
                      image_size: tuple[int, int], alpha: float = 0.0, n_found: int | None = None,
                      rejected: Sequence[RejectedPair] = (), progress: ProgressCallback | None = None,
                      cancel: Cancel = None) -> CalibrationResult:
    """Hartley rectification from the chessboard corners of usable pairs.

    Each camera's intrinsics and distortion still come from calibrateCamera (they need no metric
    scale), so the rectification also removes lens distortion; the relation between the cameras
    comes only from the point matches through the fundamental matrix.
    """
    pairs = [p for p in pairs if p.found]
    sides = [p.sides() for p in pairs]
    ol = [left.object_points(board) for left, _ in sides]
    orr = [right.object_points(board) for _, right in sides]
    L = [left.corners_cv for left, _ in sides]
    Rt = [right.corners_cv for _, right in sides]
    report_progress(progress, 0, 4, "calibrating the left camera")
    rms1, M1, D1, rv1, tv1 = cv2.calibrateCamera(ol, L, image_size, None, None)
    check_cancel(cancel)
    report_progress(progress, 1, 4, "calibrating the right camera")
    rms2, M2, D2, rv2, tv2 = cv2.calibrateCamera(orr, Rt, image_size, None, None)
    check_cancel(cancel)
    report_progress(progress, 2, 4, "rectifying (Hartley)")
    D1, D2 = D1.reshape(1, -1), D2.reshape(1, -1)
    commons = [p.common() for p in pairs]
    pl = np.concatenate([c[1].reshape(-1, 2) for c in commons])
    pr = np.concatenate([c[2].reshape(-1, 2) for c in commons])
    h = _hartley_from_points(pl, pr, image_size, M1, D1, M2, D2, alpha)
    epi = epipolar_error_px([c[1] for c in commons], [c[2] for c in commons], M1, D1, h.R1,
                            h.P1, M2, D2, h.R2, h.P2)
    per_pair = []
    for i, p in enumerate(pairs):
        el = rms_px("pinhole", ol[i], L[i], rv1[i], tv1[i], M1, D1)
        er = rms_px("pinhole", orr[i], Rt[i], rv2[i], tv2[i], M2, D2)
        per_pair.append(PairError(p.name, el, er))
    opt1, _ = cv2.getOptimalNewCameraMatrix(M1, D1, image_size, 1, image_size)
    opt2, _ = cv2.getOptimalNewCameraMatrix(M2, D2, image_size, 1, image_size)
    calib = StereoCalibration(
        image_size=image_size, M1=M1, D1=D1, M2=M2, D2=D2, R=h.R, T=h.T, E=h.E,
        F=h.F, R1=h.R1, R2=h.R2, P1=h.P1, P2=h.P2, Q=h.Q, board=board,
        rms_left=float(rms1), rms_right=float(rms2), rms_stereo=float("nan"),
        epipolar_error_px=epi, per_pair=tuple(per_pair), method="hartley", alpha=float(alpha),
        optimal_M1=opt1, optimal_M2=opt2, left_out=tuple((r.name, r.reason) for r in rejected))
    report_progress(progress, 4, 4, "done")
    report = CalibrationReport(
        pairs_found=len(pairs) + len(rejected) if n_found is None else n_found,
        pairs_used=len(pairs), used=tuple(p.name for p in pairs), rejected=tuple(rejected),
        rms_left=float(rms1), rms_right=float(rms2), rms_stereo=float("nan"),
        epipolar_error_px=epi, baseline_mm=float("nan"),
        relative_rotation_deg=calib.relative_rotation_deg, method="hartley",
        notes=(HARTLEY_NOTE,))
    return CalibrationResult(calib, report)


def match_features(left: np.ndarray, right: np.ndarray, max_features: int = 4000,
                   ratio: float = 0.75) -> tuple[np.ndarray, np.ndarray]:
    """Matched SIFT keypoints of a scene pair (Lowe's ratio test, mutual), (N, 2) px each."""
    sift = cv2.SIFT.create(nfeatures=max_features)
    kl, dl = sift.detectAndCompute(to_gray(left), None)
    kr, dr = sift.detectAndCompute(to_gray(right), None)
    if dl is None or dr is None or len(kl) < 8 or len(kr) < 8:
        raise CalibrationError("too few features in the scene pair to match (need texture)")
    il, ir = mutual_ratio_matches(dl, dr, ratio)
    if len(il) < 8:
        raise CalibrationError(f"only {len(il)} feature matches in the scene pair, at least 8 "
                               "are needed")
    pl = np.array([kl[i].pt for i in il], np.float64)
    pr = np.array([kr[j].pt for j in ir], np.float64)
    return pl, pr


def calibrate_hartley_features(pairs: Sequence[tuple[str, np.ndarray, np.ndarray]],
                               focal_px: float | None = None, progress: ProgressCallback | None = None,
                               cancel: Cancel = None) -> CalibrationResult:
    """Hartley rectification of a rig without a board, from features matched in scene pairs.

    `pairs` holds (name, left, right) images of one size; the matches of all pairs are pooled.
    Without a board there are no intrinsics: a nominal pinhole camera (focal `focal_px`, default
    the image width; centre in the middle; no distortion) stands in, so lens distortion is not
    removed and distances are not metric.
    """
    pairs = list(pairs)
    if not pairs:
        raise CalibrationError("no image pairs to match features in")
    h, w = pairs[0][1].shape[:2]
    pl_all, pr_all, used, rejected = [], [], [], []
    for k, (name, left, right) in enumerate(pairs):
        check_cancel(cancel)
        report_progress(progress, k, len(pairs) + 1, f"matching features ({name})")
        if left.shape[:2] != (h, w) or right.shape[:2] != (h, w):
            raise CalibrationError(f"{name}: images differ in size from the first pair ({w}x{h})")
        try:
            pl, pr = match_features(left, right)
        except CalibrationError as exc:
            rejected.append(RejectedPair(name, str(exc)))
            continue
        pl_all.append(pl)
        pr_all.append(pr)
        used.append(name)
    if not used:
        if len(pairs) == 1:
            raise CalibrationError(f"{pairs[0][0]}: {rejected[0].reason}")
        raise CalibrationError(f"too few feature matches in any of {len(pairs)} pairs "
                               "(the scene needs texture)")
    f = float(focal_px or w)
    M = np.array([[f, 0, (w - 1) / 2.0], [0, f, (h - 1) / 2.0], [0, 0, 1]], np.float64)
    D = np.zeros((1, 5))
    pl, pr = np.concatenate(pl_all), np.concatenate(pr_all)
    res = _hartley_from_points(pl, pr, (w, h), M, D, M.copy(), D.copy(), 0.0)
    epi = epipolar_error_px([res.ul], [res.ur], M, D, res.R1, res.P1, M, D,
                            res.R2, res.P2)
    calib = StereoCalibration(
        image_size=(w, h), M1=M, D1=D, M2=M.copy(), D2=D.copy(), R=res.R, T=res.T,
        E=res.E, F=res.F, R1=res.R1, R2=res.R2, P1=res.P1, P2=res.P2,
        Q=res.Q, board=None, epipolar_error_px=epi, method="hartley")
    note2 = (f"No chessboard: a nominal camera (focal {f:g} px, no distortion) was assumed, so "
             f"lens distortion is not corrected. {len(res.ul)} of {len(pl)} feature matches "
             "were inliers; the epipolar error is measured on them.")
    report_progress(progress, len(pairs) + 1, len(pairs) + 1, "done")
    report = CalibrationReport(
        pairs_found=len(pairs), pairs_used=len(used), used=tuple(used), rejected=tuple(rejected),
        rms_left=float("nan"), rms_right=float("nan"), rms_stereo=float("nan"),
        epipolar_error_px=epi, baseline_mm=float("nan"),
        relative_rotation_deg=calib.relative_rotation_deg, method="hartley",
        notes=(HARTLEY_NOTE, note2))
    return CalibrationResult(calib, report)


def calibrate_hartley_scene(left: np.ndarray, right: np.ndarray, name: str = "scene",
                            focal_px: float | None = None) -> CalibrationResult:
    """Hartley rectification from one scene pair (see calibrate_hartley_features)."""
    if left.shape[:2] != right.shape[:2]:
        raise CalibrationError(f"{name}: left and right images have different sizes")
    return calibrate_hartley_features([(name, left, right)], focal_px)
