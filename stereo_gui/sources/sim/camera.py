"""The simulated rig's description: each camera's true intrinsics, how to build a rig, and
the rig's true parameters as cv2.stereoCalibrate names them (saved as truth.json)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_gui.core import lens
from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.core.lens import LensModel
from stereo_gui.files.readers import read_json_object

TRUTH_FORMAT_VERSION = 1


@dataclass(frozen=True, eq=False)
class CameraTruth:
    """One camera's true intrinsics: M (3x3 float64, px) and D (1xN float64) of lens `model`
    (core.lens: "pinhole" k1 k2 p1 p2 k3, "rational" 8 coefficients, "fisheye" k1..k4)."""

    M: np.ndarray
    D: np.ndarray
    model: LensModel = "pinhole"

    def __post_init__(self) -> None:
        lens.check_model(self.model)
        object.__setattr__(self, "M", np.asarray(self.M, np.float64).reshape(3, 3))
        D = np.asarray(self.D, np.float64).reshape(1, -1)
        count = lens.DIST_COUNT[self.model]
        if D.shape[1] != count:
            raise InputError(f"a {self.model} camera needs {count} distortion "
                             f"coefficients, not {D.shape[1]}")
        object.__setattr__(self, "D", D)

    @staticmethod
    def make(fx: float, fy: float, cx: float, cy: float,
             k1: float = 0.0, k2: float = 0.0, p1: float = 0.0, p2: float = 0.0,
             k3: float = 0.0) -> CameraTruth:
        M = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return CameraTruth(M, np.array([[k1, k2, p1, p2, k3]]))

    @staticmethod
    def make_fisheye(fx: float, fy: float, cx: float, cy: float, k1: float = 0.0,
                     k2: float = 0.0, k3: float = 0.0, k4: float = 0.0) -> CameraTruth:
        M = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return CameraTruth(M, np.array([[k1, k2, k3, k4]]), "fisheye")


def _default_left() -> CameraTruth:
    return CameraTruth.make(752.0, 748.5, 323.6, 237.2, k1=-0.182, k2=0.061, p1=1.1e-3,
                            p2=-6.0e-4, k3=-0.012)


def _default_right() -> CameraTruth:
    return CameraTruth.make(745.3, 742.8, 316.1, 243.4, k1=-0.214, k2=0.083, p1=-7.5e-4,
                            p2=1.25e-3, k3=-0.021)


def _fisheye_left() -> CameraTruth:
    # a wide-angle webcam: about 100 degrees across the 640 px width
    return CameraTruth.make_fisheye(368.0, 367.1, 322.4, 238.3, k1=0.021, k2=-0.013, k3=0.004,
                                    k4=-0.0011)


def _fisheye_right() -> CameraTruth:
    return CameraTruth.make_fisheye(365.6, 364.9, 317.2, 242.6, k1=0.017, k2=-0.009, k3=0.0028,
                                    k4=-0.0008)


@dataclass(frozen=True)
class RigConfig:
    """How to build a simulated rig. Angles in radians, lengths in mm, noise in grey levels."""

    image_size: tuple[int, int] = (640, 480)  # (width, height), px
    left: CameraTruth = field(default_factory=_default_left)
    right: CameraTruth = field(default_factory=_default_right)
    # R_right_left as a Rodrigues vector: about 0.8 degrees in total
    rvec_right_left: tuple[float, float, float] = (0.0061, -0.0118, 0.0042)
    baseline_mm: float = 110.0
    # direction of T_right_left; scaled so that |T| = baseline_mm
    t_direction: tuple[float, float, float] = (-1.0, 0.0065, -0.0085)
    noise_sigma: float = 2.0  # sensor noise, grey levels (standard deviation)
    gain_right: float = 0.93  # the right camera is a little darker
    # what two cheap webcams add (all off by default): the right camera's own black level (grey
    # levels added after its gain), darker corners (the share of brightness lost in the image
    # corners, falling off with the squared distance from the centre) and MJPG compression
    # (each frame JPEG-encoded at this quality and decoded, as a USB webcam sends it)
    black_right: float = 0.0
    vignetting: float = 0.0
    jpeg_quality: int | None = None
    # the right camera takes its picture this long after the left (s): two webcams are not
    # synchronised, and a moving board is seen at two moments
    time_offset_s: float = 0.0
    # the cameras start as webcams do, in their automatic modes (autofocus, exposure, white
    # balance: sim/controls.py); off, they hold the values the rig's truth was made with
    auto_modes: bool = False
    board: BoardSpec = field(default_factory=BoardSpec)
    supersample: int = 3  # samples per pixel along each axis (anti-aliasing)

    @property
    def model(self) -> LensModel:
        """The lens model of both cameras."""
        return self.left.model

    def __post_init__(self) -> None:
        if self.left.model != self.right.model:
            raise InputError("both cameras of the simulated rig need the same lens model")
        if not 0.0 <= self.vignetting < 1.0:
            raise InputError(f"vignetting must be from 0 to below 1, not {self.vignetting}")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            raise InputError(f"JPEG quality must be from 1 to 100, not {self.jpeg_quality}")
        if not -1.0 < self.time_offset_s < 1.0:
            raise InputError(f"the time offset must be under a second, not {self.time_offset_s}")
        if not -255.0 <= self.black_right <= 255.0:
            raise InputError(f"black level must be from -255 to 255, not {self.black_right}")

    @staticmethod
    def fisheye(**changes: Any) -> RigConfig:
        """A rig of two wide-angle (fisheye) webcams, 110 mm apart."""
        return RigConfig(left=_fisheye_left(), right=_fisheye_right(), **changes)

    @staticmethod
    def for_size(size: tuple[int, int]) -> RigConfig:
        """The default rig at another resolution: the same horizontal field of view (camera
        matrices scaled by width/640, principal points kept at the same place relative to the
        centre); fewer supersamples above 640x480 to keep rendering fast."""
        w, h = int(size[0]), int(size[1])
        base = RigConfig()
        if (w, h) == base.image_size:
            return base
        if w < 64 or h < 48:
            raise InputError(f"the simulated rig needs at least 64x48 pixels, not {w}x{h}")
        k = w / base.image_size[0]

        def scaled(cam: CameraTruth) -> CameraTruth:
            M = cam.M.copy()
            M[:2, :2] *= k
            M[0, 2] = (M[0, 2] - (base.image_size[0] - 1) / 2) * k + (w - 1) / 2
            M[1, 2] = (M[1, 2] - (base.image_size[1] - 1) / 2) * k + (h - 1) / 2
            return CameraTruth(M, cam.D.copy(), cam.model)

        return RigConfig(image_size=(w, h), left=scaled(base.left), right=scaled(base.right),
                         supersample=3 if w * h <= 640 * 480 else 2)


@dataclass(frozen=True, eq=False)
class RigTruth:
    """The rig's true parameters, named as cv2.stereoCalibrate returns them (T in mm)."""

    image_size: tuple[int, int]
    M1: np.ndarray
    D1: np.ndarray
    M2: np.ndarray
    D2: np.ndarray
    R: np.ndarray  # R_right_left
    T: np.ndarray  # T_right_left, 3x1, mm
    board: BoardSpec
    model: LensModel = "pinhole"  # lens model of both cameras (core.lens)

    @property
    def baseline_mm(self) -> float:
        return float(np.linalg.norm(self.T))

    @property
    def relative_rotation_deg(self) -> float:
        rvec, _ = cv2.Rodrigues(self.R)
        return float(np.degrees(np.linalg.norm(rvec)))

    def to_json(self) -> dict[str, Any]:
        return {
            "format_version": TRUTH_FORMAT_VERSION,
            "image_size": [int(self.image_size[0]), int(self.image_size[1])],
            "M1": self.M1.tolist(), "D1": self.D1.reshape(-1).tolist(),
            "M2": self.M2.tolist(), "D2": self.D2.reshape(-1).tolist(),
            "R": self.R.tolist(), "T": self.T.reshape(-1).tolist(),
            "baseline_mm": self.baseline_mm,
            "relative_rotation_deg": self.relative_rotation_deg,
            "board": self.board.to_json(),
            "model": self.model,
        }

    @staticmethod
    def from_json(data: dict[str, Any], where: str = "rig truth") -> RigTruth:
        """The truth `to_json` wrote; InputError naming `where` and the field when a value is
        missing, of the wrong type, not finite or not what a camera can have."""
        if not isinstance(data, dict):
            raise _bad(where, "should be a JSON object")
        size = _truth_image_size(data, where)
        M1, M2 = _truth_matrix(data, "M1", (3, 3), where), _truth_matrix(data, "M2", (3, 3), where)
        for key, M in (("M1", M1), ("M2", M2)):
            if not (M[0, 0] > 0 and M[1, 1] > 0 and np.allclose(M[2], (0, 0, 1))):
                raise _bad(where, f"{key} is not a camera matrix (positive focal lengths, last "
                           "row 0 0 1)")
        D1, D2 = _truth_distortion(data, "D1", where), _truth_distortion(data, "D2", where)
        R = _truth_matrix(data, "R", (3, 3), where)
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
            raise _bad(where, "R is not a rotation")
        T = _truth_matrix(data, "T", (3,), where).reshape(3, 1)
        if not np.linalg.norm(T) > 0:
            raise _bad(where, "T is zero: the cameras would be at the same place")
        board = _truth_board(data.get("board"), where)
        model = data.get("model", "pinhole")
        if model not in ("pinhole", "rational", "fisheye"):
            raise _bad(where, f"model should be pinhole, rational or fisheye, not {model!r:.40}")
        return RigTruth(image_size=size, M1=M1, D1=D1, M2=M2, D2=D2, R=R, T=T, board=board,
                        model=model)


