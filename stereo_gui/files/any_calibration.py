"""Open any calibration `--calib` and File > Open calibration accept, whoever wrote it.

`load_any_calibration(spec, image_size)` tries, in this order:

1. `rectified:F,B[,DOFFS]` (a pair that is already rectified; `image_size` is its size);
2. Middlebury 2014's `calib.txt`;
3. Kalibr's camera chain `camchain.yaml` (cam0 + cam1; `files.kalibr_calibration` reads it);
4. the EuRoC dataset's `mav0/cam0/sensor.yaml` or `mav0/cam1/sensor.yaml` (the other camera's
   file is found in the sibling folder);
5. our own calibration file (it has `format_version`; `files.calibration_file` reads it);
6. ROS camera_info: either file of a left.yaml + right.yaml pair (the other is found beside it);
7. OpenCV's stereo sample: one FileStorage file (YAML or XML) with M1 D1 M2 D2 R T, or either
   file of its intrinsics.yml + extrinsics.yml pair.

`image_size` (width, height) px, from the images or the source at hand, is used only when the
file holds no size; it may be a function returning it, called only then (reading an image to
learn its size is not free). Every failure is a CalibrationFileError (InputError for a bad spec) that
names the file.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

import cv2

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.plausibility import check_plausible
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files import kalibr_calibration as kalibr
from stereo_gui.files import rectified_calibration as rect
from stereo_gui.files.calibration_file import load_calibration
from stereo_gui.files.opencv_calibration import SizeHint, read_opencv_stereo, resolve_size
from stereo_gui.files.ros_camera_info import import_ros

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LoadedCalibration:
    """A calibration and where it came from.

    `path` is the file to remember and reopen (None for a `rectified:` spec), `files` every file
    read, `kind` one of "stereo-gui", "opencv", "ros", "middlebury", "rectified", "kalibr",
    "euroc", and `description` a short text for the status bar ("OpenCV stereo sample
    intrinsics.yml + extrinsics.yml, image size 640x480 from the images").
    """

    calibration: StereoCalibration
    path: Path | None
    kind: str
    files: tuple[Path, ...]
    description: str


def _size_text(size: tuple[int, int]) -> str:
    return f"{size[0]}x{size[1]}"


def _peek(path: Path) -> set[str] | None:
    """The top-level names of a FileStorage file that tell the formats apart, or None when
    OpenCV cannot read it as FileStorage."""
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError):
        return None
    try:
        if not fs.isOpened():
            return None
        names = ("format_version", "camera_matrix", "projection_matrix", "M1", "D1", "M2",
                 "D2", "R", "T", "Q", "P1", "P2")
        return {n for n in names if not fs.getNode(n).empty()}
    except (cv2.error, SystemError):
        return None
    finally:
        fs.release()


_SIDE = re.compile(r"(left|right)", re.IGNORECASE)


def ros_partner(path: Path) -> Path | None:
    """right.yaml beside left.yaml (and the other way round, keeping prefixes and case)."""
    found = None
    for m in _SIDE.finditer(path.stem):
        found = m  # the last "left"/"right" in the name
    if found is None:
        return None
    word = found.group(1)
    other = "right" if word.lower() == "left" else "left"
    other = other.upper() if word.isupper() else other.capitalize() if word[0].isupper() else other
    name = path.stem[:found.start()] + other + path.stem[found.end():]
    for suffix in dict.fromkeys((path.suffix, ".yaml", ".yml")):
        candidate = path.with_name(name + suffix)
        if candidate.is_file():
            return candidate
    return None


def _load_ros(path: Path) -> LoadedCalibration:
    other = ros_partner(path)
    if other is None:
        raise CalibrationFileError(
            f"{path} is one ROS camera_info file; the other camera's file (left.yaml next to "
            "right.yaml, or the same name with left and right swapped) was not found beside it")
    # the right camera's projection has the baseline term; names can lie, matrices do not
    left, right = (path, other) if _is_left_ros(path, other) else (other, path)
    calib = import_ros(left, right)
    return LoadedCalibration(calib, path, "ros", (left, right),
                             f"ROS camera_info {left.name} + {right.name}")


def _is_left_ros(a: Path, b: Path) -> bool:
    def tx(p: Path) -> float:
        try:
            fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
        except (cv2.error, SystemError):
            return 0.0  # import_ros then says what is wrong with it
        try:
            data = fs.getNode("projection_matrix").getNode("data")
            return abs(data.at(3).real()) if data.isSeq() and data.size() == 12 else 0.0
        except (cv2.error, SystemError):
            return 0.0
        finally:
            fs.release()

    ta, tb = tx(a), tx(b)
    if ta == tb:
        return "left" in a.name.lower()
    return ta < tb


def _load_robotics(path: Path) -> LoadedCalibration | None:
    """A Kalibr camchain or a EuRoC sensor.yaml pair, or None when `path` is neither."""
    if kalibr.looks_like_kalibr(path):
        got, kind, what = kalibr.read_kalibr_camchain(path), "kalibr", "Kalibr camchain"
    elif kalibr.looks_like_euroc(path):
        got, kind, what = kalibr.read_euroc_pair(path), "euroc", "EuRoC"
    else:
        return None
    calib = got.calibration
    check_plausible(calib, " + ".join(map(str, got.files)))
    files = " + ".join(f"{p.parent.name}/{p.name}" if kind == "euroc" else p.name
                       for p in got.files)
    return LoadedCalibration(calib, path, kind, got.files,
                             f"{what} {files} (pinhole-{got.distortion_model}, image size "
                             f"{_size_text(calib.image_size)}, baseline "
                             f"{calib.baseline_mm:.1f} mm)")


def load_any_calibration(spec: str | Path, image_size: SizeHint = None) -> LoadedCalibration:
    """Open `spec` (see the module's doc); `image_size` is used when the file holds none."""
    try:
        return _load_any(spec, image_size)
    except UnicodeDecodeError as exc:  # OpenCV hands back bytes of a text field as they are
        raise CalibrationFileError(f"{spec} holds text that is not UTF-8 (byte "
                                   f"0x{exc.object[exc.start]:02x}): it is damaged or not a "
                                   "calibration") from None


def _load_any(spec: str | Path, image_size: SizeHint) -> LoadedCalibration:
    if rect.is_rectified_spec(spec):
        parsed = rect.parse_rectified_spec(str(spec))
        image_size = resolve_size(image_size)
        if image_size is None:
            raise CalibrationFileError(f"{spec}: the image size is needed (it comes from the "
                                       "LEFT image or the source)")
        calib = parsed.calibration(image_size)
        extra = f", doffs {parsed.doffs_px:g} px" if parsed.doffs_px else ""
        return LoadedCalibration(calib, None, "rectified", (),
                                 f"rectified pair: f {parsed.focal_px:g} px, baseline "
                                 f"{parsed.baseline_mm:g} mm{extra}")
    path = Path(spec).expanduser()
    if path.is_dir():
        raise CalibrationFileError(f"{path} is a folder: give the calibration file in it")
    if path.is_file() and rect.looks_like_middlebury(path):
        calib = rect.read_middlebury(path, image_size)
        return LoadedCalibration(calib, path, "middlebury", (path,),
                                 f"Middlebury {path.name}: f {calib.focal_px:g} px, baseline "
                                 f"{calib.rectified_baseline_mm:g} mm, doffs "
                                 f"{calib.disparity_offset_px:g} px")
    robotics = _load_robotics(path) if path.is_file() else None
    if robotics is not None:
        return robotics
    names = _peek(path) if path.is_file() else None
    if names is None or "format_version" in names:
        # ours, or nothing OpenCV can read: our loader says exactly what is wrong
        return LoadedCalibration(load_calibration(path), path, "stereo-gui", (path,),
                                 path.name)
    if {"camera_matrix", "projection_matrix"} <= names:
        return _load_ros(path)
    if names & {"M1", "D1", "M2", "D2", "R", "T"}:
        got = read_opencv_stereo(path, image_size)
        check_plausible(got.calibration, " + ".join(map(str, got.files)))
        size = got.calibration.image_size
        how = "from the file" if got.size_from_file else "from the images or source"
        files = " + ".join(p.name for p in got.files)
        computed = f", computed {' '.join(got.computed)}" if got.computed else ""
        return LoadedCalibration(got.calibration, path, "opencv", got.files,
                                 f"OpenCV stereo calibration {files} (image size "
                                 f"{_size_text(size)} {how}{computed})")
    raise CalibrationFileError(
        f"{path} is not a calibration stereo-gui can read: it holds neither stereo-gui's "
        "format_version, OpenCV's stereo sample matrices (M1 D1 M2 D2 R T), a ROS "
        "camera_info (camera_matrix, projection_matrix), a Kalibr camchain (cam0, cam1) nor a "
        "EuRoC sensor.yaml (T_BS, intrinsics)")
