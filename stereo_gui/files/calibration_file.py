"""Calibration files: OpenCV FileStorage YAML (our format) and ROS camera_info YAML (export/import).

Our file uses the names of OpenCV's stereo sample (M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q) so that C++
tools read it with cv2::FileStorage, plus image size, board, quality figures, per-pair errors,
method, alpha, creation time and `format_version`. T and the P2/Q translation terms are in mm.

The file also records the lens model (`lens_model`), how the calibration was made (`origin`),
the warnings found then, and the parameters' 1-sigma covariance (`uncertainty_names`,
`uncertainty_covariance`); files without them load as before (no uncertainty). It records the
cameras' controls when the pairs were captured (`camera_controls`: `left` and `right` maps of
backend, focus, exposure...; switches as 0/1), so that they can be restored and a changed focus
noticed; files without them load as before, and a damaged `camera_controls` is left out with a
warning in the log, the calibration itself still loads.

ROS camera_info files (left.yaml, right.yaml) follow ROS's layout ({rows, cols, data} matrices,
distortion_model plumb_bob, rational_polynomial or equidistant for fisheye lenses) and ROS's unit
for the projection's translation term: METRES.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import re
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.camera_settings import SWITCHES, PairSettings
from stereo_gui.core.errors import CalibrationFileError, InputError
from stereo_gui.core.stereo_calibration import (
    MATRIX_SHAPES,
    PairError,
    StereoCalibration,
    check_matrices,
)
from stereo_gui.files.atomic import os_error_text, write_many_atomic, write_text_atomic

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
# ROS camera_info's distortion_model of each lens model (core.lens)
ROS_DISTORTION_MODELS = {"pinhole": "plumb_bob", "rational": "rational_polynomial",
                         "fisheye": "equidistant"}
MATRIX_NAMES = ("M1", "D1", "M2", "D2", "R", "T", "E", "F", "R1", "R2", "P1", "P2", "Q")


# ---- OpenCV FileStorage YAML -------------------------------------------------------------------
def calibration_text(calib: StereoCalibration) -> str:
    """`calib` as the FileStorage YAML text `save_calibration` writes."""
    fs = cv2.FileStorage(".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY
                         | cv2.FILE_STORAGE_FORMAT_YAML)
    if not fs.isOpened():
        raise InputError("OpenCV could not start a FileStorage document")
    fs.write("format_version", FORMAT_VERSION)
    fs.write("created", calib.created)
    fs.write("method", calib.method)
    fs.write("alpha", float(calib.alpha))
    fs.write("image_width", int(calib.width))
    fs.write("image_height", int(calib.height))
    if calib.scaled_from is not None:
        fs.write("scaled_from_width", int(calib.scaled_from[0]))
        fs.write("scaled_from_height", int(calib.scaled_from[1]))
    for name in MATRIX_NAMES:
        fs.write(name, np.asarray(getattr(calib, name), np.float64))
    for name in ("optimal_M1", "optimal_M2"):
        m = getattr(calib, name)
        if m is not None:
            fs.write(name, np.asarray(m, np.float64))
    if calib.board is not None:
        fs.write("board_cols", int(calib.board.cols))
        fs.write("board_rows", int(calib.board.rows))
        fs.write("square_mm", float(calib.board.square_mm))
        if calib.board.target != "chessboard":
            fs.write("board_target", calib.board.target)
            fs.write("marker_mm", float(calib.board.marker_mm))
        if calib.board.target == "charuco":
            fs.write("board_dictionary", calib.board.dictionary)
    _write_lens_and_uncertainty(fs, calib)
    _write_camera_controls(fs, calib)
    _write_lens_shading(fs, calib)
    fs.write("rms_left", float(calib.rms_left))
    fs.write("rms_right", float(calib.rms_right))
    fs.write("rms_stereo", float(calib.rms_stereo))
    fs.write("epipolar_error_px", float(calib.epipolar_error_px))
    fs.write("baseline_mm", float(calib.baseline_mm))  # for people reading the file
    fs.startWriteStruct("per_pair", cv2.FileNode_SEQ)
    for pe in calib.per_pair:
        fs.startWriteStruct("", cv2.FileNode_MAP)
        fs.write("name", str(pe.name))
        fs.write("error_left", float(pe.error_left))
        fs.write("error_right", float(pe.error_right))
        fs.endWriteStruct()
    fs.endWriteStruct()
    return fs.releaseAndGetString()


def _same_calibration(a: StereoCalibration, b: StereoCalibration) -> bool:
    for name in MATRIX_NAMES:
        if not np.array_equal(np.asarray(getattr(a, name), np.float64).reshape(-1),
                              np.asarray(getattr(b, name), np.float64).reshape(-1)):
            return False
    return (a.image_size == b.image_size and len(a.per_pair) == len(b.per_pair)
            and a.board == b.board and _controls_of(a) == _controls_of(b)
            and _same_shading(a.lens_shading, b.lens_shading))


def _same_shading(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return all(math.isclose(getattr(getattr(a, side), k), getattr(getattr(b, side), k),
                            rel_tol=1e-9, abs_tol=1e-12)
               for side in ("left", "right") for k in ("k1", "k2", "black"))


def _controls_of(calib: StereoCalibration):
    c = calib.camera_controls
    return None if c is None or c.empty else c


def save_calibration(calib: StereoCalibration, path: str | Path) -> Path:
    """Write `calib` to `path` as FileStorage YAML, atomically; return the path.

    cv2.FileStorage does not report a failed write (a full disk leaves a torn file and no error),
    so the document is made in memory, written by files.atomic, and read back with
    `load_calibration` before it replaces `path`.
    """
    path = Path(path)
    check_calibration(calib, f"cannot save {path}")
    text = calibration_text(calib)

    def verify(tmp: Path) -> None:
        if not _same_calibration(load_calibration(tmp), calib):
            raise CalibrationFileError("the matrices read back differ from those written")

    write_text_atomic(path, text, verify)
    return path


def _parse_error(exc: BaseException) -> str:
    """The parser's own words ('line 3: Invalid or unsupported syntax'): the binding raises a
    SystemError whose text only names the binding, with OpenCV's error as its cause."""
    cause = exc.__cause__ or exc.__context__
    if isinstance(exc, SystemError) and isinstance(cause, cv2.error):
        exc = cause
    text = str(exc).strip()
    found = re.search(r"\((\d+)\): ([^']+)'?\s*$", text)
    if found:
        return f"line {found.group(1)}: {found.group(2).strip()}"
    return text.splitlines()[-1] if text else type(exc).__name__


