"""Calibration files: OpenCV FileStorage YAML (our format).

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

The file's checks before and while it is parsed are in `calibration_file_checks`, its optional
parts (lens model, uncertainty, warnings, lens shading, cameras' controls) in
`calibration_file_parts`. ROS camera_info files (export and import) are `ros_camera_info`'s,
imported from here too.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import CalibrationFileError, InputError
from stereo_gui.core.plausibility import check_plausible
from stereo_gui.core.shading import PairShading
from stereo_gui.core.stereo_calibration import (
    MATRIX_NAMES,
    METHODS,
    PairError,
    StereoCalibration,
    check_image_size,
    check_matrices,
    from_file,
)
from stereo_gui.files.atomic import write_text_atomic
from stereo_gui.files.calibration_file_checks import (
    fail,
    open_filestorage,
    parse_error,
    read_int,
    read_mat,
    read_real,
    read_string,
)
from stereo_gui.files.calibration_file_parts import (
    controls_of,
    read_camera_controls,
    read_left_out,
    read_lens_model,
    read_lens_shading,
    read_uncertainty,
    read_warnings,
    write_camera_controls,
    write_lens_and_uncertainty,
    write_lens_shading,
)
from stereo_gui.files.ros_camera_info import (
    ROS_DISTORTION_MODELS,
    export_ros,
    import_ros,
    ros_camera_info_text,
)

__all__ = ["FORMAT_VERSION", "ROS_DISTORTION_MODELS", "calibration_text", "export_ros",
           "import_ros", "load_calibration", "load_calibration_for_size", "ros_camera_info_text",
           "save_calibration"]

log = logging.getLogger(__name__)

FORMAT_VERSION = 1


# ---- writing ----------------------------------------------------------------------------------
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
    write_lens_and_uncertainty(fs, calib)
    write_camera_controls(fs, calib)
    write_lens_shading(fs, calib)
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
            and a.board == b.board and controls_of(a) == controls_of(b)
            and _same_shading(a.lens_shading, b.lens_shading))


def _same_shading(a: PairShading | None, b: PairShading | None) -> bool:
    if a is None or b is None:
        return a is b
    return all(math.isclose(x, y, rel_tol=1e-9, abs_tol=1e-12)
               for la, lb in ((a.left, b.left), (a.right, b.right))
               for x, y in zip(la.coefficients, lb.coefficients))


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


# ---- reading ----------------------------------------------------------------------------------
def load_calibration(path: str | Path) -> StereoCalibration:
    """Read a calibration written by save_calibration; raise CalibrationFileError saying exactly
    what is wrong (missing file, not FileStorage, unsupported version, bad or missing matrix, a
    value no camera has: see StereoCalibration and core.plausibility)."""
    path = Path(path)
    where = str(path)
    fs = open_filestorage(path)
    try:
        calib = _read_calibration(fs, where)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser gave up on a damaged node
        raise CalibrationFileError(f"{where} is damaged ({parse_error(exc)})") from None
    except UnicodeDecodeError:
        raise CalibrationFileError(f"{where}: a text value is not UTF-8") from None
    finally:
        fs.release()
    check_plausible(calib, where)
    return calib


def _read_calibration(fs: cv2.FileStorage, where: str) -> StereoCalibration:
    vnode = fs.getNode("format_version")
    if vnode.empty() or vnode.isNone():
        raise CalibrationFileError(f"{where}: not a stereo-gui calibration file (format_version "
                                   "is missing)")
    if not vnode.isInt() or int(vnode.real()) != FORMAT_VERSION:
        shown = vnode.string() if vnode.isString() else f"{vnode.real():g}"
        raise CalibrationFileError(f"{where}: unsupported format_version {shown} (this version "
                                   f"reads {FORMAT_VERSION})")
    w = read_int(fs, "image_width", where)
    h = read_int(fs, "image_height", where)
    found = {name: read_mat(fs, name, where) for name in MATRIX_NAMES}
    with from_file(where):
        check_image_size(w, h)
        check_matrices(found)  # (before the distortion's length says which lens model)
    mats = {name: m for name, m in found.items() if m is not None}  # all: checked just above
    board = None
    if not fs.getNode("board_cols").empty():
        try:
            board = BoardSpec(read_int(fs, "board_cols", where),
                              read_int(fs, "board_rows", where),
                              read_real(fs, "square_mm", where),
                              read_string(fs, "board_target", "chessboard"),
                              read_real(fs, "marker_mm", where, 0.0),
                              read_string(fs, "board_dictionary", "DICT_4X4_50"))
        except InputError as exc:
            raise CalibrationFileError(f"{where}: {exc}") from None
    per_pair = _per_pair(fs, where)
    method = read_string(fs, "method", "bouguet")
    if method not in METHODS:
        raise CalibrationFileError(f"{where}: unknown method {method!r}")
    model = read_lens_model(fs, where, mats["D1"].size)
    nan = float("nan")
    with from_file(where):
        return StereoCalibration(
            image_size=(w, h),
            M1=mats["M1"], D1=mats["D1"].reshape(1, -1), M2=mats["M2"],
            D2=mats["D2"].reshape(1, -1), R=mats["R"], T=mats["T"], E=mats["E"], F=mats["F"],
            R1=mats["R1"], R2=mats["R2"], P1=mats["P1"], P2=mats["P2"], Q=mats["Q"], board=board,
            rms_left=read_real(fs, "rms_left", where, nan),
            rms_right=read_real(fs, "rms_right", where, nan),
            rms_stereo=read_real(fs, "rms_stereo", where, nan),
            epipolar_error_px=read_real(fs, "epipolar_error_px", where, nan),
            per_pair=tuple(per_pair), method=method,
            alpha=read_real(fs, "alpha", where, 0.0),
            optimal_M1=read_mat(fs, "optimal_M1", where),
            optimal_M2=read_mat(fs, "optimal_M2", where),
            created=read_string(fs, "created", ""), scaled_from=_scaled_from(fs, where),
            model=model, uncertainty=read_uncertainty(fs, where, model, mats["D1"].size),
            origin=read_string(fs, "origin", ""),
            swapped_inputs=read_real(fs, "swapped_inputs", where, 0.0) != 0.0,
            warnings=read_warnings(fs), left_out=read_left_out(fs),
            camera_controls=read_camera_controls(fs, where),
            lens_shading=read_lens_shading(fs, where))


def _scaled_from(fs: cv2.FileStorage, where: str) -> tuple[int, int] | None:
    present = [not fs.getNode(n).empty() for n in ("scaled_from_width", "scaled_from_height")]
    if not any(present):
        return None
    if not all(present):
        fail(where, "scaled_from_width and scaled_from_height must be given together")
    return (read_int(fs, "scaled_from_width", where), read_int(fs, "scaled_from_height", where))


def _per_pair(fs: cv2.FileStorage, where: str) -> list[PairError]:
    per_pair: list[PairError] = []
    pp = fs.getNode("per_pair")
    if pp.empty() or pp.isNone():
        return per_pair
    if not pp.isSeq():
        fail(where, "per_pair should be a sequence")
    for i in range(pp.size()):
        item = pp.at(i)
        if not item.isMap():
            fail(where, f"per_pair entry {i + 1} is incomplete")
        name = item.getNode("name")
        el, er = item.getNode("error_left"), item.getNode("error_right")
        if el.empty() or er.empty():
            fail(where, f"per_pair entry {i + 1} is incomplete")
        if not all(n.isReal() or n.isInt() for n in (el, er)):
            fail(where, f"per_pair entry {i + 1}: error_left and error_right should be numbers")
        if name.isString():
            nm = name.string()
        elif name.isInt() or name.isReal():
            nm = f"{name.real():g}"
        else:
            nm = str(i + 1)
        with from_file(f"{where}: per_pair entry {i + 1}"):
            per_pair.append(PairError(nm, float(el.real()), float(er.real())))
    return per_pair


def load_calibration_for_size(path: str | Path, image_size: tuple[int, int]) -> StereoCalibration:
    """Load a calibration and scale it to `image_size` (same aspect ratio only; else
    CalibrationError explains why it cannot be used)."""
    return load_calibration(path).scaled_to(image_size)
