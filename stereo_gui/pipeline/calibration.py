"""The Calibration tab's job and texts, without Qt: detect the board in a session's included
pairs and calibrate the rig (run by a JobWorker off the UI thread, with progress and cancel),
and the camera matrices as the report shows them."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import CalibrationResult, calibrate_stereo
from stereo_gui.core.detect import PairDetection, PairInput, detect_pairs
from stereo_gui.core.errors import InputError
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.pipeline.jobs import JobControl, Progress


@dataclass(frozen=True, eq=False)
class CalibrationRun:
    """What a calibration job returns: the result, detections by pair name, rectify maps."""

    result: CalibrationResult
    detections: dict[str, PairDetection]
    files: dict[str, tuple[str, str]]  # pair name -> (left file, right file)
    maps: RectifyMaps
    folder: Path
    excluded: tuple[str, ...]  # pairs left out by the user (session exclusions)


def read_image(path: str) -> np.ndarray:
    """A BGR image from `path`; InputError if it cannot be read."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"cannot read image {path}")
    return img


def calibration_job(folder: Path, board: BoardSpec, alpha: float, method: str,
                    model: str = "pinhole", fix_k3: bool = False):
    """A JobWorker job: detect the board in the session's included pairs and calibrate (with
    left and right exchanged when the session says the cameras are swapped)."""

    def job(control: JobControl):
        from stereo_gui.files.session import CaptureSession

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
        inputs = [PairInput(p.name, (lambda f=a: read_image(f)), (lambda f=b: read_image(f)),
                            Path(a).name, Path(b).name) for p, (a, b) in zip(included, sides)]
        n = len(inputs)
        total = n + 10
        yield Progress(0, total, f"finding the board in {n} pairs")
        dets = detect_pairs(
            inputs, board, cancel=control,
            progress=lambda d, t, s: control.report(d, total, f"finding the board: {s}"))
        yield Progress(n, total, "calibrating")
        result = calibrate_stereo(
            dets, board, alpha=alpha, method=method, cancel=control, model=model, fix_k3=fix_k3,
            progress=lambda d, t, s: control.report(n + round(9 * d / max(t, 1)), total, s),
            origin=f"{folder}" + (" with left and right exchanged" if swapped else ""))
        if swapped:
            result = replace(result, calibration=result.calibration.with_updates(swapped_inputs=True))
        control.check()
        yield Progress(n + 9, total, "computing rectification maps")
        maps = result.calibration.rectify_maps()
        return CalibrationRun(result, {d.name: d for d in dets}, files, maps, Path(folder),
                              excluded)

    return job


def _fmt_matrix(m: np.ndarray | None, digits: int = 3) -> str:
    if m is None:
        return "  (not available)"
    m = np.atleast_2d(np.asarray(m, np.float64))
    cells = [[f"{v:.{digits}f}" for v in row] for row in m]
    width = max(len(c) for row in cells for c in row)
    return "\n".join("  [ " + "  ".join(c.rjust(width) for c in row) + " ]" for row in cells)


def _dist_text(d: np.ndarray, model: str = "pinhole", sigmas=None) -> str:
    from stereo_gui.core.lens import distortion_names

    d = np.asarray(d, np.float64).reshape(-1)
    names = distortion_names(model, d.size)
    if sigmas is None:
        return "  " + "  ".join(f"{n}={v:+.5f}" for n, v in zip(names, d, strict=False))
    return "  " + "  ".join(f"{n}={v:+.5f}" + ("" if s is None else f" ±{s:.5f}")
                            for n, v, s in zip(names, d, sigmas, strict=False))


def matrices_text(calib: StereoCalibration) -> str:
    """The camera matrices and distortion as the report shows them, plus the rectified ones."""
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