MAX_FILE_BYTES = 4 << 20  # a calibration with a thousand pairs is a few hundred kB
MAX_NESTING = 64


def _check_parsable(path: Path, where: str) -> None:
    """Refuse what would crash OpenCV's parser: it recurses per nesting level and a file with
    100,000 nested brackets overflows the C stack (a segmentation fault, not an error)."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise CalibrationFileError(f"{where} is {size} bytes: too large for a calibration")
        data = path.read_bytes()
    except OSError as exc:
        raise CalibrationFileError(f"{where} cannot be read: {os_error_text(exc)}") from None
    depth = deepest = 0
    quote = 0
    for byte in data:
        if quote:
            if byte == quote:
                quote = 0
        elif byte in (0x22, 0x27):  # " '
            quote = byte
        elif byte in (0x5B, 0x7B):  # [ {
            depth += 1
            deepest = max(deepest, depth)
        elif byte in (0x5D, 0x7D):  # ] }
            depth = max(0, depth - 1)
        elif byte == 0x0A:
            quote = 0
    indent = max((len(line) - len(line.lstrip(b" \t")) for line in data.splitlines()),
                 default=0)
    if deepest > MAX_NESTING or indent > 40 * MAX_NESTING:
        raise CalibrationFileError(f"{where} is nested too deeply to be a calibration file")


def _open(path: Path) -> cv2.FileStorage:
    if not path.exists():
        raise CalibrationFileError(f"calibration file {path} does not exist")
    if not path.is_file():
        raise CalibrationFileError(f"calibration file {path} is not a file")
    try:  # opened by Python first: OpenCV would call an unreadable file "not FileStorage"
        with open(path, "rb"):
            pass
    except OSError as exc:
        raise CalibrationFileError(f"calibration file {path} cannot be read: "
                                   f"{os_error_text(exc)}") from None
    _check_parsable(path, f"calibration file {path}")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        raise CalibrationFileError(
            f"{path} is not an OpenCV FileStorage file ({_parse_error(exc)})") from None
    if not fs.isOpened():
        raise CalibrationFileError(f"{path} is not an OpenCV FileStorage file")
    return fs


def _real(fs, name: str, where: str, default: float | None = None) -> float:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        if default is not None:
            return default
        raise CalibrationFileError(f"{where}: {name} is missing")
    if not (node.isReal() or node.isInt()):
        raise CalibrationFileError(f"{where}: {name} should be a number")
    return float(node.real())


def _int(fs, name: str, where: str) -> int:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        raise CalibrationFileError(f"{where}: {name} is missing")
    if not node.isInt():
        raise CalibrationFileError(f"{where}: {name} should be a whole number")
    return int(node.real())


def _string(fs, name: str, default: str) -> str:
    node = fs.getNode(name)
    return node.string() if node.isString() else default


def _mat(fs, name: str, where: str, max_side: int = 16) -> np.ndarray | None:
    node = fs.getNode(name)
    if node.empty() or node.isNone():
        return None
    # check the header against the data before OpenCV reads it: a huge rows x cols makes
    # FileNode.mat() abort the process instead of raising
    rows, cols, dt, data = (node.getNode(k) for k in ("rows", "cols", "dt", "data"))
    if not node.isMap() or rows.empty() or cols.empty() or data.empty():
        raise CalibrationFileError(f"{where}: {name} is not a matrix")
    if not (rows.isInt() and cols.isInt() and 1 <= rows.real() <= max_side
            and 1 <= cols.real() <= max_side):
        raise CalibrationFileError(f"{where}: matrix {name} should have 1 to {max_side} rows and "
                                   "columns")
    if not (dt.isString() and dt.string() in ("d", "f", "i", "u", "s", "c", "w")):
        raise CalibrationFileError(f"{where}: matrix {name} has an unknown element type")
    if not data.isSeq() or data.size() != int(rows.real()) * int(cols.real()):
        raise CalibrationFileError(f"{where}: matrix {name} says {int(rows.real())}x"
                                   f"{int(cols.real())} but holds {data.size()} values")
    try:
        m = node.mat()
    except (cv2.error, SystemError) as exc:  # a header that disagrees with its data, ...
        raise CalibrationFileError(f"{where}: matrix {name} is not readable "
                                   f"({_parse_error(exc)})") from None
    if m is None:
        raise CalibrationFileError(f"{where}: {name} is not a matrix")
    return np.asarray(m, np.float64)


# ---- validation -------------------------------------------------------------------------------
MAX_IMAGE_SIDE_PX = 100_000  # larger images are not made by any camera: the file is damaged
MAX_FOCAL_PX = 1e7
MAX_BASELINE_MM = 1e7
MAX_DISTORTION = 1e6
MAX_UNCERTAINTY_PARAMETERS = 128  # both cameras' intrinsics and distortion, rotation, translation


def _fail(where: str, text: str) -> None:
    raise CalibrationFileError(f"{where}: {text}")


def _check_size(w: int, h: int, where: str, what: str = "image size") -> None:
    if not (0 < w <= MAX_IMAGE_SIDE_PX and 0 < h <= MAX_IMAGE_SIDE_PX):
        _fail(where, f"{what} {w}x{h} is not valid (1 to {MAX_IMAGE_SIDE_PX} px a side)")


def _check_camera(M: np.ndarray, name: str, where: str) -> None:
    fx, fy = M[0, 0], M[1, 1]
    if not (0 < fx <= MAX_FOCAL_PX and 0 < fy <= MAX_FOCAL_PX):
        _fail(where, f"matrix {name} has focal lengths {fx:g}, {fy:g} px (they must be positive "
                     f"and at most {MAX_FOCAL_PX:g})")
    if not np.allclose(M[2], (0.0, 0.0, 1.0), atol=1e-9) or M[1, 0] != 0:
        _fail(where, f"matrix {name} is not a camera matrix (its last row must be 0 0 1)")


def check_calibration(calib: StereoCalibration, where: str) -> None:
    """Raise CalibrationFileError naming the field of `calib` that no camera could have: an
    absurd image size, a zero or negative focal length, a zero baseline, a singular
    rectification, not a rotation, negative or non-finite quality figures, ...

    NaN quality figures mean "not known" where a calibration legitimately has none (an imported
    or already-rectified calibration has no per-pair record; Hartley's method has no stereo RMS);
    anywhere else they are refused.
    """
    with np.errstate(all="ignore"):  # absurd values overflow on their way to being refused
        _check_calibration(calib, where)


def _check_calibration(calib: StereoCalibration, where: str) -> None:
    check_matrices({k: getattr(calib, k) for k in MATRIX_SHAPES}
                   | {"D1": calib.D1, "D2": calib.D2}, where)
    _check_size(calib.width, calib.height, where)
    if calib.scaled_from is not None:
        sw, sh = calib.scaled_from
        _check_size(sw, sh, where, "scaled_from size")
        if sw * calib.height != sh * calib.width:
            _fail(where, f"scaled_from size {sw}x{sh} does not have the aspect ratio of "
                         f"{calib.width}x{calib.height}")
    _check_camera(calib.M1, "M1", where)
    _check_camera(calib.M2, "M2", where)
    for name in ("D1", "D2"):
        if np.max(np.abs(getattr(calib, name))) > MAX_DISTORTION:
            _fail(where, f"distortion {name} holds coefficients above {MAX_DISTORTION:g}")
    R = calib.R
    if np.max(np.abs(R)) > 1.0 + 1e-4 or not (
            np.allclose(R.T @ R, np.eye(3), atol=1e-4) and abs(np.linalg.det(R) - 1) < 1e-4):
        _fail(where, "matrix R is not a rotation")
    baseline = calib.baseline_mm
    if not 0 < baseline <= MAX_BASELINE_MM:
        _fail(where, f"T gives a baseline of {baseline:g} mm (it must be positive and at most "
                     f"{MAX_BASELINE_MM:g} mm)")
    for name in ("R1", "R2"):
        if not abs(np.linalg.det(getattr(calib, name))) > 1e-9:
            _fail(where, f"matrix {name} is singular: it cannot rectify")
    for name in ("P1", "P2"):
        P = getattr(calib, name)
        if not (0 < P[0, 0] <= MAX_FOCAL_PX and 0 < P[1, 1] <= MAX_FOCAL_PX):
            _fail(where, f"matrix {name} has focal lengths {P[0, 0]:g}, {P[1, 1]:g} px (they "
                         "must be positive)")
    if calib.P2[0, 3] == 0 and calib.P2[1, 3] == 0:
        _fail(where, "matrix P2 has no baseline term (P2[0,3] and P2[1,3] are zero)")
    if calib.Q[2, 3] == 0 or calib.Q[3, 2] == 0:
        _fail(where, "matrix Q cannot turn disparities into distances (Q[2,3] or Q[3,2] is 0)")
    if calib.method not in ("bouguet", "hartley", "identity"):
        _fail(where, f"unknown method {calib.method!r}")
    if not (math.isfinite(calib.alpha) and -1.0 <= calib.alpha <= 1.0):
        _fail(where, f"alpha {calib.alpha:g} is not between -1 and 1")
    check_plausible(calib, where)
    unknown_ok = not calib.per_pair
    for name in ("rms_left", "rms_right", "rms_stereo", "epipolar_error_px"):
        v = _as_float(getattr(calib, name))
        if math.isnan(v):
            if unknown_ok or (name == "rms_stereo" and calib.method == "hartley"):
                continue
            _fail(where, f"{name} is not a number")
        if not (math.isfinite(v) and v >= 0):
            _fail(where, f"{name} is {v:g}; it must be a finite number of pixels >= 0")
    for i, pe in enumerate(calib.per_pair, start=1):
        for side, v in (("error_left", pe.error_left), ("error_right", pe.error_right)):
            v = _as_float(v)
            if not (math.isfinite(v) and v >= 0):
                _fail(where, f"per_pair entry {i} ({pe.name}): {side} is {v:g}; it must be a "
                             "finite number of pixels >= 0")


# ---- physical plausibility -------------------------------------------------------------------
# What any camera pair and its rectification obey, whoever computed them. Each test names the
# field that fails it. Tolerances allow a file written with fewer digits than ours (a hand-made
# or another tool's file); damage is orders of magnitude beyond them.
MIN_BASELINE_MM = 1.0  # a metric calibration's cameras are apart by at least this
PLAUSIBLE_BASELINE_MM = 100_000.0  # 100 m: beyond, readings become absurd, not a rig
MIN_FOV_FOCAL = 0.05  # focal length in image widths: below, a pinhole view wider than 174 deg
MAX_FOV_FOCAL = 100.0  # above, a view narrower than 0.6 deg
MAX_FOCAL_RATIO = 3.0  # the two cameras, and the rectified ones, differ in focal length by less
ROTATION_TOL = 1e-3
RELATIVE_TOL = 1e-3


def _near(a, b, tol: float = RELATIVE_TOL) -> bool:
    """Each element of `a` within `tol` of its own size of `b`'s (zeros: of the largest's)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1e-300)
    return bool(np.all(np.abs(a - b) <= tol * np.maximum(np.abs(a), np.abs(b)) + 1e-9 * scale))


