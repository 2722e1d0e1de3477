"""The Calibration tab's job and texts, without Qt: detect the board in a session's included
pairs and calibrate the rig (run by a JobWorker off the UI thread, with progress and cancel),
each used pair's corners reprojected through the result (for the review), and the camera
matrices laid out as the original scripts printed them, so a user can compare the two."""

from __future__ import annotations

import logging
from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import CalibrationResult, calibrate_stereo, with_measured_shading
from stereo_gui.core.detect import PairDetection, PairInput, detect_pairs
from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import JobControl, Progress
from stereo_gui.core.lens import distortion_names, project_points, undistort_points
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.core.util import how_many
from stereo_gui.files.images import read_image_file
from stereo_gui.files.session import CaptureSession

log = logging.getLogger(__name__)

_POSE_ITERATIONS = 30


@dataclass(frozen=True, eq=False)
class PairReprojection:
    """One pair's corners as detected and as the calibration reprojects them, raw image pixels.

    The board pose is fitted to both images' corners at once (the cameras and R, T fixed: what
    the calibration's joint refinement did for this pair), so `rms_left_px`/`rms_right_px` are
    the pair's reprojection errors (root mean square over its points, px) as the chart shows.
    """

    name: str
    detected_left: np.ndarray  # (N, 2) px
    reprojected_left: np.ndarray  # (N, 2) px
    detected_right: np.ndarray  # (M, 2) px
    reprojected_right: np.ndarray  # (M, 2) px
    rms_left_px: float
    rms_right_px: float


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1)))) if len(d) else float("nan")


def reproject_pair(calib: StereoCalibration, det: PairDetection,
                   board: BoardSpec) -> PairReprojection | None:
    """The pair's corners reprojected through `calib` (see PairReprojection); None when the
    calibration has no metric R, T (Hartley) or the pair has no corners in both images."""
    if not calib.metric or det.left is None or det.right is None:
        return None
    model = calib.model
    obj_l = np.asarray(det.left.object_points(board), np.float64)
    obj_r = np.asarray(det.right.object_points(board), np.float64)
    img_l = np.asarray(det.left.corners, np.float64).reshape(-1, 2)
    img_r = np.asarray(det.right.corners, np.float64).reshape(-1, 2)
    if len(img_l) < 4:
        return None
    # start: the left camera's view of the board alone
    norm = undistort_points(model, img_l, calib.M1, calib.D1)
    ok, rb, tb = cv2.solvePnP(obj_l.reshape(-1, 1, 3), norm.reshape(-1, 1, 2), np.eye(3), None)
    if not ok:
        return None
    rb, tb = rb.reshape(3, 1).astype(np.float64), tb.reshape(3, 1).astype(np.float64)
    r_lr = cv2.Rodrigues(np.asarray(calib.R, np.float64))[0]
    t_lr = np.asarray(calib.T, np.float64).reshape(3, 1)

    def residuals(rb: np.ndarray, tb: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pl, jl = project_points(model, obj_l, rb, tb, calib.M1, calib.D1, jacobian=True)
        r2, t2, dr3dr1, dr3dt1, _, _, dt3dr1, dt3dt1, _, _ = cv2.composeRT(rb, tb, r_lr, t_lr)
        pr, jr = project_points(model, obj_r, r2, t2, calib.M2, calib.D2, jacobian=True)
        jr_b = jr[:, 0:3] @ np.hstack([dr3dr1, dr3dt1]) + jr[:, 3:6] @ np.hstack([dt3dr1, dt3dt1])
        res = np.concatenate([(pl - img_l).reshape(-1), (pr - img_r).reshape(-1)])
        return res, np.vstack([jl[:, 0:6], jr_b]), pl, pr

    lam = 1e-3
    res, J, pl, pr = residuals(rb, tb)
    cost = float(res @ res)
    for _ in range(_POSE_ITERATIONS):  # Levenberg-Marquardt over the six pose parameters
        A = J.T @ J
        step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), -J.T @ res)
        rn, tn = rb + step[:3].reshape(3, 1), tb + step[3:].reshape(3, 1)
        res_n, J_n, pl_n, pr_n = residuals(rn, tn)
        cost_n = float(res_n @ res_n)
        if cost_n < cost:
            done = (cost - cost_n) <= 1e-12 * max(cost, 1e-300)
            rb, tb, res, J, pl, pr, cost = rn, tn, res_n, J_n, pl_n, pr_n, cost_n
            lam = max(lam / 10.0, 1e-12)
            if done:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return PairReprojection(det.name, img_l, pl, img_r, pr, _rms(pl, img_l), _rms(pr, img_r))


def reproject_pairs(calib: StereoCalibration, detections: Mapping[str, PairDetection],
                    board: BoardSpec, names: Iterable[str]) -> dict[str, PairReprojection]:
    """`reproject_pair` for each named pair whose detection is known (failures are logged)."""
    out: dict[str, PairReprojection] = {}
    for name in names:
        det = detections.get(name)
        if det is None:
            continue
        try:
            rp = reproject_pair(calib, det, board)
        except (cv2.error, np.linalg.LinAlgError) as exc:
            log.warning("pair %s: reprojection failed: %s", name, exc)
            continue
        if rp is not None:
            out[name] = rp
    return out


@dataclass(frozen=True, eq=False)
class CalibrationRun:
    """What a calibration job returns: the result, detections by pair name, rectify maps."""

    result: CalibrationResult
    detections: dict[str, PairDetection]
    files: dict[str, tuple[str, str]]  # pair name -> (left file, right file)
    maps: RectifyMaps
    folder: Path
    excluded: tuple[str, ...]  # pairs left out by the user (session exclusions)
    reprojections: dict[str, PairReprojection] = field(default_factory=dict)  # used pairs


