"""ROS camera_info files (left.yaml, right.yaml): export and import.

They follow ROS's layout ({rows, cols, data} matrices, distortion_model plumb_bob,
rational_polynomial or equidistant for fisheye lenses) and ROS's unit for the projection's
translation term: METRES (ours is mm).
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import CalibrationFileError, InputError
from stereo_gui.core.lens import LensModel
from stereo_gui.core.plausibility import check_plausible
from stereo_gui.core.stereo_calibration import (
    StereoCalibration,
    check_camera_matrix,
    check_image_size,
    check_projection_focal,
    from_file,
    q_from_projections,
)
from stereo_gui.files.atomic import write_many_atomic
from stereo_gui.files.calibration_file_checks import check_parsable, parse_error, read_string

log = logging.getLogger(__name__)

ROS_DISTORTION_MODELS: dict[LensModel, str] = {
    "pinhole": "plumb_bob", "rational": "rational_polynomial", "fisheye": "equidistant"}


def _num(x: float) -> str:
    """A float as YAML text that reads back to the same double."""
    x = float(x)
    if math.isfinite(x):
        return repr(x)
    raise CalibrationFileError(f"cannot export a non-finite value ({x}) to ROS camera_info")


def _ros_matrix(name: str, m: NDArray[np.float64]) -> str:
    m = np.atleast_2d(np.asarray(m, np.float64))
    rows, cols = m.shape
    data = ", ".join(_num(v) for v in m.reshape(-1))
    return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"


def ros_camera_info_text(calib: StereoCalibration, side: str,
                         camera_name: str | None = None) -> str:
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


def export_ros(calib: StereoCalibration, folder: str | Path,
               prefix: str = "") -> tuple[Path, Path]:
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


@dataclass(frozen=True)
class _RosCamera:
    """What one camera_info file holds (the projection's translation term still in metres)."""

    image_width: int
    image_height: int
    distortion_model: str
    camera_matrix: NDArray[np.float64]
    distortion_coefficients: NDArray[np.float64]
    rectification_matrix: NDArray[np.float64]
    projection_matrix: NDArray[np.float64]


def _ros_int(fs: cv2.FileStorage, key: str, where: str) -> int:
    n = fs.getNode(key)
    if n.empty() or not n.isInt():
        raise CalibrationFileError(f"{where}: {key} is missing or not a whole number")
    return int(n.real())


def _ros_mat(fs: cv2.FileStorage, key: str, shape: tuple[int, int] | None,
             where: str) -> NDArray[np.float64]:
    """The {rows, cols, data} matrix `key`, of `shape` when one is given."""
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
    return m


def _ros_camera(fs: cv2.FileStorage, where: str) -> _RosCamera:
    width, height = _ros_int(fs, "image_width", where), _ros_int(fs, "image_height", where)
    with from_file(where):
        check_image_size(width, height)
    model = read_string(fs, "distortion_model", "plumb_bob")
    if model not in ROS_DISTORTION_MODELS.values():
        raise CalibrationFileError(f"{where}: distortion model {model!r} is "
                                   "not supported (plumb_bob, rational_polynomial or "
                                   "equidistant)")
    return _RosCamera(width, height, model, _ros_mat(fs, "camera_matrix", (3, 3), where),
                      _ros_mat(fs, "distortion_coefficients", None, where),
                      _ros_mat(fs, "rectification_matrix", (3, 3), where),
                      _ros_mat(fs, "projection_matrix", (3, 4), where))


def _ros_read(path: Path) -> _RosCamera:
    where = str(path)
    if not path.exists():
        raise CalibrationFileError(f"ROS camera_info file {path} does not exist")
    check_parsable(path, f"ROS camera_info file {path}")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_FORMAT_YAML)
    except (cv2.error, SystemError):
        raise CalibrationFileError(f"{path} is not a readable YAML file") from None
    try:
        if not fs.isOpened():
            raise CalibrationFileError(f"{path} is not a readable YAML file")
        return _ros_camera(fs, where)
    except UnicodeDecodeError:
        raise CalibrationFileError(f"{where}: a text value is not UTF-8") from None
    except (cv2.error, SystemError) as exc:
        raise CalibrationFileError(f"{where} is damaged ({parse_error(exc)})") from None
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
    size = (left.image_width, left.image_height)
    if size != (right.image_width, right.image_height):
        raise CalibrationFileError(f"{lp} is {size[0]}x{size[1]} but {rp} is "
                                   f"{right.image_width}x{right.image_height}")
    M1, M2 = left.camera_matrix, right.camera_matrix
    for path, side in ((lp, left), (rp, right)):
        with from_file(str(path)):
            check_camera_matrix(side.camera_matrix, "camera_matrix")
            check_projection_focal(side.projection_matrix, "projection_matrix")
    D1 = left.distortion_coefficients.reshape(1, -1)
    D2 = right.distortion_coefficients.reshape(1, -1)
    R1, R2 = left.rectification_matrix, right.rectification_matrix
    P1 = left.projection_matrix.copy()
    P2 = right.projection_matrix.copy()
    P1[:, 3] *= 1000.0  # m -> mm
    P2[:, 3] *= 1000.0
    t_rect = np.array([[P2[0, 3] / P2[0, 0]], [P2[1, 3] / P2[1, 1]], [0.0]])
    if not np.any(t_rect):
        raise CalibrationFileError(f"{rp}: projection_matrix has no baseline term (P[0,3] and "
                                   "P[1,3] are zero), so it is not the right camera of a stereo "
                                   "pair")
    R = R2.T @ R1
    T = R2.T @ t_rect
    tx = np.array([[0, -T[2, 0], T[1, 0]], [T[2, 0], 0, -T[0, 0]], [-T[1, 0], T[0, 0], 0]])
    E = tx @ R
    F = np.linalg.inv(M2).T @ E @ np.linalg.inv(M1)
    F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
    Q = q_from_projections(P1, P2)
    models = {v: k for k, v in ROS_DISTORTION_MODELS.items()}
    if left.distortion_model != right.distortion_model:
        raise CalibrationFileError(f"{lp} and {rp} have different distortion models "
                                   f"({left.distortion_model}, {right.distortion_model})")
    model = models[left.distortion_model]
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