def _is_rotation(m: np.ndarray) -> bool:
    return (np.allclose(m.T @ m, np.eye(3), atol=ROTATION_TOL)
            and abs(np.linalg.det(m) - 1.0) < ROTATION_TOL)


def _same_up_to_scale(a: np.ndarray, b: np.ndarray) -> bool:
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if not (na > 0 and nb > 0):
        return False
    a, b = a / na, b / nb  # unit norm: compared against 1, whatever each element's size
    return min(np.max(np.abs(a - b)), np.max(np.abs(a + b))) <= RELATIVE_TOL


def _q_of(P1: np.ndarray, P2: np.ndarray, vertical: bool) -> np.ndarray:
    """The disparity-to-depth matrix cv2.stereoRectify builds from the rectified projections."""
    if not vertical:
        return q_from_projections(P1, P2)
    f, cx, cy = P1[1, 1], P1[0, 2], P1[1, 2]
    ty = P2[1, 3] / P2[1, 1]
    return np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f],
                     [0, 0, -1.0 / ty, (cy - P2[1, 2]) / ty]], np.float64)


def check_plausible(calib: StereoCalibration, where: str) -> None:
    """Raise CalibrationFileError naming the field of `calib` that no camera pair has, or that
    disagrees with the rest: focal lengths for no lens (or two cameras, or the rectified ones,
    far apart), a principal point outside the image, a lens model that does not map the image's
    own pixels, a baseline of less than a millimetre or more than 100 m, rectification
    rotations that are not rotations or do not share one frame, P1/P2 that are not a rectified
    pair or show the images in a corner of theirs, Q, E or F that do not follow from the rest.

    Hartley's rectification has no metric baseline and homographies for R1/R2: only what it
    shares with the others is checked. An already rectified pair ("identity") is its P1/P2."""
    with np.errstate(all="ignore"):
        _check_plausible(calib, where)


MIN_FOOTPRINT = 0.5  # share of the rectified image's width and height a raw image covers


