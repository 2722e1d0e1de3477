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

This module reads and writes; it checks only the format. The values are checked by the types
they become (a StereoCalibration and its parts refuse what no camera has when they are built)
and by core.plausibility (whether the whole is a rig that could exist); their words are said
here with the file's name in front.

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
from typing import NoReturn, cast

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.camera_settings import SWITCHES, PairSettings
from stereo_gui.core.errors import CalibrationFileError, CalibrationValueError, InputError
from stereo_gui.core.lens import LENS_MODELS, LensModel
from stereo_gui.core.plausibility import check_plausible
from stereo_gui.core.shading import LensShading, PairShading
from stereo_gui.core.stereo_calibration import (
    MATRIX_NAMES,
    METHODS,
    Method,
    PairError,
    StereoCalibration,
    check_camera_matrix,
    check_image_size,
    check_matrices,
    check_projection_focal,
    from_file,
    q_from_projections,
)
from stereo_gui.core.uncertainty import CalibrationUncertainty, CalibrationWarning
from stereo_gui.files.atomic import os_error_text, write_many_atomic, write_text_atomic

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
# ROS camera_info's distortion_model of each lens model (core.lens)
ROS_DISTORTION_MODELS = {"pinhole": "plumb_bob", "rational": "rational_polynomial",
                         "fisheye": "equidistant"}


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
    for name, m in calib.matrices().items():
        fs.write(name, m)
    for name, opt in (("optimal_M1", calib.optimal_M1), ("optimal_M2", calib.optimal_M2)):
        if opt is not None:
            fs.write(name, opt)
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
    for ma, mb in zip(a.matrices().values(), b.matrices().values()):
        if not np.array_equal(ma.reshape(-1), mb.reshape(-1)):
            return False
    return (a.image_size == b.image_size and len(a.per_pair) == len(b.per_pair)
            and a.board == b.board and _controls_of(a) == _controls_of(b)
            and _same_shading(a.lens_shading, b.lens_shading))


def _same_shading(a: PairShading | None, b: PairShading | None) -> bool:
    if a is None or b is None:
        return a is b
    return all(math.isclose(x, y, rel_tol=1e-9, abs_tol=1e-12)
               for la, lb in ((a.left, b.left), (a.right, b.right))
               for x, y in zip(la.coefficients, lb.coefficients))


def _controls_of(calib: StereoCalibration) -> PairSettings | None:
    c = calib.camera_controls
    return None if c is None or c.empty else c


def save_calibration(calib: StereoCalibration, path: str | Path) -> Path:
    """Write `calib` to `path` as FileStorage YAML, atomically; return the path.

    cv2.FileStorage does not report a failed write (a full disk leaves a torn file and no error),
    so the document is made in memory, written by files.atomic, and read back with
    `load_calibration` before it replaces `path`.
    """
    path = Path(path)
    check_plausible(calib, f"cannot save {path}")
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


def _fail(where: str, text: str) -> NoReturn:
    raise CalibrationFileError(f"{where}: {text}")


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


MAX_UNCERTAINTY_PARAMETERS = 128  # both cameras' intrinsics and distortion, rotation, translation


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
        with from_file(f"{where}: per_pair entry {i + 1}"):
            per_pair.append(PairError(nm, float(el.real()), float(er.real())))
    return per_pair


def load_calibration(path: str | Path) -> StereoCalibration:
    """Read a calibration written by save_calibration; raise CalibrationFileError saying exactly
    what is wrong (missing file, not FileStorage, unsupported version, bad or missing matrix, a
    value no camera has: see StereoCalibration and core.plausibility)."""
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
    check_plausible(calib, where)
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
    mats = {name: _mat(fs, name, where) for name in MATRIX_NAMES}
    with from_file(where):
        check_image_size(w, h)
        check_matrices(mats)  # (before the distortion's length says which lens model)
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
    if method not in METHODS:
        raise CalibrationFileError(f"{where}: unknown method {method!r}")
    model = _lens_model(fs, where, mats["D1"].size)
    nan = float("nan")
    with from_file(where):
        return StereoCalibration(
            image_size=(w, h),
            M1=mats["M1"], D1=mats["D1"].reshape(1, -1), M2=mats["M2"],
            D2=mats["D2"].reshape(1, -1), R=mats["R"], T=mats["T"], E=mats["E"], F=mats["F"],
            R1=mats["R1"], R2=mats["R2"], P1=mats["P1"], P2=mats["P2"], Q=mats["Q"], board=board,
            rms_left=_real(fs, "rms_left", where, nan),
            rms_right=_real(fs, "rms_right", where, nan),
            rms_stereo=_real(fs, "rms_stereo", where, nan),
            epipolar_error_px=_real(fs, "epipolar_error_px", where, nan),
            per_pair=tuple(per_pair), method=cast(Method, method),
            alpha=_real(fs, "alpha", where, 0.0),
            optimal_M1=_mat(fs, "optimal_M1", where), optimal_M2=_mat(fs, "optimal_M2", where),
            created=_string(fs, "created", ""), scaled_from=_scaled_from(fs, where),
            model=model, uncertainty=_read_uncertainty(fs, where, model, mats["D1"].size),
            origin=_string(fs, "origin", ""),
            swapped_inputs=_real(fs, "swapped_inputs", where, 0.0) != 0.0,
            warnings=_read_warnings(fs), left_out=_read_left_out(fs),
            camera_controls=_read_camera_controls(fs, where),
            lens_shading=_read_lens_shading(fs, where))


