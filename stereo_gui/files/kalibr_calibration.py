"""Robotics calibrations: Kalibr's camera chain (camchain.yaml) and the EuRoC dataset's pair of
sensor.yaml files; Kalibr's is also written (`write_kalibr_camchain`).

Kalibr (ethz-asl/kalibr, wiki "YAML formats"): top-level `cam0`, `cam1` (more cameras are left
out), each with `camera_model`, `intrinsics` [fu, fv, pu, pv] px, `distortion_model`,
`distortion_coeffs` and `resolution` [w, h]; cam1 has `T_cn_cnm1`, the 4x4 transform taking
points from cam0's frame to cam1's (T_c1_c0), translation in METRES.

EuRoC (the ASL dataset layout): `mav0/cam0/sensor.yaml` and `mav0/cam1/sensor.yaml`, each with
`T_BS` ({rows, cols, data}: 4x4 row-major, body <- sensor, metres), `resolution`,
`camera_model`, `intrinsics` [fu, fv, cu, cv], `distortion_model` and
`distortion_coefficients`. Either file opens the pair; cam0 is the left camera, and
T_c1_c0 = inv(T_BS1) @ T_BS0.

Lenses: camera_model `pinhole` only (omni, ds, eucm have no OpenCV counterpart). Distortion
`radtan` / `radial-tangential` is OpenCV's k1 k2 p1 p2 (our "pinhole" model, k3 = 0), `none`
is no distortion, `equidistant` is OpenCV's fisheye model k1..k4 ("fisheye").

The stereo convention is OpenCV's: R = T_c1_c0[:3, :3], T = 1000 T_c1_c0[:3, 3] (mm). What the
files leave out is computed as for OpenCV's sample files: E, F and the Bouguet rectification
(CALIB_ZERO_DISPARITY, alpha 0; core.lens.stereo_rectify, so the fisheye model too).

Both formats are plain YAML that cv2.FileStorage does not read (Kalibr's matrices are block
lists of flow lists): they are parsed with PyYAML's safe loader. An OpenCV `%YAML:1.0` first
line, which some EuRoC-style files carry, is dropped first. Every failure is a
CalibrationFileError naming the file and what is wrong.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.lens import LensModel, stereo_rectify
from stereo_gui.core.stereo_calibration import StereoCalibration, from_file
from stereo_gui.files.atomic import os_error_text, write_text_atomic

log = logging.getLogger(__name__)

# a YAML mapping as PyYAML parses it: any values, checked where they are read
YamlMap = dict[str, Any]

MAX_FILE_BYTES = 1 << 20  # a camera chain is a few hundred bytes
ROTATION_TOL = 1e-4  # R^T R = I within this: files hold 8 or more digits
MAX_PX = 1e6  # focal lengths and principal points beyond any camera's (and overflow)
MAX_TRANSLATION_M = 1000.0  # far beyond any rig (check_plausible has the finer limit)
SNIFF_BYTES = 65536
# distortion_model -> our lens model (core.lens) and its number of coefficients in the file
# distortion_model -> (core.lens model, coefficient count)
DISTORTIONS: dict[str, tuple[LensModel, int]] = {
    "radtan": ("pinhole", 4), "radial-tangential": ("pinhole", 4), "none": ("pinhole", 0),
    "equidistant": ("fisheye", 4)}
_OPENCV_DIRECTIVE = re.compile(r"\A\ufeff?%YAML:\d+\.\d+[^\n]*\n")
_KALIBR_CAM = re.compile(rb"^cam\d+\s*:\s*(#.*)?$", re.MULTILINE)
_KALIBR_FIELD = re.compile(rb"^\s+(camera_model|intrinsics|distortion_model)\s*:", re.MULTILINE)
_EUROC_OWN = re.compile(rb"^(T_BS|distortion_coefficients)\s*:", re.MULTILINE)
_EUROC_FIELD = re.compile(rb"^(sensor_type|camera_model|intrinsics)\s*:", re.MULTILINE)


@dataclass(frozen=True)
class RoboticsCalibration:
    """A calibration read from a Kalibr camchain or a EuRoC pair: the calibration, every file
    read, and each camera's distortion_model as the file named it."""

    calibration: StereoCalibration
    files: tuple[Path, ...]
    distortion_model: str