def _check_lenses(calib: StereoCalibration, where: str) -> None:
    """Each camera's lens model maps the pixels of its own image to rays and back (a
    distortion that folds over inside the image does not), and its rectification shows the
    image over a good part of the rectified one (not squeezed into a corner of it)."""
    from stereo_gui.core.lens import ROUND_TRIP_PX, pixel_grid, round_trip_px, undistort_points

    w, h = calib.width, calib.height
    pts = pixel_grid(w, h)
    sides = (("1", calib.M1, calib.D1, calib.R1, calib.P1), ("2", calib.M2, calib.D2, calib.R2,
                                                             calib.P2))
    for k, M, D, R, P in sides:
        off, (x, y) = round_trip_px(calib.model, M, D, (w, h))
        if off == float("inf"):
            _fail(where, f"distortion D{k} cannot be applied to the image of camera {k}")
        if not off <= ROUND_TRIP_PX:
            _fail(where, f"distortion D{k} does not describe camera {k}'s lens: pixel "
                         f"({x:.0f}, {y:.0f}) comes back {off:.3g} px away "
                         "(a lens model folding over inside the image)")
        try:
            rect = undistort_points(calib.model, pts, M, D, R=R, P=P)
        except cv2.error:
            _fail(where, f"distortion D{k} cannot be applied to the image of camera {k}")
        span = np.ptp(rect, axis=0) if np.all(np.isfinite(rect)) else np.zeros(2)
        if not (span[0] >= MIN_FOOTPRINT * w and span[1] >= MIN_FOOTPRINT * h):
            _fail(where, f"matrices R{k} and P{k} with distortion D{k} show camera {k}'s image "
                         f"in {span[0]:.0f} x {span[1]:.0f} px of the {w}x{h} rectified image: "
                         "they do not belong together")


def _check_plausible(calib: StereoCalibration, where: str) -> None:
    w, h = calib.width, calib.height
    hartley = calib.method == "hartley"
    least = MIN_FOV_FOCAL * (2.0 if calib.model == "fisheye" else 1.0)
    for name in ("M1", "M2"):
        M = getattr(calib, name)
        fx, fy = M[0, 0], M[1, 1]
        if not least * w <= fx <= MAX_FOV_FOCAL * w or not 0.5 <= fy / fx <= 2.0:
            _fail(where, f"matrix {name} has focal lengths {fx:g}, {fy:g} px, which no lens "
                         f"has for an image {w} px wide (a focal length of {least * w:g} to "
                         f"{MAX_FOV_FOCAL * w:g} px, the same within a factor 2 across)")
        if calib.method != "identity" and not (0 <= M[0, 2] <= w and 0 <= M[1, 2] <= h):
            _fail(where, f"matrix {name} puts the principal point at ({M[0, 2]:g}, {M[1, 2]:g}) "
                         f"px, outside the {w}x{h} image")
    f1, f2 = calib.M1[0, 0], calib.M2[0, 0]
    if max(f1, f2) > MAX_FOCAL_RATIO * min(f1, f2):
        _fail(where, f"matrices M1 and M2 have focal lengths {f1:g} and {f2:g} px: more than "
                     f"{MAX_FOCAL_RATIO:g} times apart, they are not the two cameras of one rig")
    P1, P2 = np.asarray(calib.P1, np.float64), np.asarray(calib.P2, np.float64)
    for name, P in (("P1", P1), ("P2", P2)):
        if not _near(P[2], (0.0, 0.0, 1.0, 0.0), 1e-6) or abs(P[0, 1]) > 1e-6 * P[0, 0] \
                or P[1, 0] != 0:
            _fail(where, f"matrix {name} is not a rectified camera's projection (its last row "
                         "must be 0 0 1 0, without skew)")
    if np.any(P1[:, 3] != 0):
        _fail(where, "matrix P1 has a translation term: the left rectified camera is the origin")
    if not (_near(P1[0, 0], P2[0, 0]) and _near(P1[1, 1], P2[1, 1])):
        _fail(where, f"matrices P1 and P2 have different focal lengths ({P1[0, 0]:g}, "
                     f"{P2[0, 0]:g} px): they are not one rectified pair")
    vertical = P2[0, 3] == 0
    if not (_near(P1[0, 2], P2[0, 2]) if vertical else _near(P1[1, 2], P2[1, 2])):
        _fail(where, "matrices P1 and P2 put their principal points on different "
                     f"{'columns' if vertical else 'rows'}: rows of the two images would not "
                     "match")
    if vertical and P2[1, 3] == 0 or not vertical and P2[1, 3] != 0:
        _fail(where, "matrix P2 has a baseline term along both image axes")
    rect_f = P1[0, 0]
    cams = min(f1, f2), max(f1, f2)
    if not cams[0] / MAX_FOCAL_RATIO <= rect_f <= cams[1] * MAX_FOCAL_RATIO:
        _fail(where, f"the rectified focal length (P1, P2) is {rect_f:g} px but the cameras' "
                     f"(M1, M2) are {f1:g} and {f2:g} px: they do not belong together")
    if not (-w <= P1[0, 2] <= 2 * w and -h <= P1[1, 2] <= 2 * h):
        _fail(where, f"matrix P1 puts the rectified principal point at ({P1[0, 2]:g}, "
                     f"{P1[1, 2]:g}) px, far outside the {w}x{h} image")
    if not _near(calib.Q, _q_of(P1, P2, vertical), 1e-6):
        _fail(where, "matrix Q does not follow from P1 and P2: it would turn disparities into "
                     "distances of another rig")
    R, T = np.asarray(calib.R, np.float64), np.asarray(calib.T, np.float64).reshape(3)
    E, F = np.asarray(calib.E, np.float64), np.asarray(calib.F, np.float64)
    tx = np.array([[0, -T[2], T[1]], [T[2], 0, -T[0]], [-T[1], T[0], 0]])
    if not hartley and not _same_up_to_scale(E, tx @ R):
        _fail(where, "matrix E does not follow from R and T")
    F_of_E = np.linalg.inv(calib.M2).T @ E @ np.linalg.inv(calib.M1)
    if not _same_up_to_scale(F, F_of_E):
        _fail(where, "matrix F does not follow from E, M1 and M2")
    _check_lenses(calib, where)
    if hartley:
        return
    baseline = float(np.linalg.norm(T))
    if not MIN_BASELINE_MM <= baseline <= PLAUSIBLE_BASELINE_MM:
        _fail(where, f"T gives a baseline of {baseline:g} mm (a rig's cameras are "
                     f"{MIN_BASELINE_MM:g} mm to {PLAUSIBLE_BASELINE_MM / 1000:g} m apart)")
    R1, R2 = np.asarray(calib.R1, np.float64), np.asarray(calib.R2, np.float64)
    for name, m in (("R1", R1), ("R2", R2)):
        if not _is_rotation(m):
            _fail(where, f"matrix {name} is not a rotation")
    if not np.allclose(R1, R2 @ R, atol=ROTATION_TOL):
        _fail(where, "matrices R1, R2 and R disagree: the rectified cameras would not look the "
                     "same way")
    t_rect = R2 @ T  # the baseline in the rectified frame: along the rows (or columns) alone
    axis = 1 if vertical else 0
    across = np.delete(t_rect, axis)
    if np.max(np.abs(across)) > RELATIVE_TOL * baseline * 10:
        _fail(where, "matrix R2 does not turn the baseline T along the image rows: rows of the "
                     "rectified images would not match")
    b_p2 = P2[axis, 3] / P2[axis, axis]
    if not _near(b_p2, t_rect[axis], 10 * RELATIVE_TOL):
        _fail(where, f"matrix P2 holds a baseline of {abs(b_p2):g} mm but T one of "
                     f"{baseline:g} mm: distances would be off by a factor "
                     f"{abs(b_p2) / baseline:.3g}")