# ---- reading truth.json: each part checked, InputError naming the file and the field ------------
def _bad(where: str, text: str) -> InputError:
    return InputError(f"{where}: {text}")


def _truth_matrix(data: dict[str, Any], key: str, shape: tuple[int, ...], where: str
                  ) -> np.ndarray:
    """data[key] as a finite float64 array of `shape` (given as nested or flat lists)."""
    raw = data.get(key)
    try:
        m = np.array(raw, np.float64)
    except (TypeError, ValueError, OverflowError):
        raise _bad(where, f"{key} should be a list of numbers") from None
    if m.size != int(np.prod(shape)) or (m.ndim != len(shape) and m.ndim != 1):
        raise _bad(where, f"{key} should be {'x'.join(map(str, shape))} numbers")
    m = m.reshape(shape)
    if not np.all(np.isfinite(m)) or np.max(np.abs(m)) > 1e7:
        raise _bad(where, f"{key} holds values that are not finite or absurd")
    return m


def _truth_image_size(data: dict[str, Any], where: str) -> tuple[int, int]:
    size = data.get("image_size")
    if not (isinstance(size, list) and len(size) == 2 and all(
            isinstance(v, int) and not isinstance(v, bool) and 0 < v <= 100_000
            for v in size)):
        raise _bad(where, f"image_size should be [width, height] in px, not {size!r:.60}")
    return size[0], size[1]