@dataclass(frozen=True, eq=False)
class _Camera:
    M: np.ndarray  # 3x3, px
    D: np.ndarray  # 1xN, of `model`
    model: LensModel
    size: tuple[int, int]  # (width, height), px
    distortion_model: str  # as the file names it


# ---- telling the formats apart ------------------------------------------------------------
def _head(path: Path) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read(SNIFF_BYTES)
    except OSError:
        return b""


def looks_like_kalibr(path: Path) -> bool:
    """True for a file with a top-level `cam0:` (or `cam1:`...) holding Kalibr's camera
    fields."""
    head = _head(path)
    return bool(_KALIBR_CAM.search(head) and _KALIBR_FIELD.search(head))


def looks_like_euroc(path: Path) -> bool:
    """True for a EuRoC sensor.yaml: a top-level `T_BS` or `distortion_coefficients` beside
    sensor fields (either may be the one missing: the reader then says so)."""
    head = _head(path)
    return bool(_EUROC_OWN.search(head) and _EUROC_FIELD.search(head))


# ---- parsing -------------------------------------------------------------------------------
def _load_yaml(path: Path) -> YamlMap:
    """The top-level mapping of a plain YAML file."""
    try:  # guarded: without PyYAML the error says what to install (a test checks it)
        import yaml
    except ImportError:
        raise CalibrationFileError(f"{path}: reading Kalibr and EuRoC files needs PyYAML "
                                   "(pip install pyyaml)") from None
    text = _read_text(path)
    try:
        doc = yaml.safe_load(_OPENCV_DIRECTIVE.sub("", text, count=1))
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}" if where is not None else ""
        problem = getattr(exc, "problem", None) or type(exc).__name__
        raise CalibrationFileError(f"{path} is not readable YAML{at} ({problem})") from None
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise CalibrationFileError(f"{path} is not readable YAML ({exc})") from None
    if not isinstance(doc, dict):
        raise CalibrationFileError(f"{path} holds no YAML mapping of names to values")
    return doc


def _read_text(path: Path) -> str:
    if not path.is_file():
        raise CalibrationFileError(f"calibration file {path} does not exist")
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise CalibrationFileError(f"{path} is too large for a camera calibration")
        return path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise CalibrationFileError(f"{path} cannot be read: {os_error_text(exc)}") from None
    except UnicodeDecodeError:
        raise CalibrationFileError(f"{path} is not UTF-8 text") from None


def _number(v: object) -> float | None:
    if isinstance(v, bool):  # YAML's yes/no/on/off
        return None
    if isinstance(v, (int, float)):
        f = float(v) if abs(v) < 1e308 else math.inf
    elif isinstance(v, str):  # PyYAML reads "1e-05" (no dot) as a string
        try:
            f = float(v)
        except ValueError:
            return None
    else:
        return None
    return f if math.isfinite(f) else None


def _numbers(doc: YamlMap, key: str, where: str, count: int | None = None) -> np.ndarray:
    """The list of finite numbers doc[key], of `count` elements when given."""
    if key not in doc:
        raise CalibrationFileError(f"{where}: {key} is missing")
    value = doc[key]
    values = [_number(v) for v in value] if isinstance(value, list) else [None]
    if any(v is None for v in values):
        raise CalibrationFileError(f"{where}: {key} should be a list of finite numbers")
    if count is not None and len(values) != count:
        raise CalibrationFileError(f"{where}: {key} should hold {count} numbers, found "
                                   f"{len(values)}")
    return np.array(values, np.float64)