EXCLUDED_BY_YOU = "excluded by you"  # why an excluded pair is not in a calibration


def read_image(path: str | Path) -> np.ndarray:
    """A BGR image from `path`; InputError if it cannot be read."""
    return read_image_file(path, cv2.IMREAD_COLOR)


def calibration_job(folder: Path, board: BoardSpec, alpha: float, method: str,
                    model: str = "pinhole", fix_k3: bool = False
                    ) -> Callable[[JobControl], Generator[Progress, None, CalibrationRun]]:
    """A JobWorker job: detect the board in the session's included pairs and calibrate (with
    left and right exchanged when the session says the cameras are swapped)."""

    def job(control: JobControl) -> Generator[Progress, None, CalibrationRun]:
        yield Progress(0, 1, f"reading {folder}")
        session = CaptureSession.open(folder)
        included = list(session.included_pairs())
        excluded = tuple(p.name for p in session.pairs if p.excluded)
        swapped = bool(getattr(session, "swapped", False))
        if not included:
            raise InputError(f"{folder} has no image pairs to calibrate from"
                             + (f" ({len(excluded)} excluded)" if excluded else ""))
        sides = [(p.right, p.left) if swapped else (p.left, p.right) for p in included]
        files = {p.name: (str(a), str(b)) for p, (a, b) in zip(included, sides)}
        inputs = [PairInput(p.name, partial(read_image, a), partial(read_image, b),
                            Path(a).name, Path(b).name) for p, (a, b) in zip(included, sides)]
        n = len(inputs)
        total = n + 10
        yield Progress(0, total, f"finding the board in {how_many(n, 'pair')}")
        dets = detect_pairs(
            inputs, board, cancel=control,
            progress=lambda d, t, s: control.report(d, total, f"finding the board: {s}"))
        yield Progress(n, total, "calibrating")
        result = calibrate_stereo(
            dets, board, alpha=alpha, method=method, cancel=control, model=model, fix_k3=fix_k3,
            progress=lambda d, t, s: control.report(n + round(9 * d / max(t, 1)), total, s),
            origin=f"{folder}" + (" with left and right exchanged" if swapped else ""))
        yield Progress(n + 8, total, "measuring the lens shading")
        result = replace(result, calibration=with_measured_shading(
            result.calibration, dets, inputs, board))
        control.check()
        if swapped:
            result = replace(result, calibration=result.calibration.with_updates(swapped_inputs=True))
        if excluded:  # recorded with the calibration, beside the pairs it rejected
            calib = result.calibration
            result = replace(result, calibration=calib.with_updates(
                left_out=tuple((name, EXCLUDED_BY_YOU) for name in excluded) + calib.left_out))
        if session.camera_controls is not None:
            result = replace(result, calibration=result.calibration.with_updates(
                camera_controls=session.calibration_controls()))
        control.check()
        yield Progress(n + 9, total, "computing rectification maps")
        maps = result.calibration.rectify_maps()
        by_name = {d.name: d for d in dets}
        control.check()
        reprojections = reproject_pairs(result.calibration, by_name, board,
                                        [p.name for p in result.calibration.per_pair])
        return CalibrationRun(result, by_name, files, maps, Path(folder), excluded,
                              reprojections)

    return job


def _fmt_matrix(m: np.ndarray | None, digits: int = 3) -> str:
    if m is None:
        return "  (not available)"
    m = np.atleast_2d(np.asarray(m, np.float64))
    cells = [[f"{v:.{digits}f}" for v in row] for row in m]
    width = max(len(c) for row in cells for c in row)
    return "\n".join("  [ " + "  ".join(c.rjust(width) for c in row) + " ]" for row in cells)


def _dist_text(d: np.ndarray, model: str = "pinhole",
               sigmas: Sequence[float | None] | None = None) -> str:
    d = np.asarray(d, np.float64).reshape(-1)
    names = distortion_names(model, d.size)
    if sigmas is None:
        return "  " + "  ".join(f"{n}={v:+.5f}" for n, v in zip(names, d, strict=False))
    return "  " + "  ".join(f"{n}={v:+.5f}" + ("" if s is None else f" ±{s:.5f}")
                            for n, v, s in zip(names, d, sigmas, strict=False))


def matrices_text(calib: StereoCalibration) -> str:
    """The camera matrices and distortion in the original scripts' layout, plus the rectified
    ones."""
    parts = []
    for side, M, opt, D, P in (("left", calib.M1, calib.optimal_M1, calib.D1, calib.P1),
                               ("right", calib.M2, calib.optimal_M2, calib.D2, calib.P2)):
        parts += [
            f"Matrix M without rectification ({side} camera, {'M1' if side == 'left' else 'M2'}):",
            _fmt_matrix(M, 2),
            f"Matrix Mrekt rectified ({side} camera, getOptimalNewCameraMatrix alpha=1):",
            _fmt_matrix(opt, 2),
            f"Rectified projection {'P1' if side == 'left' else 'P2'} ({side}, used for depth):",
            _fmt_matrix(P, 2),
            f"Distortion {'D1' if side == 'left' else 'D2'} ({side}, {calib.model} model"
            + (", ± 1 sigma" if calib.uncertainty is not None else "") + "):",
            _dist_text(D, calib.model, None if calib.uncertainty is None else
                       calib.uncertainty.camera(side, np.asarray(D).size)["dist"]),
            "",
        ]
    parts += ["Rotation R (left camera frame -> right camera frame):", _fmt_matrix(calib.R, 5),
              "Translation T (mm):", _fmt_matrix(np.asarray(calib.T).reshape(1, 3), 3)]
    return "\n".join(parts)