def _truth_distortion(data: dict[str, Any], key: str, where: str) -> np.ndarray:
    """A lens's distortion coefficients, 1xN (N one of OpenCV's counts)."""
    raw = data.get(key)
    n = len(raw) if isinstance(raw, list) else -1
    if n not in (4, 5, 8, 12, 14):
        raise _bad(where, f"{key} should have 4, 5, 8, 12 or 14 coefficients")
    return _truth_matrix(data, key, (n,), where).reshape(1, -1)


def _truth_board(b: object, where: str) -> BoardSpec:
    if not isinstance(b, dict):
        raise _bad(where, "board should be an object with cols, rows, square_mm")
    cols, rows, sq = b.get("cols"), b.get("rows"), b.get("square_mm")
    if not (isinstance(cols, int) and isinstance(rows, int) and not isinstance(cols, bool)
            and not isinstance(rows, bool) and isinstance(sq, int | float)
            and not isinstance(sq, bool)):
        raise _bad(where, "board cols and rows should be whole numbers and square_mm a number")
    target = b.get("target", "chessboard")
    marker = b.get("marker_mm", 0.0)
    dictionary = b.get("dictionary", BoardSpec().dictionary)
    if not (isinstance(target, str) and isinstance(dictionary, str)
            and isinstance(marker, int | float) and not isinstance(marker, bool)):
        raise _bad(where, "board target and dictionary should be text and marker_mm a number")
    try:
        return BoardSpec(cols, rows, float(sq), target, float(marker), dictionary)
    except InputError as exc:
        raise _bad(where, f"board: {exc}") from None


def load_truth(path: str | Path) -> RigTruth:
    """The rig truth of a `truth.json` written by `write_calibration_set` (or its folder)."""
    path = Path(path)
    if path.is_dir():
        path = path / "truth.json"
    return RigTruth.from_json(read_json_object(path, "rig truth"), where=str(path))