def _text(doc: YamlMap, key: str, where: str) -> str:
    value = doc.get(key)
    if value is None:
        raise CalibrationFileError(f"{where}: {key} is missing")
    return str(value).strip()


def _size(doc: YamlMap, where: str) -> tuple[int, int]:
    w, h = _numbers(doc, "resolution", where, 2)
    if not (w == int(w) and h == int(h) and 0 < w <= 100_000 and 0 < h <= 100_000):
        raise CalibrationFileError(f"{where}: resolution should be two positive whole numbers "
                                   "(width, height)")
    return int(w), int(h)


def _camera(doc: object, where: str, coeffs_key: str) -> _Camera:
    """One camera's lens from Kalibr's or EuRoC's fields (their names differ only for the
    distortion coefficients)."""
    if not isinstance(doc, dict):
        raise CalibrationFileError(f"{where} is not a mapping of camera fields")
    projection = _text(doc, "camera_model", where)
    if projection != "pinhole":
        raise CalibrationFileError(
            f"{where}: camera_model {projection[:40]!r} is not supported: stereo-gui reads the "
            "pinhole projection only (omni, ds and eucm have no OpenCV counterpart)")
    fu, fv, cu, cv = _numbers(doc, "intrinsics", where, 4)
    if not (fu > 0 and fv > 0):
        raise CalibrationFileError(f"{where}: intrinsics have no positive focal length "
                                   f"(fu {fu:g}, fv {fv:g})")
    if max(fu, fv, abs(cu), abs(cv)) > MAX_PX:
        raise CalibrationFileError(f"{where}: intrinsics [{fu:g}, {fv:g}, {cu:g}, {cv:g}] are "
                                   "beyond any camera's")
    name = _text(doc, "distortion_model", where)
    if name not in DISTORTIONS:
        raise CalibrationFileError(f"{where}: distortion_model {name[:40]!r} is not supported (use "
                                   f"{', '.join(DISTORTIONS)})")
    model, count = DISTORTIONS[name]
    # `none` needs no coefficients; given, they must be an empty list
    k = _numbers(doc, coeffs_key, where, count) if count or coeffs_key in doc else np.zeros(0)
    D = np.zeros((1, 5)) if model == "pinhole" else np.zeros((1, 4))
    D[0, :count] = k  # radtan's k1 k2 p1 p2 are OpenCV's first four
    M = np.array([[fu, 0.0, cu], [0.0, fv, cv], [0.0, 0.0, 1.0]])
    return _Camera(M, D, model, _size(doc, where), name)


def _transform(value: object, key: str, where: str) -> np.ndarray:
    """A 4x4 rigid transform: Kalibr's list of 4 rows, or EuRoC's {rows, cols, data}."""
    if isinstance(value, dict):
        rows, cols = _number(value.get("rows")), _number(value.get("cols"))
        if (rows, cols) != (4.0, 4.0):
            raise CalibrationFileError(f"{where}: {key} should have rows: 4 and cols: 4")
        m = _numbers(value, "data", f"{where}: {key}", 16).reshape(4, 4)
    elif isinstance(value, list) and len(value) == 4 and all(isinstance(r, list) for r in value):
        m = np.array([_numbers({key: r}, key, where, 4) for r in value])
    else:
        raise CalibrationFileError(f"{where}: {key} should be a 4x4 matrix (4 rows of 4 numbers)")
    R = m[:3, :3]
    if not np.all(np.abs(m[:3, 3]) <= MAX_TRANSLATION_M):
        raise CalibrationFileError(f"{where}: {key} has a translation of "
                                   f"{np.max(np.abs(m[:3, 3])):.3g} m: not a camera of a rig")
    if not np.allclose(m[3], (0.0, 0.0, 0.0, 1.0), atol=1e-9):
        raise CalibrationFileError(f"{where}: {key}'s last row should be 0 0 0 1")
    if not (np.max(np.abs(R)) <= 1.0 + ROTATION_TOL  # (and R^T R cannot overflow)
            and np.allclose(R.T @ R, np.eye(3), atol=ROTATION_TOL)
            and abs(np.linalg.det(R) - 1.0) < ROTATION_TOL):
        raise CalibrationFileError(f"{where}: {key}'s upper-left 3x3 block is not a rotation")
    return m


