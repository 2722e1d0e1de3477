"""Stereo calibrations written by OpenCV's stereo sample (samples/cpp/stereo_calib.cpp) and by
the many tools that copied it: FileStorage files (YAML or XML) holding `M1 D1 M2 D2 R T`,
optionally `R1 R2 P1 P2 Q E F`, either in one file or as the sample's own pair
`intrinsics.yml` (M1 D1 M2 D2) + `extrinsics.yml` (R T R1 R2 P1 P2 Q) in one folder.

What the files leave out is computed: E and F from R and T, the rectification (R1 R2 P1 P2 Q)
with cv2.stereoRectify (CALIB_ZERO_DISPARITY, alpha 0, as our own calibrations), Q from P1 and
P2. The sample writes no image size; it is read from the file when present (`image_width` +
`image_height`, or `imageSize` / `image_size` as [w, h]), else the caller gives the size of its
images or source; without either, CalibrationFileError says so.

T is taken to be in millimetres, our unit. The sample measures T in board squares (`-s`, the
square size, defaults to 1): a baseline below 1 is reported as a warning.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.stereo_calibration import (
    StereoCalibration,
    from_file,
    q_from_projections,
)
from stereo_gui.files.filestorage import read_matrix

log = logging.getLogger(__name__)

REQUIRED = ("M1", "D1", "M2", "D2", "R", "T")
OPTIONAL = ("R1", "R2", "P1", "P2", "Q", "E", "F")
INTRINSIC_NAMES = ("M1", "D1", "M2", "D2")
EXTRINSIC_NAMES = ("R", "T", "R1", "R2", "P1", "P2", "Q", "E", "F")
SUFFIXES = (".yml", ".yaml", ".xml", ".json")
_OPENCV_NAME = re.compile(r"(intrinsic|extrinsic)", re.IGNORECASE)


# an image size (width, height) px, or a function that returns it (or None), asked only when a
# file holds no size of its own: reading an image to learn its size is not free
SizeHint = tuple[int, int] | Callable[[], tuple[int, int] | None] | None


def resolve_size(hint: SizeHint) -> tuple[int, int] | None:
    value = hint() if callable(hint) else hint
    return None if value is None else (int(value[0]), int(value[1]))


@dataclass(frozen=True)
class OpenCVStereoFile:
    """A calibration read from OpenCV sample files: the calibration, every file read, and which
    matrices were computed here because the files did not hold them."""

    calibration: StereoCalibration
    files: tuple[Path, ...]
    computed: tuple[str, ...]
    size_from_file: bool


def _open(path: Path) -> cv2.FileStorage:
    if not path.is_file():
        raise CalibrationFileError(f"calibration file {path} does not exist")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError):
        raise CalibrationFileError(f"{path} is not an OpenCV FileStorage file") from None
    if not fs.isOpened():
        raise CalibrationFileError(f"{path} is not an OpenCV FileStorage file")
    return fs


def _present(fs: cv2.FileStorage, name: str) -> bool:
    node = fs.getNode(name)
    return not (node.empty() or node.isNone())


def holds_stereo_sample_matrices(fs: cv2.FileStorage) -> bool:
    """True when an open FileStorage holds any of the sample's matrix names."""
    return any(_present(fs, n) for n in REQUIRED)


def _matrix(fs: cv2.FileStorage, name: str, where: Path) -> NDArray[np.float64]:
    m = read_matrix(fs.getNode(name), name, str(where))
    if not np.all(np.isfinite(m)):
        raise CalibrationFileError(f"{where}: matrix {name} holds values that are not finite")
    return m


def _size_in(fs: cv2.FileStorage, where: Path) -> tuple[int, int] | None:
    """The image size a file holds, (width, height) px, or None."""
    def positive_int(node: cv2.FileNode) -> int | None:
        if node.empty() or not (node.isInt() or node.isReal()):
            return None
        v = node.real()
        return int(v) if v == int(v) and v > 0 else None

    w, h = positive_int(fs.getNode("image_width")), positive_int(fs.getNode("image_height"))
    if w and h:
        return w, h
    for key in ("imageSize", "image_size"):
        node = fs.getNode(key)
        if node.empty() or node.isNone():
            continue
        values = None
        if node.isSeq() and node.size() == 2:  # cv::Size: [640, 480]
            values = [node.at(0).real(), node.at(1).real()]
        elif node.isMap():  # a 2-element matrix (Python's fs.write of a tuple)
            m = read_matrix(node, key, str(where))
            if m.size == 2:
                values = [float(v) for v in m.reshape(-1)]
        if values and all(v == int(v) and v > 0 for v in values):
            return int(values[0]), int(values[1])
        raise CalibrationFileError(f"{where}: {key} should be two positive whole numbers "
                                   "(width, height)")
    return None


