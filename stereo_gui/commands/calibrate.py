"""`stereo-gui calibrate DIR --board 9x6 --square-mm 25 -o calib.yaml [--json]`.

Finds the image pairs of DIR, detects the chessboard in both images of each pair (on all cores),
calibrates the rig, writes the calibration file and prints a summary (or one JSON object).
Progress goes to stderr so that stdout stays clean for --json.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from stereo_gui.commands import options
from stereo_gui.commands.disparity import check_outputs
from stereo_gui.core.board import (
    DEFAULT_DICTIONARY,
    DICTIONARIES,
    TARGET_NAMES,
    TARGETS,
    BoardSpec,
    parse_board,
)
from stereo_gui.core.calibrate import (
    DEFAULT_MIN_PAIRS,
    CalibrationResult,
    RejectedPair,
    calibrate_hartley_features,
    calibrate_stereo,
    with_measured_shading,
)
from stereo_gui.core.detect import METHODS as DETECTORS
from stereo_gui.core.detect import PairInput, detect_pairs
from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.core.lens import LENS_MODELS, distortion_names
from stereo_gui.core.shading import shading_words
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.calibration_file import export_ros, save_calibration
from stereo_gui.files.pairs import (
    ImagePair,
    PairDiscovery,
    check_same_size,
    discover_pairs,
    load_image,
)
from stereo_gui.files.session import MANIFEST, CaptureSession


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folder", metavar="DIR", help="folder of chessboard pairs (chessboard-L1/-R1, "
                   "left1/right1, or left/ and right/ subfolders)")
    p.add_argument("--target", choices=TARGETS, default="chessboard",
                   help="calibration target: chessboard (default), circles (symmetric circle "
                        "grid), acircles (asymmetric circle grid) or charuco (ChArUco board, "
                        "which counts when partly visible)")
    p.add_argument("--board", default=None,
                   help="COLSxROWS: inner corners of a chessboard (default 9x6), circles of a "
                        "circle grid, squares of a ChArUco board (default 7x5)")
    p.add_argument("--square-mm", type=options.declared(BoardSpec, "square_mm"), default=25.0,
                   help="side of one square in millimetres, or the circle spacing of a circle "
                        "grid (default 25)")
    p.add_argument("--marker-mm", type=options.declared(BoardSpec, "marker_mm"), default=0.0,
                   help="ChArUco: side of the ArUco markers (default 0.75 x square); circle "
                        "grids: circle diameter (not needed to detect them)")
    p.add_argument("--dict", default=DEFAULT_DICTIONARY, choices=DICTIONARIES, metavar="NAME",
                   help=f"ChArUco: the ArUco dictionary (default {DEFAULT_DICTIONARY})")
    p.add_argument("--model", choices=LENS_MODELS, default="pinhole",
                   help="lens model: pinhole (5 coefficients, default), rational (8) or fisheye "
                        "(cv2.fisheye, for wide-angle webcams)")
    p.add_argument("--fix-k3", action="store_true",
                   help="hold k3 (and the higher terms) at zero, when the pairs cannot determine "
                        "them (the warnings say when)")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="calibration file to write (OpenCV FileStorage YAML)")
    p.add_argument("--alpha", type=options.declared(StereoCalibration, "alpha"), default=0.0,
                   help="rectification scaling: 0 keeps only valid pixels, 1 keeps all (default 0)")
    p.add_argument("--method", choices=("bouguet", "hartley"), default="bouguet",
                   help="bouguet (metric, default) or hartley (uncalibrated, no metric scale)")
    p.add_argument("--min-pairs", type=options.whole(1, options.MAX_PAIRS),
                   default=DEFAULT_MIN_PAIRS,
                   help=f"fewest usable pairs to accept (default {DEFAULT_MIN_PAIRS})")
    p.add_argument("--keep-outliers", action="store_true",
                   help="do not drop pairs whose error is far above the median")
    p.add_argument("--detector", choices=DETECTORS, default="classic",
                   help="chessboard detector (default classic: findChessboardCorners + cornerSubPix)")
    p.add_argument("--swap", action="store_true",
                   help="exchange the left and right images (the cameras are swapped; a capture "
                        "session that says so is exchanged without it)")
    p.add_argument("--ros-dir", metavar="DIR", default=None,
                   help="also write ROS camera_info files left.yaml and right.yaml into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a summary")
    p.add_argument("--progress", action="store_true",
                   help="report progress on stderr even when it is not a terminal (one line per "
                        "step); on a terminal progress is always shown")


class _StderrProgress:
    """Progress on stderr: one updating line on a terminal (erased when done, so an error
    message stands alone); a line per tenth of each step otherwise, only when asked for, so that
    scripts see exactly one line on stderr when something is wrong."""

    def __init__(self, force_lines: bool = False) -> None:
        self.tty = sys.stderr.isatty()
        self.enabled = self.tty or force_lines
        self._last: tuple[str, int] | None = None
        self._width = 0

    def __call__(self, done: int, total: int, text: str) -> None:
        if not self.enabled:
            return
        line = f"{text}: {done}/{total}"
        if self.tty:
            sys.stderr.write("\r" + line.ljust(self._width))
            self._width = max(self._width, len(line))
        else:
            key = (text, (10 * done) // max(total, 1))
            if key != self._last or done == total:
                self._last = key
                sys.stderr.write(line + "\n")
        sys.stderr.flush()

    def clear(self) -> None:
        if self.enabled and self.tty and self._width:
            sys.stderr.write("\r" + " " * self._width + "\r")
            sys.stderr.flush()
            self._width = 0


def _finite(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


def _camera(M: np.ndarray, D: np.ndarray, model: str = "pinhole") -> dict[str, Any]:
    d = [float(v) for v in D.reshape(-1)]
    if model == "pinhole":
        d = d[:5] + [0.0] * (5 - len(d[:5]))
    return {"fx": float(M[0, 0]), "fy": float(M[1, 1]), "cx": float(M[0, 2]),
            "cy": float(M[1, 2]), "dist": d}


def result_json(result: CalibrationResult, output: Path | None = None) -> dict[str, Any]:
    """The --json object: the fields scripts depend on (a contract, like the options), plus a
    few more."""
    c, r = result.calibration, result.report
    out = {
        "pairs_found": r.pairs_found,
        "pairs_used": r.pairs_used,
        "pairs_rejected": [{"name": x.name, "reason": x.reason} for x in r.rejected],
        "image_size": [c.width, c.height],
        "rms_left": _finite(r.rms_left),
        "rms_right": _finite(r.rms_right),
        "rms_stereo": _finite(r.rms_stereo),
        "epipolar_error_px": _finite(r.epipolar_error_px),
        "baseline_mm": _finite(r.baseline_mm),
        "left": _camera(c.M1, c.D1, c.model),
        "right": _camera(c.M2, c.D2, c.model),
        "model": c.model,
        "distortion_names": list(distortion_names(c.model, c.D1.size)),
        "board": c.board.to_json() if c.board is not None else None,
        "uncertainty": c.uncertainty.to_json(c) if c.uncertainty is not None else None,
        "warnings": [w.to_json() for w in r.warnings],
        "origin": c.origin,
        "per_pair": [{"name": p.name, "error_left": p.error_left, "error_right": p.error_right}
                     for p in c.per_pair],
        "relative_rotation_deg": _finite(r.relative_rotation_deg),
        "rectified_focal_px": float(c.focal_px),
        "method": c.method,
        "alpha": c.alpha,
        "notes": list(r.notes),
        "lens_shading": None if c.lens_shading is None else {
            side: {"k1": lens.k1, "k2": lens.k2, "black": lens.black,
                   "corner_loss": lens.corner_loss}
            for side, lens in (("left", c.lens_shading.left), ("right", c.lens_shading.right))},
    }
    if output is not None:
        out["output"] = str(output)
    return out


def summary_text(result: CalibrationResult, output: Path | None, seconds: float) -> str:
    """What the command prints: the pairs, the cameras with their ±, the rig, the worst pairs,
    notes and warnings, and the file written (`output` None: nothing was written)."""
    c, r = result.calibration, result.report
    lines = [f"calibrated from {r.pairs_used} of {r.pairs_found} pairs in {seconds:.1f} s "
             f"({c.width}x{c.height}, board {c.board.label() if c.board else '-'}, {c.method}, "
             f"{c.model} lens model)"]
    for x in r.rejected:
        lines.append(f"  rejected {x.name}: {x.reason}")
    u = c.uncertainty
    names = distortion_names(c.model, c.D1.size)

    def pm(side: str, name: str, v: float, digits: int) -> str:
        if u is None:
            return f"{v:.{digits}f}"
        return f"{v:.{digits}f} ± {u.sigma(f'{side}.{name}'):.{digits}f}"

    for side, M, D in (("left", c.M1, c.D1), ("right", c.M2, c.D2)):
        d = "  ".join(f"{n} {pm(side, n, v, 4)}" for n, v in zip(names, D.reshape(-1)))
        lines.append(f"{side:5}: fx {pm(side, 'fx', M[0, 0], 2)}  fy {pm(side, 'fy', M[1, 1], 2)}  "
                     f"cx {pm(side, 'cx', M[0, 2], 2)}  cy {pm(side, 'cy', M[1, 2], 2)} px")
        lines.append(f"       dist {d}")
    if u is not None:
        lines.append("(± is 1 sigma, one standard deviation)")
    if c.optimal_M1 is not None and c.optimal_M2 is not None:
        for side, M in (("left ", c.optimal_M1), ("right", c.optimal_M2)):
            lines.append(f"optimal new camera matrix {side} (alpha 1): fx {M[0, 0]:.2f}  "
                         f"fy {M[1, 1]:.2f}  cx {M[0, 2]:.2f}  cy {M[1, 2]:.2f} px")
    def px(x: float) -> str:
        return f"{x:.3f} px" if math.isfinite(x) else "n/a"

    lines.append(f"RMS reprojection error: left {px(r.rms_left)}, right {px(r.rms_right)}, "
                 f"stereo {px(r.rms_stereo)}")
    lines.append(f"epipolar error after rectification: {r.epipolar_error_px:.3f} px")
    if c.method == "bouguet":
        lines.append(shading_words(c.lens_shading))
    if c.metric and u is not None:
        lines.append(f"baseline {r.baseline_mm:.2f} ± {u.baseline_sigma_mm(c.T):.2f} mm, relative "
                     f"rotation {r.relative_rotation_deg:.3f} ± {u.rotation_sigma_deg(c.R):.3f} "
                     f"deg (1 sigma), rectified focal {c.focal_px:.1f} px")
    elif c.metric:
        lines.append(f"baseline {r.baseline_mm:.2f} mm, relative rotation "
                     f"{r.relative_rotation_deg:.3f} deg, rectified focal {c.focal_px:.1f} px")
    else:
        lines.append(f"relative rotation {r.relative_rotation_deg:.3f} deg; baseline unknown")
    worst = sorted(c.per_pair, key=lambda p: -max(p.error_left, p.error_right))[:3]
    if worst:
        lines.append("worst pairs: " + ", ".join(
            f"{p.name} ({p.error_left:.2f}/{p.error_right:.2f} px)" for p in worst))
    for note in r.notes:
        lines.append(f"NOTE: {note}")
    for w in r.warnings:
        lines.append(f"WARNING ({w.code}): {w.message}")
    lines.append(f"wrote {output}" if output is not None else "NOT WRITTEN (see the error below)")
    return "\n".join(lines)


def _session_in(folder: Path) -> CaptureSession | None:
    """The capture session in `folder`, or None without a manifest (opened once: what its
    manifest could not give is said once, as a warning)."""
    return CaptureSession.open(folder) if (folder / MANIFEST).is_file() else None


def _check_outputs(output: Path, ros_dir: Path | None, found: PairDiscovery,
                   folder: Path) -> None:
    """The calibration and the ROS files may be written: none is one of the set's pictures,
    its session or its truth, they are not one file, and an existing output is a calibration
    (one that is anything else is not written over)."""
    outputs = [(output, None)]
    if ros_dir is not None:
        outputs += [(ros_dir / "left.yaml", None), (ros_dir / "right.yaml", None)]
    inputs = [f for p in found.pairs for f in (p.left, p.right)]
    inputs += [folder / MANIFEST, folder / "truth.json"]
    check_outputs(outputs, inputs)
    if output.is_file():
        try:
            load_any_calibration(output, (640, 480))
        except StereoGuiError:
            raise InputError(f"{output} exists and is not a calibration: choose another name "
                             "(nothing was written)") from None


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    board = parse_board(args.board or ("7x5" if args.target == "charuco" else "9x6"),
                        args.square_mm, args.target, args.marker_mm, args.dict)
    output, ros_dir = _output_paths(args)
    found = discover_pairs(args.folder)
    _check_outputs(output, ros_dir, found, Path(args.folder))
    if found.unpaired:
        sys.stderr.write(f"stereo-gui: warning: {found.warning()}\n")
    chosen = _chosen_pairs(args.folder, found, bool(args.swap))
    progress = _StderrProgress(force_lines=args.progress)
    try:
        result = _calibrate_pairs(args, board, chosen, progress)
    finally:
        progress.clear()
    skipped = [RejectedPair(p.name, "excluded in the capture session")
               for p in found.pairs if p.name in chosen.excluded]
    if skipped:
        r = result.report
        result = replace(result, report=replace(r, pairs_found=r.pairs_found + len(skipped),
                                                rejected=r.rejected + tuple(skipped)))
    try:
        save_calibration(result.calibration, output)
        if ros_dir is not None:
            export_ros(result.calibration, ros_dir)
    except (StereoGuiError, OSError) as exc:
        # the work is not lost for want of a file: what was computed is printed (the worst
        # pairs, the warnings) before the refusal, so the person can leave pairs out or write
        # elsewhere without guessing
        _write_result(args, result, None, time.perf_counter() - t0)
        raise InputError(f"{exc}; the calibration printed above was computed but not written: "
                         f"{_save_remedy(exc)}") from None
    _write_result(args, result, output, time.perf_counter() - t0)
    if ros_dir is not None and not args.json:
        sys.stdout.write(f"wrote {ros_dir / 'left.yaml'} and {ros_dir / 'right.yaml'} "
                         "(ROS camera_info, baseline in metres)\n")
    return 0


def _write_result(args: argparse.Namespace, result: CalibrationResult, output: Path | None,
                  seconds: float) -> None:
    """The result on stdout, as JSON or as the summary; `output` None when it was not written."""
    if args.json:
        sys.stdout.write(json.dumps(result_json(result, output), indent=2) + "\n")
    else:
        sys.stdout.write(summary_text(result, output, seconds) + "\n")
    sys.stdout.flush()


def _save_remedy(exc: Exception) -> str:
    """What to do when the calibration could not be written."""
    if isinstance(exc, OSError):
        return "free space on the disk or give another file with -o, and calibrate again"
    return ("leave out the worst pairs named above (or capture more pairs, with the board in "
            "the image's corners), and calibrate again")


def _output_paths(args: argparse.Namespace) -> tuple[Path, Path | None]:
    """(the calibration file, the folder for the ROS files or None), checked before any work."""
    output = Path(args.output)
    if not output.parent.is_dir() and str(output.parent):
        raise InputError(f"cannot write {output}: folder {output.parent} does not exist")
    if args.ros_dir is not None and not args.ros_dir:
        raise InputError("--ros-dir is empty: give the folder for left.yaml and right.yaml")
    ros_dir = Path(args.ros_dir) if args.ros_dir else None
    if ros_dir is not None and not ros_dir.is_dir():
        raise InputError(f"--ros-dir {ros_dir} is not an existing folder")
    return output, ros_dir


@dataclass(frozen=True)
class _ChosenPairs:
    """The pairs to calibrate from: those of the folder its capture session does not exclude,
    each as (left file, right file) after the exchange the user or the session asks for."""

    session: CaptureSession | None
    excluded: set[str]
    pairs: list[ImagePair]
    sides: list[tuple[Path, Path]]
    swap: bool


def _chosen_pairs(folder: str, found: PairDiscovery, swap_asked: bool) -> _ChosenPairs:
    session = _session_in(Path(folder))
    excluded = {p.name for p in session.pairs if p.excluded} if session else set()
    pairs = [p for p in found.pairs if p.name not in excluded]
    if found.pairs and not pairs:
        raise InputError(f"every pair in {folder} is excluded in its capture session")
    swap = swap_asked or bool(session and session.swapped)
    sides = [(p.right, p.left) if swap else (p.left, p.right) for p in pairs]
    return _ChosenPairs(session, excluded, pairs, sides, swap)


def _calibrate_pairs(args: argparse.Namespace, board: BoardSpec, chosen: _ChosenPairs,
                     progress: _StderrProgress) -> CalibrationResult:
    """Find the target in the chosen pairs and calibrate from them (with no target anywhere
    and --method hartley, from features matched in the scene)."""
    items = [PairInput(p.name, functools.partial(load_image, a), functools.partial(load_image, b),
                       a.name, b.name) for p, (a, b) in zip(chosen.pairs, chosen.sides)]
    detections = detect_pairs(items, board, method=args.detector,
                              progress=lambda d, t, _: progress(
                                  d, t, f"detecting {TARGET_NAMES[board.target]}s"))
    size = check_same_size([(d.left_file, d.image_size) for d in detections])
    if args.method == "hartley" and not any(d.found for d in detections):
        # no board anywhere: Hartley can still work from features matched in the scene
        sys.stderr.write("stereo-gui: warning: no chessboard found; rectifying from "
                         "matched scene features (Hartley, no metric scale, no undistortion)\n")
        images = [(p.name, load_image(a), load_image(b))
                  for p, (a, b) in zip(chosen.pairs, chosen.sides)]
        return calibrate_hartley_features(
            images, progress=lambda d, t, text: progress(d, t, "matching features"))
    swap = chosen.swap
    result = calibrate_stereo(
        detections, board, size, alpha=args.alpha, method=args.method,
        # what is being done, in the calibration's own words ("calibrating the left
        # camera", "... folds over: calibrating again with k3 held at zero", ...)
        progress=lambda d, t, text: progress(d, t, text),
        min_pairs=args.min_pairs, reject_outliers=not args.keep_outliers,
        model=args.model, fix_k3=args.fix_k3,
        origin=f"{args.folder}" + (" with left and right exchanged" if swap else ""))
    if swap:
        result = replace(result, calibration=result.calibration.with_updates(
            swapped_inputs=True))
    result = replace(result, calibration=with_measured_shading(
        result.calibration, detections, items, board))
    controls = chosen.session.camera_controls if chosen.session is not None else None
    if controls is not None:  # the cameras' focus and exposure go with the calibration
        result = replace(result, calibration=result.calibration.with_updates(
            camera_controls=controls.swapped() if swap else controls))
    return result