def _as_float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def _scaled_from(fs, where: str) -> tuple[int, int] | None:
    present = [not fs.getNode(n).empty() for n in ("scaled_from_width", "scaled_from_height")]
    if not any(present):
        return None
    if not all(present):
        _fail(where, "scaled_from_width and scaled_from_height must be given together")
    return (_int(fs, "scaled_from_width", where), _int(fs, "scaled_from_height", where))


def _per_pair(fs, where: str) -> list[PairError]:
    per_pair = []
    pp = fs.getNode("per_pair")
    if pp.empty() or pp.isNone():
        return per_pair
    if not pp.isSeq():
        _fail(where, "per_pair should be a sequence")
    for i in range(pp.size()):
        item = pp.at(i)
        if not item.isMap():
            _fail(where, f"per_pair entry {i + 1} is incomplete")
        name = item.getNode("name")
        el, er = item.getNode("error_left"), item.getNode("error_right")
        if el.empty() or er.empty():
            _fail(where, f"per_pair entry {i + 1} is incomplete")
        if not all(n.isReal() or n.isInt() for n in (el, er)):
            _fail(where, f"per_pair entry {i + 1}: error_left and error_right should be numbers")
        if name.isString():
            nm = name.string()
        elif name.isInt() or name.isReal():
            nm = f"{name.real():g}"
        else:
            nm = str(i + 1)
        per_pair.append(PairError(nm, float(el.real()), float(er.real())))
    return per_pair


def load_calibration(path: str | Path) -> StereoCalibration:
    """Read a calibration written by save_calibration; raise CalibrationFileError saying exactly
    what is wrong (missing file, not FileStorage, unsupported version, bad or missing matrix, a
    value no camera has: see check_calibration)."""
    path = Path(path)
    where = str(path)
    fs = _open(path)
    try:
        calib = _read_calibration(fs, where)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser gave up on a damaged node
        raise CalibrationFileError(f"{where} is damaged ({_parse_error(exc)})") from None
    except UnicodeDecodeError:
        raise CalibrationFileError(f"{where}: a text value is not UTF-8") from None
    finally:
        fs.release()
    check_calibration(calib, where)
    return calib


def _read_calibration(fs, where: str) -> StereoCalibration:
    vnode = fs.getNode("format_version")
    if vnode.empty() or vnode.isNone():
        raise CalibrationFileError(f"{where}: not a stereo-gui calibration file (format_version "
                                   "is missing)")
    if not vnode.isInt() or int(vnode.real()) != FORMAT_VERSION:
        shown = vnode.string() if vnode.isString() else f"{vnode.real():g}"
        raise CalibrationFileError(f"{where}: unsupported format_version {shown} (this version "
                                   f"reads {FORMAT_VERSION})")
    w = _int(fs, "image_width", where)
    h = _int(fs, "image_height", where)
    _check_size(w, h, where)
    mats = {name: _mat(fs, name, where) for name in MATRIX_NAMES}
    check_matrices(mats, where)
    opt = {}
    for name in ("optimal_M1", "optimal_M2"):
        m = _mat(fs, name, where)
        if m is not None:
            if m.shape != (3, 3) or not np.all(np.isfinite(m)):
                raise CalibrationFileError(f"{where}: matrix {name} should be a finite 3x3")
        opt[name] = m
    board = None
    if not fs.getNode("board_cols").empty():
        try:
            board = BoardSpec(_int(fs, "board_cols", where), _int(fs, "board_rows", where),
                              _real(fs, "square_mm", where),
                              _string(fs, "board_target", "chessboard"),
                              _real(fs, "marker_mm", where, 0.0),
                              _string(fs, "board_dictionary", "DICT_4X4_50"))
        except InputError as exc:
            raise CalibrationFileError(f"{where}: {exc}") from None
    per_pair = _per_pair(fs, where)
    method = _string(fs, "method", "bouguet")
    if method not in ("bouguet", "hartley", "identity"):
        raise CalibrationFileError(f"{where}: unknown method {method!r}")
    extra = _read_lens_and_uncertainty(fs, where, mats)
    nan = float("nan")
    return StereoCalibration(
        image_size=(w, h),
        M1=mats["M1"], D1=mats["D1"].reshape(1, -1), M2=mats["M2"], D2=mats["D2"].reshape(1, -1),
        R=mats["R"], T=mats["T"], E=mats["E"], F=mats["F"], R1=mats["R1"], R2=mats["R2"],
        P1=mats["P1"], P2=mats["P2"], Q=mats["Q"], board=board,
        rms_left=_real(fs, "rms_left", where, nan), rms_right=_real(fs, "rms_right", where, nan),
        rms_stereo=_real(fs, "rms_stereo", where, nan),
        epipolar_error_px=_real(fs, "epipolar_error_px", where, nan),
        per_pair=tuple(per_pair), method=method, alpha=_real(fs, "alpha", where, 0.0),
        optimal_M1=opt["optimal_M1"], optimal_M2=opt["optimal_M2"],
        created=_string(fs, "created", ""), scaled_from=_scaled_from(fs, where),
        camera_controls=_read_camera_controls(fs, where),
        lens_shading=_read_lens_shading(fs, where), **extra)