def partner_file(path: Path) -> Path | None:
    """The other file of the sample's pair: extrinsics.yml beside intrinsics.yml (and the other
    way round), with the same prefix ("left_intrinsics.xml" -> "left_extrinsics.xml") and any of
    the FileStorage suffixes; None when there is none."""
    found = _OPENCV_NAME.search(path.stem)
    if found is None:
        return None
    word = found.group(1)
    other = "extrinsic" if word.lower() == "intrinsic" else "intrinsic"
    other = other.upper() if word.isupper() else other.capitalize() if word[0].isupper() else other
    base = path.stem[:found.start()] + other + path.stem[found.end():]
    for suffix in dict.fromkeys((path.suffix, *SUFFIXES)):
        candidate = path.with_name(base + suffix)
        if candidate.is_file():
            return candidate
    return None


def _read_all(path: Path) -> tuple[dict[str, NDArray[np.float64]], tuple[int, int] | None]:
    fs = _open(path)
    try:
        mats = {n: _matrix(fs, n, path) for n in REQUIRED + OPTIONAL if _present(fs, n)}
        return mats, _size_in(fs, path)
    finally:
        fs.release()


def _essential(R: NDArray[np.float64], T: NDArray[np.float64]) -> NDArray[np.float64]:
    t = T.reshape(3)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]], np.float64)
    return tx @ R


def _read_with_partner(path: Path) -> tuple[dict[str, NDArray[np.float64]],
                                            tuple[int, int] | None, list[Path]]:
    """The matrices and image size of `path` and, when it lacks intrinsics or extrinsics, of
    its partner file (what `path` holds wins); the files read."""
    mats, size = _read_all(path)
    files = [path]
    missing_intrinsics = [n for n in INTRINSIC_NAMES if n not in mats]
    missing_extrinsics = [n for n in ("R", "T") if n not in mats]
    if missing_intrinsics or missing_extrinsics:
        other = partner_file(path)
        if other is not None:
            more, more_size = _read_all(other)
            for name, m in more.items():
                mats.setdefault(name, m)
            size = size or more_size
            files.append(other)
    return mats, size, files


def _check_required(mats: dict[str, NDArray[np.float64]], files: list[Path], where: str) -> None:
    missing = [n for n in REQUIRED if n not in mats]
    if missing:
        hint = ""
        if len(files) == 1 and (set(missing) <= set(INTRINSIC_NAMES)
                                or set(missing) <= {"R", "T"}):
            kind = "intrinsics" if set(missing) <= set(INTRINSIC_NAMES) else "extrinsics"
            hint = (f"; OpenCV's stereo sample writes them to {kind}.yml, which was not found "
                    f"beside it")
        raise CalibrationFileError(f"{where}: {', '.join(missing)} missing (a stereo calibration "
                                   f"needs {' '.join(REQUIRED)}){hint}")


def _image_size(size: tuple[int, int] | None, image_size: SizeHint,
                where: str) -> tuple[tuple[int, int], bool]:
    """The files' image size, else the caller's; and whether it came from the files."""
    if size is None:
        hint = resolve_size(image_size)
        if hint is None:
            raise CalibrationFileError(
                f"{where} does not say which image size it was made for (no image_width and "
                "image_height): open it together with images or a source, whose size is then "
                "used, or add image_width and image_height to the file")
        size = (int(hint[0]), int(hint[1]))
        size_from_file = False
    else:
        size_from_file = True
    if size[0] <= 0 or size[1] <= 0:
        raise CalibrationFileError(f"{where}: image size {size[0]}x{size[1]} is not valid")
    return size, size_from_file


@dataclass(frozen=True)
class _Cameras:
    """The matrices every stereo calibration file holds, checked and in our shapes."""

    M1: NDArray[np.float64]
    D1: NDArray[np.float64]
    M2: NDArray[np.float64]
    D2: NDArray[np.float64]
    R: NDArray[np.float64]
    T: NDArray[np.float64]


