"""Calibrations of pairs that are already rectified: `rectified:F,B[,DOFFS]` and Middlebury 2014's
`calib.txt`.

Both become `StereoCalibration.identity` (no remapping): focal length F px, baseline B mm and
DOFFS = cx_right - cx_left px, the offset between the two principal points that stereo cameras
and benchmarks have, so that Z = f B / (d + doffs).

Middlebury's calib.txt (https://vision.middlebury.edu/stereo/data/scenes2014/) holds lines such as
``cam0=[3997.684 0 1176.728; 0 3997.684 1011.728; 0 0 1]``, ``doffs=131.111``,
``baseline=193.001`` (mm), ``width=2964``, ``height=1988``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereo_gui.core.errors import CalibrationFileError, InputError
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.opencv_calibration import SizeHint, resolve_size

PREFIX = "rectified:"
FORM = ("rectified:F,B or rectified:F,B,DOFFS (focal length F in px, baseline B in mm, and "
        "DOFFS = cx_right - cx_left in px when the principal points differ), for example "
        "rectified:700,110 or rectified:3997.7,193.0,131.1")
# bounds that keep f*B, f/d and the matcher's disparity range finite and meaningful
_F_RANGE = (1e-3, 1e7)  # px
_B_RANGE = (1e-3, 1e7)  # mm
# px: the matcher's disparities (OpenCV's 16-bit fixed point, 1/16 px) reach 2047 px at most,
# and the disparity of a point is f B / Z - DOFFS; Middlebury 2014's full-size scenes have 0-300
_DOFFS_LIMIT = 1024.0


@dataclass(frozen=True)
class RectifiedSpec:
    """A parsed `rectified:` spec: focal length px, baseline mm, principal point offset px."""

    focal_px: float
    baseline_mm: float
    doffs_px: float = 0.0

    def calibration(self, image_size: tuple[int, int]) -> StereoCalibration:
        """The identity calibration of images of `image_size` (width, height) px."""
        return StereoCalibration.identity(image_size, self.focal_px, self.baseline_mm,
                                          doffs_px=self.doffs_px)


def is_rectified_spec(spec: str | Path) -> bool:
    return isinstance(spec, str) and spec.strip().lower().startswith(PREFIX)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def parse_rectified_spec(spec: str) -> RectifiedSpec:
    """Parse `rectified:F,B[,DOFFS]`; InputError saying what the form is for anything else."""
    body = spec.strip()[len(PREFIX):]
    parts = [p.strip() for p in body.split(",")]
    if len(parts) not in (2, 3) or not all(parts):
        raise InputError(f"{spec!r}: give {FORM}")
    values = [_number(p) for p in parts]
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{spec!r}: F, B and DOFFS must be numbers; give {FORM}")
    f, b = values[0], values[1]
    doffs = values[2] if len(values) == 3 else 0.0
    problem = _out_of_range(f, b, doffs)
    if problem:
        raise InputError(f"{spec!r}: {problem}")
    return RectifiedSpec(f, b, doffs)


def _out_of_range(f: float, b: float, doffs: float) -> str:
    """What is wrong with these values ("" when nothing)."""
    if not _F_RANGE[0] <= f <= _F_RANGE[1]:
        return f"the focal length F must be a positive number of pixels up to {_F_RANGE[1]:g}, " \
               f"not {f:g}"
    if not _B_RANGE[0] <= b <= _B_RANGE[1]:
        return f"the baseline B must be a positive number of millimetres up to " \
               f"{_B_RANGE[1]:g}, not {b:g}"
    if not abs(doffs) <= _DOFFS_LIMIT:
        return (f"DOFFS = cx_right - cx_left of {doffs:g} px is not a principal point offset a "
                f"matcher can search with (at most {_DOFFS_LIMIT:g} px either way)")
    return ""


# ---- Middlebury 2014 ---------------------------------------------------------------------------
_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")


def looks_like_middlebury(path: Path) -> bool:
    """True for a text file whose lines include cam0=[...] (Middlebury's calib.txt)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return re.search(rb"^\s*cam0\s*=\s*\[", head, re.MULTILINE) is not None


def _camera(text: str, key: str, where: Path) -> np.ndarray:
    inner = text.strip()
    if not (inner.startswith("[") and inner.endswith("]")):
        raise CalibrationFileError(f"{where}: {key} should be a matrix like "
                                   "[f 0 cx; 0 f cy; 0 0 1]")
    rows = [r.split() for r in inner[1:-1].split(";")]
    try:
        m = np.array([[float(v) for v in r] for r in rows], np.float64)
    except ValueError:
        raise CalibrationFileError(f"{where}: {key} holds something that is not a number") from None
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise CalibrationFileError(f"{where}: {key} should be a 3x3 matrix of numbers")
    return m


def read_middlebury(path: str | Path, image_size: SizeHint = None) -> StereoCalibration:
    """The calibration of a Middlebury 2014 calib.txt (its width/height when present, else
    `image_size`); CalibrationFileError naming the key that is missing or wrong."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise CalibrationFileError(f"cannot read {path}: {exc.strerror or exc}") from None
    values: dict[str, str] = {}
    for line in text.splitlines():
        m = _LINE.match(line)
        if m:
            values[m.group(1).lower()] = m.group(2)
    for key in ("cam0", "cam1", "baseline"):
        if key not in values:
            raise CalibrationFileError(f"{path}: {key}= is missing (a Middlebury calib.txt has "
                                       "cam0, cam1, doffs, baseline, width and height)")
    cam0 = _camera(values["cam0"], "cam0", path)
    cam1 = _camera(values["cam1"], "cam1", path)

    def number(key: str) -> float:
        v = _number(values[key])
        if not math.isfinite(v):
            raise CalibrationFileError(f"{path}: {key}={values[key]} is not a number")
        return v

    f, cx, cy = cam0[0, 0], cam0[0, 2], cam0[1, 2]
    if not f > 0 or abs(cam0[1, 1] - f) > 1e-6 * f or abs(cam1[0, 0] - f) > 1e-6 * f \
            or abs(cam1[1, 2] - cy) > 1e-3:
        raise CalibrationFileError(f"{path}: cam0 and cam1 are not a rectified pair (they "
                                   "should share the focal length and cy)")
    doffs = number("doffs") if "doffs" in values else float(cam1[0, 2] - cx)
    if abs(doffs - (cam1[0, 2] - cx)) > 0.5:
        raise CalibrationFileError(f"{path}: doffs={doffs:g} disagrees with the principal points "
                                   f"(cam1 cx - cam0 cx = {cam1[0, 2] - cx:g})")
    baseline = number("baseline")
    if "width" in values and "height" in values:
        w, h = number("width"), number("height")
        if not (w == int(w) and h == int(h) and w > 0 and h > 0):
            raise CalibrationFileError(f"{path}: width and height should be positive whole "
                                       "numbers")
        size = (int(w), int(h))
    elif (hint := resolve_size(image_size)) is not None:
        size = hint
    else:
        raise CalibrationFileError(f"{path} holds no width= and height=: open it together with "
                                   "images, whose size is then used")
    problem = _out_of_range(float(f), baseline, doffs)
    if problem:
        raise CalibrationFileError(f"{path}: {problem}")
    return StereoCalibration.identity(size, float(f), baseline, cx=float(cx), cy=float(cy),
                                      doffs_px=doffs)