# ---- lens shading ---------------------------------------------------------------------------
def _write_lens_shading(fs, calib: StereoCalibration) -> None:
    shading = calib.lens_shading
    if shading is None:
        return
    fs.startWriteStruct("lens_shading", cv2.FileNode_MAP)
    for side in ("left", "right"):
        lens = getattr(shading, side)
        fs.startWriteStruct(side, cv2.FileNode_MAP)
        fs.write("k1", float(lens.k1))
        fs.write("k2", float(lens.k2))
        fs.write("black", float(lens.black))
        fs.endWriteStruct()
    fs.write("samples", int(shading.samples))
    fs.write("images", int(shading.images))
    fs.endWriteStruct()


def _read_lens_shading(fs, where: str):
    """The `lens_shading` node as a core.shading.PairShading, or None (missing; or damaged: then
    said in the log, and the images are matched as they come)."""
    from stereo_gui.core.shading import MAX_BLACK, MAX_LOSS, MIN_BLACK, LensShading, PairShading

    node = fs.getNode("lens_shading")
    if node.empty() or node.isNone():
        return None
    try:
        if not node.isMap():
            raise ValueError("lens_shading should be a map with left and right")
        lenses = []
        for side in ("left", "right"):
            n = node.getNode(side)
            if n.empty() or not n.isMap():
                raise ValueError(f"lens_shading has no {side} map")
            k = []
            for name in ("k1", "k2", "black"):
                v = n.getNode(name)
                if name == "black" and (v.empty() or v.isNone()):
                    k.append(0.0)
                    continue
                if v.empty() or not (v.isReal() or v.isInt()) or not math.isfinite(v.real()):
                    raise ValueError(f"lens_shading {side} {name} should be a finite number")
                k.append(float(v.real()))
            if not MIN_BLACK <= k[2] <= MAX_BLACK:
                raise ValueError(f"lens_shading {side} black should be from {MIN_BLACK:g} to "
                                 f"{MAX_BLACK:g} grey levels")
            lens = LensShading(*k)
            corner = lens.brightness(np.linspace(0.0, 1.0, 21))
            if corner.min() <= 1.0 - MAX_LOSS or corner.max() >= 1.0 + MAX_LOSS:
                raise ValueError(f"lens_shading {side} darkens or brightens the image by more "
                                 f"than {100 * MAX_LOSS:.0f} %")
            lenses.append(lens)
        counts = [int(node.getNode(n).real()) if node.getNode(n).isInt() else 0
                  for n in ("samples", "images")]
        return PairShading(lenses[0], lenses[1], *counts)
    except ValueError as exc:
        log.warning("%s: %s; the lens shading of this calibration is not used", where, exc)
        return None


# ---- the cameras' controls ------------------------------------------------------------------
def _write_camera_controls(fs, calib: StereoCalibration) -> None:
    c = _controls_of(calib)
    if c is None:
        return
    fs.startWriteStruct("camera_controls", cv2.FileNode_MAP)
    for side in ("left", "right"):
        s = c.side(side)
        fs.startWriteStruct(side, cv2.FileNode_MAP)
        if s.backend:
            fs.write("backend", s.backend)
        for name, v in s.known.items():
            fs.write(name, int(v) if isinstance(v, bool) else float(v))
        fs.endWriteStruct()
    fs.endWriteStruct()


def _read_camera_controls(fs, where: str) -> PairSettings | None:
    """The `camera_controls` node, or None (missing, or damaged: then said in the log)."""
    node = fs.getNode("camera_controls")
    if node.empty() or node.isNone():
        return None
    try:
        if not node.isMap():
            raise ValueError("camera_controls should be a map with left and right")
        sides = {}
        for side in ("left", "right"):
            n = node.getNode(side)
            data: dict = {}
            if not n.empty() and not n.isNone():
                if not n.isMap():
                    raise ValueError(f"camera_controls {side} should be a map")
                for key in n.keys():
                    v = n.getNode(key)
                    if v.isString():
                        data[key] = v.string()
                    elif key in SWITCHES and v.isInt():
                        data[key] = int(v.real()) != 0
                    elif v.isInt() or v.isReal():
                        data[key] = float(v.real())
                    else:
                        raise ValueError(f"camera_controls {side} {key} should be a number")
            sides[side] = data
        return PairSettings.from_json(sides, "camera_controls")
    except ValueError as exc:
        log.warning("%s: %s; the cameras' controls of this calibration are not known", where, exc)
        return None


# ---- lens model, uncertainty, origin and warnings ------------------------------------------
def _write_lens_and_uncertainty(fs, calib: StereoCalibration) -> None:
    """The lens model, where the calibration came from, its warnings and its 1-sigma covariance
    (names in order, then the matrix)."""
    fs.write("lens_model", calib.model)
    if calib.swapped_inputs:
        fs.write("swapped_inputs", 1)
    if calib.origin:
        fs.write("origin", calib.origin)
    if calib.warnings:
        fs.startWriteStruct("warnings", cv2.FileNode_SEQ)
        for w in calib.warnings:
            fs.startWriteStruct("", cv2.FileNode_MAP)
            fs.write("code", w.code)
            fs.write("message", w.message)
            fs.write("proposal", w.proposal)
            fs.endWriteStruct()
        fs.endWriteStruct()
    if calib.left_out:
        fs.startWriteStruct("pairs_left_out", cv2.FileNode_SEQ)
        for name, why in calib.left_out:
            fs.startWriteStruct("", cv2.FileNode_MAP)
            fs.write("name", name)
            fs.write("why", why)
            fs.endWriteStruct()
        fs.endWriteStruct()
    u = calib.uncertainty
    if u is not None:
        fs.write("uncertainty_level", "1 sigma")
        fs.write("uncertainty_method", u.method)
        fs.write("uncertainty_corner_px", float(u.sigma_px))
        fs.startWriteStruct("uncertainty_names", cv2.FileNode_SEQ)
        for n in u.names:
            fs.write("", n)
        fs.endWriteStruct()
        fs.write("uncertainty_covariance", np.asarray(u.covariance, np.float64))