def _cameras(mats: dict[str, NDArray[np.float64]], where: str) -> _Cameras:
    M1, M2 = mats["M1"], mats["M2"]
    D1, D2 = mats["D1"].reshape(1, -1), mats["D2"].reshape(1, -1)
    R = mats["R"]
    if R.size == 3:  # a rotation vector (Rodrigues), as some tools write
        R = np.asarray(cv2.Rodrigues(R.reshape(3, 1))[0], np.float64)
    T = mats["T"]
    if T.size != 3:
        raise CalibrationFileError(f"{where}: T should hold 3 numbers, found {T.size}")
    T = T.reshape(3, 1)
    for name, m, shape in (("M1", M1, (3, 3)), ("M2", M2, (3, 3)), ("R", R, (3, 3))):
        if m.shape != shape:
            raise CalibrationFileError(f"{where}: matrix {name} should be 3x3, found "
                                       f"{'x'.join(map(str, m.shape))}")
    for name, M in (("M1", M1), ("M2", M2)):
        if not (M[0, 0] > 0 and M[1, 1] > 0):
            raise CalibrationFileError(f"{where}: {name} has no positive focal length")
    for name, D in (("D1", D1), ("D2", D2)):
        if D.size not in (4, 5, 8, 12, 14):
            raise CalibrationFileError(f"{where}: distortion {name} should have 4, 5, 8, 12 or "
                                       f"14 coefficients, found {D.size}")
    if not np.any(T):
        raise CalibrationFileError(f"{where}: T is zero: the two cameras are at one place")
    return _Cameras(M1, D1, M2, D2, R, T)


def _completed(mats: dict[str, NDArray[np.float64]], cams: _Cameras, size: tuple[int, int],
               where: str) -> tuple[dict[str, NDArray[np.float64]], list[str]]:
    """R1 R2 P1 P2 Q E F: from the files, else computed; and the names of those computed."""
    computed: list[str] = []
    rect: dict[str, NDArray[np.float64]] = {n: mats[n] for n in ("R1", "R2", "P1", "P2")
                                            if n in mats}
    Q = mats.get("Q")
    if len(rect) < 4:
        try:
            R1, R2, P1, P2, q, _, _ = cv2.stereoRectify(
                cams.M1, cams.D1, cams.M2, cams.D2, size, cams.R, cams.T,
                flags=cv2.CALIB_ZERO_DISPARITY, alpha=0.0)
        except cv2.error as exc:
            raise CalibrationFileError(f"{where}: cv2.stereoRectify failed on these matrices "
                                       f"({str(exc).strip().splitlines()[-1]})") from None
        rect = {n: np.asarray(m, np.float64)
                for n, m in (("R1", R1), ("R2", R2), ("P1", P1), ("P2", P2))}
        Q = np.asarray(q, np.float64)
        computed += ["R1", "R2", "P1", "P2", "Q"]
    elif Q is None:
        Q = q_from_projections(rect["P1"], rect["P2"])
        computed.append("Q")
    E = mats.get("E")
    if E is None:
        E = _essential(cams.R, cams.T)
        computed.append("E")
    F = mats.get("F")
    if F is None:
        F = np.linalg.inv(cams.M2).T @ E @ np.linalg.inv(cams.M1)
        F = F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F
        computed.append("F")
    return {**rect, "Q": Q, "E": E, "F": F}, computed


def read_opencv_stereo(path: str | Path, image_size: SizeHint = None) -> OpenCVStereoFile:
    """Read OpenCV stereo sample files starting from `path` (one file, or either file of the
    intrinsics + extrinsics pair). `image_size` (width, height) px is used when the files hold
    none. Raises CalibrationFileError naming the file and what is missing or wrong."""
    path = Path(path)
    mats, size_in_files, files = _read_with_partner(path)
    where = " + ".join(str(p) for p in files)
    _check_required(mats, files, where)
    size, size_from_file = _image_size(size_in_files, image_size, where)
    cams = _cameras(mats, where)
    rest, computed = _completed(mats, cams, size, where)
    with from_file(where):
        calib = StereoCalibration(image_size=size, M1=cams.M1, D1=cams.D1, M2=cams.M2,
                                  D2=cams.D2, R=cams.R, T=cams.T, E=rest["E"], F=rest["F"],
                                  R1=rest["R1"], R2=rest["R2"], P1=rest["P1"], P2=rest["P2"],
                                  Q=rest["Q"], method="bouguet")
    if calib.baseline_mm < 1.0:
        log.warning("%s: the baseline is %.4g; stereo-gui reads T in millimetres, but OpenCV's "
                    "stereo sample writes it in board squares unless given the square size (-s)",
                    where, calib.baseline_mm)
    if computed:
        log.info("%s: computed %s", where, " ".join(computed))
    return OpenCVStereoFile(calib, tuple(files), tuple(computed), size_from_file)
