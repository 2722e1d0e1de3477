"""The optional parts of our calibration file, each written and read on its own: the lens model,
where the calibration came from, its warnings and the pairs left out, the parameters' 1-sigma
covariance, the lens shading and the cameras' controls. A file without a part loads as before;
a damaged lens shading or camera_controls is left out with a warning in the log."""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np

from stereo_gui.core.camera_settings import SWITCHES, PairSettings
from stereo_gui.core.errors import CalibrationFileError, CalibrationValueError
from stereo_gui.core.lens import LENS_MODELS, LensModel
from stereo_gui.core.shading import LensShading, PairShading
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.uncertainty import CalibrationUncertainty, CalibrationWarning
from stereo_gui.files.calibration_file_checks import read_mat, read_real, read_string

log = logging.getLogger(__name__)

MAX_UNCERTAINTY_PARAMETERS = 128  # both cameras' intrinsics and distortion, rotation, translation


# ---- lens model, uncertainty, origin and warnings ------------------------------------------
def write_lens_and_uncertainty(fs: cv2.FileStorage, calib: StereoCalibration) -> None:
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


def read_lens_model(fs: cv2.FileStorage, where: str, n_dist: int) -> LensModel:
    model = read_string(fs, "lens_model", "")
    if not model:  # files before lens models: the coefficient count says which pinhole model
        return "rational" if n_dist > 5 else "pinhole"
    if model not in LENS_MODELS:
        raise CalibrationFileError(f"{where}: unknown lens_model {model!r} (use one of "
                                   f"{', '.join(LENS_MODELS)})")
    return model


def read_warnings(fs: cv2.FileStorage) -> tuple[CalibrationWarning, ...]:
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


def read_left_out(fs: cv2.FileStorage) -> tuple[tuple[str, str], ...]:
    left_out = []
    ln = fs.getNode("pairs_left_out")
    if not ln.empty() and ln.isSeq():  # (what cannot be read there is left out: a note only)
        for i in range(ln.size()):
            item = ln.at(i)
            name, why = item.getNode("name"), item.getNode("why")
            if item.isMap() and name.isString() and why.isString():
                left_out.append((name.string(), why.string()))
    return tuple(left_out)


def read_uncertainty(fs: cv2.FileStorage, where: str, model: LensModel,
                     n_dist: int) -> CalibrationUncertainty | None:
    nn = fs.getNode("uncertainty_names")
    if nn.empty() or nn.isNone():
        return None
    if not nn.isSeq():
        raise CalibrationFileError(f"{where}: uncertainty_names should be a sequence")
    names = tuple(nn.at(i).string() for i in range(nn.size()))
    cov = read_mat(fs, "uncertainty_covariance", where, max_side=MAX_UNCERTAINTY_PARAMETERS)
    if cov is None:
        raise CalibrationFileError(f"{where}: uncertainty_covariance should be a finite "
                                   f"{len(names)}x{len(names)} matrix")
    try:
        u = CalibrationUncertainty(names, cov,
                                   read_real(fs, "uncertainty_corner_px", where, math.nan),
                                   read_string(fs, "uncertainty_method", "jacobian"), model)
        u.check_parameters(n_dist)
    except CalibrationValueError as exc:
        raise CalibrationFileError(f"{where}: {exc}; remove uncertainty_names and "
                                   "uncertainty_covariance to use the file without its "
                                   "uncertainty") from None
    return u


# ---- lens shading ---------------------------------------------------------------------------
def write_lens_shading(fs: cv2.FileStorage, calib: StereoCalibration) -> None:
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


def read_lens_shading(fs: cv2.FileStorage, where: str) -> PairShading | None:
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
def controls_of(calib: StereoCalibration) -> PairSettings | None:
    c = calib.camera_controls
    return None if c is None or c.empty else c


def write_camera_controls(fs: cv2.FileStorage, calib: StereoCalibration) -> None:
    c = controls_of(calib)
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


def read_camera_controls(fs: cv2.FileStorage, where: str) -> PairSettings | None:
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
            data: dict[str, str | bool | float] = {}
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