def _read_lens_and_uncertainty(fs, where: str, mats: dict) -> dict:
    from stereo_gui.core.lens import DIST_COUNT, LENS_MODELS
    from stereo_gui.core.uncertainty import CalibrationUncertainty, CalibrationWarning

    model = _string(fs, "lens_model", "")
    d = mats["D1"].size
    if not model:  # files before lens models: the coefficient count says which pinhole model
        model = "rational" if d > 5 else "pinhole"
    if model not in LENS_MODELS:
        raise CalibrationFileError(f"{where}: unknown lens_model {model!r} (use one of "
                                   f"{', '.join(LENS_MODELS)})")
    if model == "fisheye" and (d != 4 or mats["D2"].size != 4):
        raise CalibrationFileError(f"{where}: a fisheye calibration needs 4 distortion "
                                   f"coefficients per camera, found {d} and {mats['D2'].size}")
    if model != "fisheye" and d < DIST_COUNT["pinhole"] - 1:
        raise CalibrationFileError(f"{where}: distortion D1 has too few coefficients ({d})")
    if mats["D2"].size != d:
        raise CalibrationFileError(f"{where}: distortion D1 has {d} coefficients and D2 "
                                   f"{mats['D2'].size}: both cameras of a calibration have the "
                                   "same lens model")
    out: dict = {"model": model, "origin": _string(fs, "origin", ""),
                 "swapped_inputs": _real(fs, "swapped_inputs", where, 0.0) != 0.0}
    warnings = []
    wn = fs.getNode("warnings")
    if not wn.empty() and wn.isSeq():
        for i in range(wn.size()):
            item = wn.at(i)
            code, msg = item.getNode("code"), item.getNode("message")
            if item.isMap() and code.isString() and msg.isString():
                prop = item.getNode("proposal")
                warnings.append(CalibrationWarning(code.string(), msg.string(),
                                                   prop.string() if prop.isString() else ""))
    out["warnings"] = tuple(warnings)
    left_out = []
    ln = fs.getNode("pairs_left_out")
    if not ln.empty() and ln.isSeq():  # (what cannot be read there is left out: a note only)
        for i in range(ln.size()):
            item = ln.at(i)
            name, why = item.getNode("name"), item.getNode("why")
            if item.isMap() and name.isString() and why.isString():
                left_out.append((name.string(), why.string()))
    out["left_out"] = tuple(left_out)
    nn = fs.getNode("uncertainty_names")
    if not nn.empty() and not nn.isNone():
        if not nn.isSeq():
            raise CalibrationFileError(f"{where}: uncertainty_names should be a sequence")
        names = tuple(nn.at(i).string() for i in range(nn.size()))
        cov = _mat(fs, "uncertainty_covariance", where, max_side=MAX_UNCERTAINTY_PARAMETERS)
        if cov is None or cov.shape != (len(names), len(names)) or not np.all(np.isfinite(cov)):
            raise CalibrationFileError(f"{where}: uncertainty_covariance should be a finite "
                                       f"{len(names)}x{len(names)} matrix")
        _check_uncertainty_names(names, model, d, where)
        out["uncertainty"] = CalibrationUncertainty(
            names, cov, _real(fs, "uncertainty_corner_px", where, float("nan")),
            _string(fs, "uncertainty_method", "jacobian"), model)
    return out


def _check_uncertainty_names(names: tuple[str, ...], model: str, n_dist: int, where: str) -> None:
    """Every name of the covariance is a parameter of this calibration, once (a distance's
    uncertainty is computed by moving each)."""
    from stereo_gui.core.uncertainty import parameter_names

    known = parameter_names(model, n_dist)
    for name in names:
        if name not in known:
            raise CalibrationFileError(
                f"{where}: uncertainty_names holds {name!r}, which is not a parameter of this "
                f"calibration ({model} lenses, {n_dist} distortion coefficients: "
                f"{', '.join(known[:2])}, ..., {known[-1]}); remove uncertainty_names and "
                "uncertainty_covariance to use the file without its uncertainty")
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise CalibrationFileError(f"{where}: uncertainty_names holds {', '.join(twice)} twice")


def load_calibration_for_size(path: str | Path, image_size: tuple[int, int]) -> StereoCalibration:
    """Load a calibration and scale it to `image_size` (same aspect ratio only; else
    CalibrationError explains why it cannot be used)."""
    return load_calibration(path).scaled_to(image_size)


# ---- ROS camera_info ---------------------------------------------------------------------------
def _num(x: float) -> str:
    """A float as YAML text that reads back to the same double."""
    x = float(x)
    if math.isfinite(x):
        return repr(x)
    raise CalibrationFileError(f"cannot export a non-finite value ({x}) to ROS camera_info")


def _ros_matrix(name: str, m: np.ndarray) -> str:
    m = np.atleast_2d(np.asarray(m, np.float64))
    rows, cols = m.shape
    data = ", ".join(_num(v) for v in m.reshape(-1))
    return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"


def ros_camera_info_text(calib: StereoCalibration, side: str, camera_name: str | None = None) -> str:
    """The ROS camera_info YAML of one camera ('left' or 'right'); the projection matrix's
    translation term is in metres, as ROS expects."""
    if side not in ("left", "right"):
        raise ValueError(side)
    M, D, R, P = ((calib.M1, calib.D1, calib.R1, calib.P1) if side == "left"
                  else (calib.M2, calib.D2, calib.R2, calib.P2))
    D = np.asarray(D, np.float64).reshape(-1)
    model = ROS_DISTORTION_MODELS[calib.model]
    if calib.model != "fisheye" and D.size < 5:
        D = np.concatenate([D, np.zeros(5 - D.size)])
    P = np.array(P, np.float64)
    P[:, 3] /= 1000.0  # mm -> m
    name = camera_name or side
    return (f"image_width: {calib.width}\nimage_height: {calib.height}\ncamera_name: {name}\n"
            + _ros_matrix("camera_matrix", M)
            + f"distortion_model: {model}\n"
            + _ros_matrix("distortion_coefficients", D.reshape(1, -1))
            + _ros_matrix("rectification_matrix", R)
            + _ros_matrix("projection_matrix", P))


def export_ros(calib: StereoCalibration, folder: str | Path, prefix: str = "") -> tuple[Path, Path]:
    """Write `left.yaml` and `right.yaml` (ROS camera_info) into `folder`; return both paths."""
    if not calib.metric:
        log.warning("exporting a Hartley calibration to ROS: its baseline is not metric")
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"cannot write ROS files: folder {folder} does not exist")
    # both written and read back before either replaces an old file
    out = write_many_atomic([(folder / f"{prefix}{side}.yaml",
                              ros_camera_info_text(calib, side).encode("utf-8"), _ros_read)
                             for side in ("left", "right")])
    return out[0], out[1]