def _inverse(m: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4x4 transform."""
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


# ---- the stereo calibration ----------------------------------------------------------------
def _cross(t: np.ndarray) -> np.ndarray:
    t = t.reshape(3)
    return np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]], np.float64)


def _check_pair(left: _Camera, right: _Camera, where: str) -> None:
    if left.model != right.model:
        raise CalibrationFileError(f"{where}: cam0 is {left.distortion_model} but cam1 is "
                                   f"{right.distortion_model}: both cameras need one lens model")
    if left.size != right.size:
        raise CalibrationFileError(f"{where}: cam0 is {left.size[0]}x{left.size[1]} but cam1 is "
                                   f"{right.size[0]}x{right.size[1]}: a stereo pair needs one "
                                   "image size")


def _stereo(left: _Camera, right: _Camera, T_c1_c0: np.ndarray, where: str,
            origin: str) -> StereoCalibration:
    """The StereoCalibration of cam0 (left) and cam1 (right), `T_c1_c0` in metres."""
    _check_pair(left, right, where)
    R = np.array(T_c1_c0[:3, :3], np.float64)
    T = np.array(T_c1_c0[:3, 3], np.float64).reshape(3, 1) * 1000.0  # m -> mm
    if not np.any(T):
        raise CalibrationFileError(f"{where}: the translation from cam0 to cam1 is zero: the "
                                   "two cameras are at one place")
    try:
        R1, R2, P1, P2, Q = stereo_rectify(left.model, left.M, left.D, right.M, right.D,
                                           left.size, R, T, 0.0)
    except cv2.error as exc:
        raise CalibrationFileError(f"{where}: the rectification cannot be computed from these "
                                   f"cameras ({str(exc).strip().splitlines()[-1]})") from None
    E = _cross(T) @ R
    F = np.linalg.inv(right.M).T @ E @ np.linalg.inv(left.M)
    F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
    with from_file(where):
        return StereoCalibration(image_size=left.size, M1=left.M, D1=left.D, M2=right.M,
                                 D2=right.D, R=R, T=T, E=E, F=F, R1=R1, R2=R2, P1=P1, P2=P2, Q=Q,
                                 method="bouguet", alpha=0.0, model=left.model, origin=origin)


def read_kalibr_camchain(path: str | Path) -> RoboticsCalibration:
    """Read cam0 (left) and cam1 (right) of a Kalibr camchain.yaml; CalibrationFileError names
    the file and what is missing or wrong."""
    path = Path(path)
    doc = _load_yaml(path)
    if "cam0" not in doc:
        raise CalibrationFileError(f"{path}: cam0 is missing (a Kalibr camera chain names its "
                                   "cameras cam0, cam1, ...)")
    if "cam1" not in doc:
        raise CalibrationFileError(f"{path} holds one camera (cam0): a stereo pair needs cam0 "
                                   "and cam1")
    left = _camera(doc["cam0"], f"{path}: cam0", "distortion_coeffs")
    right = _camera(doc["cam1"], f"{path}: cam1", "distortion_coeffs")
    if "T_cn_cnm1" not in doc["cam1"]:
        raise CalibrationFileError(f"{path}: cam1 has no T_cn_cnm1 (the transform from cam0's "
                                   "frame to cam1's), so the pair's extrinsics are unknown")
    T_c1_c0 = _transform(doc["cam1"]["T_cn_cnm1"], "T_cn_cnm1", f"{path}: cam1")
    others = sorted(k for k in doc if isinstance(k, str) and re.fullmatch(r"cam\d+", k)
                    and k not in ("cam0", "cam1"))
    if others:
        log.info("%s: using cam0 and cam1; %s left out", path, " ".join(others))
    calib = _stereo(left, right, T_c1_c0, str(path), f"read from Kalibr camchain {path}")
    return RoboticsCalibration(calib, (path,), left.distortion_model)


def euroc_pair(path: Path) -> tuple[Path, Path]:
    """(cam0, cam1) sensor.yaml of the pair `path` belongs to: the same file name in the sibling
    folder (mav0/cam0 <-> mav0/cam1)."""
    folder = path.parent.name
    if folder not in ("cam0", "cam1"):
        raise CalibrationFileError(
            f"{path} is a EuRoC sensor.yaml outside a cam0 or cam1 folder: the pair is read "
            "from mav0/cam0/sensor.yaml and mav0/cam1/sensor.yaml")
    other = path.parent.parent / ("cam1" if folder == "cam0" else "cam0") / path.name
    if not other.is_file():
        raise CalibrationFileError(f"{path} is one EuRoC camera; the other camera's file "
                                   f"{other} was not found")
    return (path, other) if folder == "cam0" else (other, path)


def _euroc_camera(path: Path) -> tuple[_Camera, np.ndarray]:
    doc = _load_yaml(path)
    sensor = str(doc.get("sensor_type", "camera")).strip()
    if sensor != "camera":
        raise CalibrationFileError(f"{path} describes a sensor of type {sensor[:40]!r}, not a "
                                   "camera: open mav0/cam0/sensor.yaml")
    if "T_BS" not in doc:
        raise CalibrationFileError(f"{path}: T_BS is missing")
    T_BS = _transform(doc["T_BS"], "T_BS", str(path))
    return _camera(doc, str(path), "distortion_coefficients"), T_BS


def read_euroc_pair(path: str | Path) -> RoboticsCalibration:
    """Read the EuRoC pair from either camera's sensor.yaml (cam0 is the left camera)."""
    cam0_path, cam1_path = euroc_pair(Path(path))
    (left, T_BS0), (right, T_BS1) = _euroc_camera(cam0_path), _euroc_camera(cam1_path)
    where = f"{cam0_path} + {cam1_path}"
    T_c1_c0 = _inverse(T_BS1) @ T_BS0  # cam0 -> body -> cam1
    calib = _stereo(left, right, T_c1_c0, where, f"read from EuRoC {where}")
    return RoboticsCalibration(calib, (cam0_path, cam1_path), left.distortion_model)


# ---- writing Kalibr's camchain -------------------------------------------------------------
def _yaml_float(x: float) -> str:
    """A float as YAML text every YAML 1.1 reader takes for a float and reads back to the same
    double: PyYAML (Kalibr's) reads 1e-05 as a string, 1.0e-05 as a number."""
    x = float(x)
    if not math.isfinite(x):
        raise CalibrationFileError(f"cannot write a non-finite value ({x}) to a Kalibr camchain")
    text = repr(x)
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def _flow(values: Iterable[float]) -> str:
    return "[" + ", ".join(_yaml_float(v) for v in values) + "]"


def _kalibr_distortion(calib: StereoCalibration, D: np.ndarray,
                       name: str) -> tuple[str, list[float]]:
    """(distortion_model, coefficients) of one camera; refused when Kalibr has no such lens."""
    d = np.asarray(D, np.float64).reshape(-1)
    if calib.model == "fisheye":
        return "equidistant", list(d[:4])
    higher = [f"{n} = {v:g}" for n, v in zip(("k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
                                                "tx", "ty"), d[4:]) if v != 0.0]
    if higher:
        kind = "rational model's" if calib.model == "rational" else "pinhole model's"
        raise CalibrationFileError(
            f"{name} cannot be written to a Kalibr camchain: Kalibr's radtan distortion is "
            f"k1 k2 p1 p2 alone, and this {kind} {', '.join(higher)}; calibrate again with "
            "k3 fixed at zero for Kalibr, or export to ROS camera_info, which keeps them")
    return "radtan", list(np.concatenate([d[:4], np.zeros(4 - min(d.size, 4))]))


def _camera_lines(calib: StereoCalibration, k: int) -> list[str]:
    M, D = (calib.M1, calib.D1) if k == 0 else (calib.M2, calib.D2)
    M = np.asarray(M, np.float64)
    if M[0, 1] != 0.0:
        raise CalibrationFileError(f"M{k + 1} has a skew term ({M[0, 1]:g}), which Kalibr's "
                                   "pinhole intrinsics [fu, fv, pu, pv] cannot hold")
    model, coeffs = _kalibr_distortion(calib, D, f"D{k + 1}")
    return ["  camera_model: pinhole",
            f"  intrinsics: {_flow((M[0, 0], M[1, 1], M[0, 2], M[1, 2]))}",
            f"  distortion_model: {model}",
            f"  distortion_coeffs: {_flow(coeffs)}",
            f"  resolution: [{calib.width}, {calib.height}]",
            f"  cam_overlaps: [{1 - k}]",
            f"  rostopic: /cam{k}/image_raw"]


def kalibr_camchain_text(calib: StereoCalibration) -> str:
    """`calib` as a Kalibr camchain.yaml (cam0 the left camera, cam1 the right)."""
    if not calib.metric:
        raise CalibrationFileError("a Hartley calibration has no metric baseline: Kalibr's "
                                   "T_cn_cnm1 needs the translation in metres")
    if calib.swapped_inputs:
        log.warning("Kalibr export: cam0 is the calibration's left camera, which is the "
                    "source's second camera (the pairs were found swapped)")
    T_c1_c0 = np.eye(4)
    T_c1_c0[:3, :3] = np.asarray(calib.R, np.float64)
    T_c1_c0[:3, 3] = np.asarray(calib.T, np.float64).reshape(3) / 1000.0  # mm -> m
    lines = ["# Kalibr camera chain written by stereo-gui: cam0 is the left camera, cam1 the",
             "# right; T_cn_cnm1 takes points from cam0's frame to cam1's, metres",
             f"# calibration created {calib.created}",
             "cam0:", *_camera_lines(calib, 0),
             "cam1:", "  T_cn_cnm1:", *(f"  - {_flow(row)}" for row in T_c1_c0),
             *_camera_lines(calib, 1)]
    return "\n".join(lines) + "\n"


def write_kalibr_camchain(path: str | Path, calibration: StereoCalibration) -> Path:
    """Write `calibration` as a Kalibr camchain.yaml, atomically; the file is read back and
    compared before it replaces `path`. CalibrationFileError when Kalibr has no model for the
    calibration's lenses (k3 or rational terms, skew, no metric baseline)."""
    text = kalibr_camchain_text(calibration)

    def verify(tmp: Path) -> None:
        _check_read_back(read_kalibr_camchain(tmp).calibration, calibration)

    return write_text_atomic(path, text, verify)


def _check_read_back(back: StereoCalibration, calib: StereoCalibration) -> None:
    """Raise CalibrationFileError naming the first value a written camchain does not give back
    (T went through metres: within a few ulps)."""
    for name, n in (("M1", 9), ("M2", 9), ("R", 9), ("D1", 4), ("D2", 4)):
        # radtan holds the first four of a pinhole model's coefficients (the rest are zero)
        a = back.matrices()[name].reshape(-1)
        b = calib.matrices()[name].reshape(-1)
        if not np.array_equal(a[:n], b[:n]):
            raise CalibrationFileError(f"{name} reads back different")
    if back.image_size != calib.image_size:
        raise CalibrationFileError("the image size reads back different")
    if not np.allclose(back.T, calib.T, rtol=1e-12, atol=0.0):
        raise CalibrationFileError("T reads back different")