# ---- lens shading ---------------------------------------------------------------------------
def _write_lens_shading(fs, calib: StereoCalibration) -> None:
    shading = calib.lens_shading
    if shading is None:
        return
    fs.startWriteStruct("lens_shading", cv2.FileNode_MAP)
    for side, lens in (("left", shading.left), ("right", shading.right)):
        fs.startWriteStruct(side, cv2.FileNode_MAP)
        fs.write("k1", float(lens.k1))
        fs.write("k2", float(lens.k2))
        fs.write("black", float(lens.black))
        fs.endWriteStruct()
    fs.write("samples", int(shading.samples))
    fs.write("images", int(shading.images))
    fs.endWriteStruct()


def _read_lens_shading(fs, where: str) -> PairShading | None:
    """The `lens_shading` node, or None (missing; or damaged: then said in the log, and the
    images are matched as they come)."""
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
                if v.empty() or not (v.isReal() or v.isInt()):
                    raise ValueError(f"lens_shading {side} {name} should be a finite number")
                k.append(float(v.real()))
            try:
                lenses.append(LensShading(*k))
            except CalibrationValueError as exc:
                raise ValueError(f"lens_shading {side} {exc}") from None
        counts = [int(node.getNode(n).real()) if node.getNode(n).isInt() else 0
                  for n in ("samples", "images")]
        try:
            return PairShading(lenses[0], lenses[1], *counts)
        except CalibrationValueError as exc:
            raise ValueError(f"lens_shading {exc}") from None
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


def _lens_model(fs, where: str, n_dist: int) -> LensModel:
    model = _string(fs, "lens_model", "")
    if not model:  # files before lens models: the coefficient count says which pinhole model
        return "rational" if n_dist > 5 else "pinhole"
    if model not in LENS_MODELS:
        raise CalibrationFileError(f"{where}: unknown lens_model {model!r} (use one of "
                                   f"{', '.join(LENS_MODELS)})")
    return cast(LensModel, model)


def _read_warnings(fs) -> tuple[CalibrationWarning, ...]:
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
    return tuple(warnings)


def _read_left_out(fs) -> tuple[tuple[str, str], ...]:
    left_out = []
    ln = fs.getNode("pairs_left_out")
    if not ln.empty() and ln.isSeq():  # (what cannot be read there is left out: a note only)
        for i in range(ln.size()):
            item = ln.at(i)
            name, why = item.getNode("name"), item.getNode("why")
            if item.isMap() and name.isString() and why.isString():
                left_out.append((name.string(), why.string()))
    return tuple(left_out)


def _read_uncertainty(fs, where: str, model: LensModel,
                      n_dist: int) -> CalibrationUncertainty | None:
    nn = fs.getNode("uncertainty_names")
    if nn.empty() or nn.isNone():
        return None
    if not nn.isSeq():
        raise CalibrationFileError(f"{where}: uncertainty_names should be a sequence")
    names = tuple(nn.at(i).string() for i in range(nn.size()))
    cov = _mat(fs, "uncertainty_covariance", where, max_side=MAX_UNCERTAINTY_PARAMETERS)
    if cov is None:
        raise CalibrationFileError(f"{where}: uncertainty_covariance should be a finite "
                                   f"{len(names)}x{len(names)} matrix")
    try:
        u = CalibrationUncertainty(names, cov, _real(fs, "uncertainty_corner_px", where, math.nan),
                                   _string(fs, "uncertainty_method", "jacobian"), model)
        u.check_parameters(n_dist)
    except CalibrationValueError as exc:
        raise CalibrationFileError(f"{where}: {exc}; remove uncertainty_names and "
                                   "uncertainty_covariance to use the file without its "
                                   "uncertainty") from None
    return u


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
        with from_file(where):
            check_image_size(out["image_width"], out["image_height"])
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
    for path, side in ((lp, left), (rp, right)):
        with from_file(str(path)):
            check_camera_matrix(side["camera_matrix"], "camera_matrix")
            check_projection_focal(side["projection_matrix"], "projection_matrix")
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
    where = f"{lp} + {rp}"
    with from_file(where):
        calib = StereoCalibration(
            image_size=size, M1=M1, D1=D1, M2=M2, D2=D2, R=R, T=T, E=E, F=F, R1=R1, R2=R2, P1=P1,
            P2=P2, Q=Q, method="bouguet", model=model,
            created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    check_plausible(calib, where)
    return calib