def _ros_read(path: Path) -> dict:
    where = str(path)
    if not path.exists():
        raise CalibrationFileError(f"ROS camera_info file {path} does not exist")
    _check_parsable(path, f"ROS camera_info file {path}")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_FORMAT_YAML)
    except (cv2.error, SystemError):
        raise CalibrationFileError(f"{path} is not a readable YAML file") from None
    try:
        if not fs.isOpened():
            raise CalibrationFileError(f"{path} is not a readable YAML file")
        out: dict = {}
        for key in ("image_width", "image_height"):
            n = fs.getNode(key)
            if n.empty() or not n.isInt():
                raise CalibrationFileError(f"{where}: {key} is missing or not a whole number")
            out[key] = int(n.real())
        _check_size(out["image_width"], out["image_height"], where)
        out["distortion_model"] = _string(fs, "distortion_model", "plumb_bob")
        if out["distortion_model"] not in ROS_DISTORTION_MODELS.values():
            raise CalibrationFileError(f"{where}: distortion model {out['distortion_model']!r} is "
                                       "not supported (plumb_bob, rational_polynomial or "
                                       "equidistant)")
        shapes = {"camera_matrix": (3, 3), "distortion_coefficients": None,
                  "rectification_matrix": (3, 3), "projection_matrix": (3, 4)}
        for key, shape in shapes.items():
            n = fs.getNode(key)
            if n.empty() or not n.isMap():
                raise CalibrationFileError(f"{where}: {key} is missing")
            rows, cols, data = n.getNode("rows"), n.getNode("cols"), n.getNode("data")
            if rows.empty() or cols.empty() or data.empty() or not data.isSeq():
                raise CalibrationFileError(f"{where}: {key} needs rows, cols and data")
            if not (rows.isInt() and cols.isInt() and 1 <= rows.real() <= 4
                    and 1 <= cols.real() <= 14):
                raise CalibrationFileError(f"{where}: {key} rows and cols should be whole "
                                           "numbers from 1 to 14")
            r, c = int(rows.real()), int(cols.real())
            if data.size() > 64 or not all(data.at(i).isReal() or data.at(i).isInt()
                                           for i in range(data.size())):
                raise CalibrationFileError(f"{where}: {key} data should be numbers")
            vals = np.array([data.at(i).real() for i in range(data.size())], np.float64)
            if vals.size != r * c:
                raise CalibrationFileError(f"{where}: {key} has {vals.size} values, rows x cols "
                                           f"is {r}x{c}")
            m = vals.reshape(r, c)
            if shape is not None and m.shape != shape:
                raise CalibrationFileError(f"{where}: {key} should be {shape[0]}x{shape[1]}, "
                                           f"found {r}x{c}")
            if not np.all(np.isfinite(m)):
                raise CalibrationFileError(f"{where}: {key} holds values that are not finite")
            out[key] = m
        return out
    except UnicodeDecodeError:
        raise CalibrationFileError(f"{where}: a text value is not UTF-8") from None
    except (cv2.error, SystemError) as exc:
        raise CalibrationFileError(f"{where} is damaged ({_parse_error(exc)})") from None
    finally:
        fs.release()


def import_ros(left_path: str | Path, right_path: str | Path) -> StereoCalibration:
    """Rebuild a StereoCalibration from a pair of ROS camera_info files.

    R and T come from the rectification and projection matrices: both rectified cameras share
    orientation, so R_right_left = R2^T R1 and T_right_left = R2^T t, where t = (P2[0,3]/fx,
    P2[1,3]/fy, 0) in metres (converted to mm).
    """
    lp, rp = Path(left_path), Path(right_path)
    left, right = _ros_read(lp), _ros_read(rp)
    size = (left["image_width"], left["image_height"])
    if size != (right["image_width"], right["image_height"]):
        raise CalibrationFileError(f"{lp} is {size[0]}x{size[1]} but {rp} is "
                                   f"{right['image_width']}x{right['image_height']}")
    M1, M2 = left["camera_matrix"], right["camera_matrix"]
    for path, M, name in ((lp, M1, "camera_matrix"), (rp, M2, "camera_matrix")):
        _check_camera(M, name, str(path))
    for path, P in ((lp, left["projection_matrix"]), (rp, right["projection_matrix"])):
        if not (0 < P[0, 0] <= MAX_FOCAL_PX and 0 < P[1, 1] <= MAX_FOCAL_PX):
            raise CalibrationFileError(f"{path}: projection_matrix has focal lengths "
                                       f"{P[0, 0]:g}, {P[1, 1]:g} px (they must be positive)")
    D1 = left["distortion_coefficients"].reshape(1, -1)
    D2 = right["distortion_coefficients"].reshape(1, -1)
    R1, R2 = left["rectification_matrix"], right["rectification_matrix"]
    P1 = left["projection_matrix"].copy()
    P2 = right["projection_matrix"].copy()
    P1[:, 3] *= 1000.0  # m -> mm
    P2[:, 3] *= 1000.0
    t_rect = np.array([[P2[0, 3] / P2[0, 0]], [P2[1, 3] / P2[1, 1]], [0.0]])
    if not np.any(t_rect):
        raise CalibrationFileError(f"{rp}: projection_matrix has no baseline term (P[0,3] and "
                                   "P[1,3] are zero), so it is not the right camera of a stereo pair")
    R = R2.T @ R1
    T = R2.T @ t_rect
    tx = np.array([[0, -T[2, 0], T[1, 0]], [T[2, 0], 0, -T[0, 0]], [-T[1, 0], T[0, 0], 0]])
    E = tx @ R
    F = np.linalg.inv(M2).T @ E @ np.linalg.inv(M1)
    F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
    Q = q_from_projections(P1, P2)
    models = {v: k for k, v in ROS_DISTORTION_MODELS.items()}
    if left["distortion_model"] != right["distortion_model"]:
        raise CalibrationFileError(f"{lp} and {rp} have different distortion models "
                                   f"({left['distortion_model']}, {right['distortion_model']})")
    model = models[left["distortion_model"]]
    if model == "fisheye" and (D1.size != 4 or D2.size != 4):
        raise CalibrationFileError(f"{lp} + {rp}: equidistant distortion needs 4 coefficients")
    if model != "fisheye":
        model = "rational" if D1.size > 5 else "pinhole"
    calib = StereoCalibration(image_size=size, M1=M1, D1=D1, M2=M2, D2=D2, R=R, T=T, E=E, F=F,
                              R1=R1, R2=R2, P1=P1, P2=P2, Q=Q, method="bouguet", model=model,
                              created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    check_calibration(calib, f"{lp} + {rp}")
    return calib


def q_from_projections(P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    """The disparity-to-depth matrix of a horizontal rectified pair, as cv2.stereoRectify builds
    it (T in the units of P2's translation term)."""
    f, cx, cy = P1[0, 0], P1[0, 2], P1[1, 2]
    tx = P2[0, 3] / P2[0, 0]
    cx2 = P2[0, 2]
    return np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f],
                     [0, 0, -1.0 / tx, (cx - cx2) / tx]], np.float64)
