"""The result of a stereo calibration: what every later step (rectify, match, measure) needs.

Names follow OpenCV's stereo sample (M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q). Frames and units:
- M1/D1 is the left camera, M2/D2 the right; pixels.
- R, T take a point from the left camera frame to the right camera frame (R_right_left,
  T_right_left); T is in millimetres.
- R1/R2 rotate the left/right camera frames into the rectified frames; P1/P2 project rectified
  points (mm) to rectified pixels; Q maps (x, y, disparity px, 1) to homogeneous (X, Y, Z, W) in mm
  in the left rectified camera frame.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any, Literal, NoReturn, get_args

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.camera_settings import PairSettings
from stereo_gui.core.errors import CalibrationError, CalibrationFileError, CalibrationValueError
from stereo_gui.core.lens import LENS_MODELS, LensModel, rectify_map, undistort_points
from stereo_gui.core.params import Param, param, params_of
from stereo_gui.core.shading import PairShading
from stereo_gui.core.uncertainty import CalibrationUncertainty, CalibrationWarning


@dataclass(frozen=True)
class PairError:
    """Mean reprojection error of one calibration pair, pixels, per camera (finite, >= 0)."""

    name: str
    error_left: float
    error_right: float

    def __post_init__(self) -> None:
        for side, value in (("error_left", self.error_left), ("error_right", self.error_right)):
            v = _as_float(value)
            if not (math.isfinite(v) and v >= 0):
                _refuse(f"pair {self.name}: {side} is {v:g}; it must be a finite number of "
                        "pixels >= 0")
            object.__setattr__(self, side, v)


@dataclass(frozen=True)
class RectifyMaps:
    """Maps for cv2.remap of left and right raw images into rectified images (fixed-point)."""

    left_x: np.ndarray
    left_y: np.ndarray
    right_x: np.ndarray
    right_y: np.ndarray
    size: tuple[int, int]  # (width, height) of the rectified images, px


# how the rectification was found: Bouguet's, Hartley's (no metric scale), or none for pairs
# that are already rectified; written to files as these words
Method = Literal["bouguet", "hartley", "identity"]
METHODS: tuple[Method, ...] = get_args(Method)
# the matrices in the order of OpenCV's stereo sample (and of our files)
MATRIX_NAMES = ("M1", "D1", "M2", "D2", "R", "T", "E", "F", "R1", "R2", "P1", "P2", "Q")


@dataclass(frozen=True, eq=False)
class StereoCalibration:
    """A stereo calibration. Arrays are float64 and read-only; T and distances are in millimetres.

    It checks itself on construction (CalibrationValueError names the field): matrices of the
    right shapes holding finite values, positive focal lengths, a rotation R, a baseline, a
    known method and lens model, quality figures >= 0, an uncertainty over this calibration's
    own parameters. Whether the whole is a rig that could exist (focal lengths for a lens, P1,
    P2, Q, E and F that follow from the rest) is `core.plausibility.check_plausible`.
    """

    image_size: tuple[int, int]  # (width, height), px
    M1: np.ndarray  # 3x3 left camera matrix
    D1: np.ndarray  # 1xN left distortion (k1 k2 p1 p2 k3 ...)
    M2: np.ndarray  # 3x3 right camera matrix
    D2: np.ndarray  # 1xN right distortion
    R: np.ndarray  # 3x3, R_right_left
    T: np.ndarray  # 3x1, T_right_left, mm
    E: np.ndarray  # 3x3 essential matrix
    F: np.ndarray  # 3x3 fundamental matrix
    R1: np.ndarray  # 3x3 left rectification rotation
    R2: np.ndarray  # 3x3 right rectification rotation
    P1: np.ndarray  # 3x4 left rectified projection
    P2: np.ndarray  # 3x4 right rectified projection
    Q: np.ndarray  # 4x4 disparity-to-depth
    board: BoardSpec | None = None
    rms_left: float = float("nan")
    rms_right: float = float("nan")
    rms_stereo: float = float("nan")
    epipolar_error_px: float = float("nan")
    per_pair: tuple[PairError, ...] = ()
    method: Method = "bouguet"
    alpha: float = param(0.0, lo=0.0, hi=1.0,
                         help="stereoRectify's free scaling: 0 keeps only valid pixels (zoomed "
                              "in), 1 keeps every pixel")
    optimal_M1: np.ndarray | None = None  # getOptimalNewCameraMatrix(alpha=1), as the reference program shows it
    optimal_M2: np.ndarray | None = None
    created: str = field(default_factory=lambda: _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    # (width, height) the calibration was made at when it was scaled to image_size by scaled_to();
    # the RMS figures and per-pair errors stay in pixels of that original size
    scaled_from: tuple[int, int] | None = None
    model: LensModel = "pinhole"  # lens model of both cameras (core.lens)
    uncertainty: CalibrationUncertainty | None = None  # 1 sigma
    # how it was made ("calibrated from 20 pairs ...", "refined from the scene ...")
    origin: str = ""
    warnings: tuple[CalibrationWarning, ...] = ()  # found when it was made
    # made from pairs whose left and right images were exchanged (the cameras were found
    # swapped): frames from the same source must be exchanged before they are rectified
    swapped_inputs: bool = False
    # (pair name, why) of the pairs it was not made from: rejected when it was made (no board
    # in both images, an outlier) or excluded by the technician
    left_out: tuple[tuple[str, str], ...] = ()
    # the cameras' controls (focus, exposure...) when the pairs were captured, as this
    # calibration names the cameras; None when not known
    camera_controls: PairSettings | None = None
    # how much darker each camera's corners are, measured on the white squares of the pairs
    # (undone before matching); None when not measured
    lens_shading: PairShading | None = None

    def __post_init__(self) -> None:
        with np.errstate(all="ignore"):  # absurd values overflow on their way to being refused
            self._check()

    def _check(self) -> None:
        matrices = self.matrices()
        check_matrices(matrices)
        for name, m in matrices.items():
            object.__setattr__(self, name, _read_only(m))
        w, h = self.image_size
        check_image_size(w, h)
        object.__setattr__(self, "image_size", (int(w), int(h)))
        if self.scaled_from is not None:
            sw, sh = self.scaled_from
            check_image_size(sw, sh, "scaled_from size")
            object.__setattr__(self, "scaled_from", (int(sw), int(sh)))
            if sw * self.height != sh * self.width:
                _refuse(f"scaled_from size {sw}x{sh} does not have the aspect ratio of "
                        f"{self.width}x{self.height}")
        check_camera_matrix(self.M1, "M1")
        check_camera_matrix(self.M2, "M2")
        self._check_lens_model()
        for name, D in (("D1", self.D1), ("D2", self.D2)):
            if np.max(np.abs(D)) > MAX_DISTORTION:
                _refuse(f"distortion {name} holds coefficients above {MAX_DISTORTION:g}")
        self._check_geometry()
        if self.method not in METHODS:
            _refuse(f"unknown method {self.method!r}")
        alpha = _as_float(self.alpha)
        if (why := alpha_problem(alpha)) is not None:
            _refuse(why)
        object.__setattr__(self, "alpha", alpha)
        self._check_figures()
        for name, opt in (("optimal_M1", self.optimal_M1), ("optimal_M2", self.optimal_M2)):
            if opt is not None:
                if np.shape(opt) != (3, 3) or not np.all(np.isfinite(opt)):
                    _refuse(f"matrix {name} should be a finite 3x3")
                object.__setattr__(self, name, _read_only(opt))
        if self.uncertainty is not None:
            if self.uncertainty.model != self.model:
                _refuse(f"the uncertainty is of {self.uncertainty.model} lenses, the "
                        f"calibration of {self.model} lenses")
            self.uncertainty.check_parameters(self.D1.size)

    def _check_lens_model(self) -> None:
        d1, d2 = self.D1.size, self.D2.size
        if self.model not in LENS_MODELS:
            _refuse(f"unknown lens model {self.model!r} (use one of {', '.join(LENS_MODELS)})")
        if self.model == "fisheye" and (d1 != 4 or d2 != 4):
            _refuse(f"a fisheye calibration needs 4 distortion coefficients per camera, found "
                    f"{d1} and {d2}")
        if d1 != d2:
            _refuse(f"distortion D1 has {d1} coefficients and D2 {d2}: both cameras of a "
                    "calibration have the same lens model")

    def _check_geometry(self) -> None:
        R = self.R
        # (as loose as the plausibility check: a rotation written by hand or by another tool to
        # four decimals is still one)
        tol = ROTATION_TOL
        if np.max(np.abs(R)) > 1.0 + tol or not (
                np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1) < tol):
            _refuse("matrix R is not a rotation")
        baseline = self.baseline_mm
        if not 0 < baseline <= MAX_BASELINE_MM:
            _refuse(f"T gives a baseline of {baseline:g} mm (it must be positive and at most "
                    f"{MAX_BASELINE_MM:g} mm)")
        for name, m in (("R1", self.R1), ("R2", self.R2)):
            if not abs(np.linalg.det(m)) > 1e-9:
                _refuse(f"matrix {name} is singular: it cannot rectify")
        check_projection_focal(self.P1, "P1")
        check_projection_focal(self.P2, "P2")
        if self.P2[0, 3] == 0 and self.P2[1, 3] == 0:
            _refuse("matrix P2 has no baseline term (P2[0,3] and P2[1,3] are zero)")
        if self.Q[2, 3] == 0 or self.Q[3, 2] == 0:
            _refuse("matrix Q cannot turn disparities into distances (Q[2,3] or Q[3,2] is 0)")

    def _check_figures(self) -> None:
        """NaN quality figures mean "not known" where a calibration legitimately has none (an
        imported or already-rectified calibration has no per-pair record; Hartley's method has
        no stereo RMS); anywhere else they are refused."""
        unknown_ok = not self.per_pair
        for name, value in (("rms_left", self.rms_left), ("rms_right", self.rms_right),
                            ("rms_stereo", self.rms_stereo),
                            ("epipolar_error_px", self.epipolar_error_px)):
            v = _as_float(value)
            object.__setattr__(self, name, v)
            if math.isnan(v):
                if unknown_ok or (name == "rms_stereo" and self.method == "hartley"):
                    continue
                _refuse(f"{name} is not a number")
            if not (math.isfinite(v) and v >= 0):
                _refuse(f"{name} is {v:g}; it must be a finite number of pixels >= 0")

    def matrices(self) -> dict[str, np.ndarray]:
        """The matrices M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q by name, in that order."""
        return {"M1": self.M1, "D1": self.D1, "M2": self.M2, "D2": self.D2, "R": self.R,
                "T": self.T, "E": self.E, "F": self.F, "R1": self.R1, "R2": self.R2,
                "P1": self.P1, "P2": self.P2, "Q": self.Q}

    def ordered(self, left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A source's (left, right) images in the order this calibration expects."""
        return (right, left) if self.swapped_inputs else (left, right)

    # ---- derived figures -------------------------------------------------------------------
    @property
    def width(self) -> int:
        return int(self.image_size[0])

    @property
    def height(self) -> int:
        return int(self.image_size[1])

    @property
    def baseline_mm(self) -> float:
        """Distance between the two camera centres, mm."""
        return float(np.linalg.norm(self.T))

    @property
    def relative_rotation_deg(self) -> float:
        """Angle of the rotation between the two cameras, degrees."""
        rvec, _ = cv2.Rodrigues(np.asarray(self.R, np.float64))
        return float(np.degrees(np.linalg.norm(rvec)))

    @property
    def focal_px(self) -> float:
        """Focal length of the rectified cameras, px."""
        return float(self.P1[0, 0])

    @property
    def rectified_baseline_mm(self) -> float:
        """Baseline along the rectified x axis, mm (positive), from P2."""
        return float(abs(self.P2[0, 3] / self.P2[0, 0]))

    @property
    def metric(self) -> bool:
        """True when distances come out in millimetres (not so for Hartley's method)."""
        return self.method != "hartley"

    # ---- use -------------------------------------------------------------------------------
    def rectify_maps(self) -> RectifyMaps:
        """Rectification maps for both cameras at the calibration's image size."""
        size = (self.width, self.height)
        lx, ly = rectify_map(self.model, self.M1, self.D1, self.R1, self.P1, size, cv2.CV_16SC2)
        rx, ry = rectify_map(self.model, self.M2, self.D2, self.R2, self.P2, size, cv2.CV_16SC2)
        return RectifyMaps(lx, ly, rx, ry, size)

    def rectify_points(self, side: str, pts: np.ndarray) -> np.ndarray:
        """Raw pixels (N, 2) of one camera ("left" or "right") -> rectified pixels (N, 2)."""
        M, D, R, P = ((self.M1, self.D1, self.R1, self.P1) if side == "left"
                      else (self.M2, self.D2, self.R2, self.P2))
        return undistort_points(self.model, pts, M, D, R=R, P=P)

    def with_updates(self, **changes: Any) -> StereoCalibration:
        return replace(self, **changes)

    def scaled_to(self, new_size: tuple[int, int]) -> StereoCalibration:
        """This calibration for images resized to `new_size` (width, height) px.

        Only a uniform scale is meaningful (the same lenses seen through a resized sensor), so
        the aspect ratio must stay the same; otherwise CalibrationError says why. Pixel
        coordinates follow OpenCV's convention (pixel centres at integers): c' = (c + 0.5) s - 0.5.
        R, T, D, R1, R2 and E do not change; M, P, Q and F do.
        """
        w, h = self.width, self.height
        nw, nh = int(new_size[0]), int(new_size[1])
        if nw <= 0 or nh <= 0:
            raise CalibrationError(f"cannot scale a calibration to {nw}x{nh}")
        if (nw, nh) == (w, h):
            return self
        if w * nh != nw * h:
            raise CalibrationError(
                f"the calibration was made at {w}x{h} and cannot be used at {nw}x{nh}: the aspect "
                f"ratios differ ({w / h:.4f} vs {nw / nh:.4f}), so the cameras were cropped, not "
                f"scaled; calibrate again at {nw}x{nh}")
        s = nw / w
        o = 0.5 * (s - 1.0)  # c' = s c + o

        def cam(M: np.ndarray) -> np.ndarray:
            M = np.array(M, np.float64)
            M[0, 0] *= s
            M[1, 1] *= s
            M[0, 1] *= s
            M[0, 2] = M[0, 2] * s + o
            M[1, 2] = M[1, 2] * s + o
            return M

        def proj(P: np.ndarray) -> np.ndarray:
            P = np.array(P, np.float64)
            P[:2, :] *= s  # rows x and y of a projection: focal, centre and the Tx*f term
            P[:2, :] += o * P[2:3, :]
            return P

        Q = np.array(self.Q, np.float64)
        Q[0, 3] = Q[0, 3] * s - o  # -cx
        Q[1, 3] = Q[1, 3] * s - o  # -cy
        Q[2, 3] *= s  # f
        Q[3, 3] *= s  # (cx1 - cx2) / Tx: disparities scale with s
        S_inv = np.linalg.inv(np.array([[s, 0, o], [0, s, o], [0, 0, 1.0]]))
        F = S_inv.T @ np.asarray(self.F, np.float64) @ S_inv
        original = self.scaled_from or (w, h)
        unc = self.uncertainty.scaled(s) if self.uncertainty is not None else None
        return replace(self, image_size=(nw, nh), M1=cam(self.M1), M2=cam(self.M2), uncertainty=unc,
                       P1=proj(self.P1), P2=proj(self.P2), Q=Q, F=F,
                       optimal_M1=None if self.optimal_M1 is None else cam(self.optimal_M1),
                       optimal_M2=None if self.optimal_M2 is None else cam(self.optimal_M2),
                       scaled_from=None if original == (nw, nh) else original)

    @property
    def disparity_offset_px(self) -> float:
        """doffs = cx_right - cx_left of the rectified cameras, px: Z = f B / (d + doffs).

        Zero for our own calibrations (CALIB_ZERO_DISPARITY); other stereo cameras and
        benchmarks (Middlebury's `doffs`) have one. Read from Q, which triangulation uses.
        """
        q32 = float(self.Q[3, 2])
        return float(self.Q[3, 3]) / q32 if q32 else 0.0

    @staticmethod
    def identity(image_size: tuple[int, int], focal_px: float, baseline_mm: float,
                 cx: float | None = None, cy: float | None = None,
                 doffs_px: float = 0.0) -> StereoCalibration:
        """A calibration for pairs that are already rectified (benchmarks): maps are the identity.

        `doffs_px` = cx_right - cx_left (Middlebury's doffs): the right camera's principal point
        lies that far right of the left one's, and Z = f B / (d + doffs).
        """
        w, h = int(image_size[0]), int(image_size[1])
        cx = (w - 1) / 2.0 if cx is None else float(cx)
        cy = (h - 1) / 2.0 if cy is None else float(cy)
        cx2 = cx + float(doffs_px)
        M = np.array([[focal_px, 0, cx], [0, focal_px, cy], [0, 0, 1]], np.float64)
        M2 = np.array([[focal_px, 0, cx2], [0, focal_px, cy], [0, 0, 1]], np.float64)
        D = np.zeros((1, 5))
        I3 = np.eye(3)
        T = np.array([[-baseline_mm], [0.0], [0.0]])
        P1 = np.hstack([M, np.zeros((3, 1))])
        P2 = np.hstack([M2, np.array([[-focal_px * baseline_mm], [0], [0]])])
        # as cv2.stereoRectify builds it: Q[3,3] = (cx1 - cx2) / Tx with Tx = -B
        Q = np.array(
            [[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, focal_px],
             [0, 0, 1.0 / baseline_mm, float(doffs_px) / baseline_mm]],
            np.float64,
        )
        tx = np.array([[0, 0, 0], [0, 0, baseline_mm], [0, -baseline_mm, 0]], np.float64)
        E = tx
        F = np.linalg.inv(M2).T @ E @ np.linalg.inv(M)
        return StereoCalibration((w, h), M, D, M2, D.copy(), I3, T, E, F, I3.copy(),
                                 I3.copy(), P1, P2, Q, method="identity")


# shapes every loaded or computed calibration must have
MATRIX_SHAPES: dict[str, tuple[int, ...]] = {
    "M1": (3, 3), "M2": (3, 3), "R": (3, 3), "T": (3, 1), "E": (3, 3), "F": (3, 3),
    "R1": (3, 3), "R2": (3, 3), "P1": (3, 4), "P2": (3, 4), "Q": (4, 4),
}
DISTORTION_COUNTS = (4, 5, 8, 12, 14)  # what OpenCV's lens models take
# beyond these no camera goes: the values are damaged
MAX_IMAGE_SIDE_PX = 100_000
MAX_FOCAL_PX = 1e7
MAX_BASELINE_MM = 1e7
ROTATION_TOL = 1e-3  # R^T R = I and det R = 1 within this
MAX_DISTORTION = 1e6


# the rectification's scaling as every caller checks it: the command line, calibrate_stereo and
# a calibration being built (a file's too)
ALPHA: Param = params_of(StereoCalibration)["alpha"]
OPENCV_DEFAULT_ALPHA = -1.0  # stereoRectify's own choice: files of OpenCV's samples hold it


def triangulate(calibration: StereoCalibration, x: float, y: float, d: float
                ) -> tuple[float, float, float] | None:
    """(X, Y, Z) mm through Q for rectified pixel (x, y) with disparity d px; None at or behind
    infinity."""
    X, Y, Z, W = np.asarray(calibration.Q, np.float64) @ np.array([x, y, d, 1.0])
    if W <= 0 or not np.isfinite(W):
        return None
    return float(X / W), float(Y / W), float(Z / W)


def alpha_problem(alpha: float) -> str | None:
    """Why `alpha` is no rectification's free scaling, or None: the declaration's range, or
    OpenCV's default (-1), which calibrations made elsewhere keep."""
    return None if alpha == OPENCV_DEFAULT_ALPHA else ALPHA.problem(alpha)


def _refuse(text: str) -> NoReturn:
    raise CalibrationValueError(text)


def _as_float(v: object) -> float:
    try:
        return float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return float("nan")


def _read_only(m: np.ndarray) -> np.ndarray:
    """A float64 copy that cannot be changed: a calibration is a value."""
    out = np.array(m, np.float64)
    out.setflags(write=False)
    return out


def check_matrices(values: Mapping[str, np.ndarray | None]) -> None:
    """Raise CalibrationValueError naming the first matrix that is missing, mis-shaped or not
    finite."""
    for name, shape in MATRIX_SHAPES.items():
        m = values.get(name)
        if m is None:
            _refuse(f"matrix {name} is missing")
        m = np.asarray(m)
        if m.shape != shape:
            got = "x".join(map(str, m.shape)) or "a scalar"
            _refuse(f"matrix {name} should be {'x'.join(map(str, shape))}, found {got}")
        if not np.all(np.isfinite(m)):
            _refuse(f"matrix {name} holds values that are not finite")
    for name in ("D1", "D2"):
        d = values.get(name)
        if d is None:
            _refuse(f"distortion {name} is missing")
        d = np.asarray(d).reshape(-1)
        if d.size not in DISTORTION_COUNTS:
            _refuse(f"distortion {name} should have 4, 5, 8, 12 or 14 coefficients, found "
                    f"{d.size}")
        if not np.all(np.isfinite(d)):
            _refuse(f"distortion {name} holds values that are not finite")


def check_image_size(w: int, h: int, what: str = "image size") -> None:
    """Raise CalibrationValueError unless w x h px is an image a camera makes."""
    if not (0 < w <= MAX_IMAGE_SIDE_PX and 0 < h <= MAX_IMAGE_SIDE_PX):
        _refuse(f"{what} {w}x{h} is not valid (1 to {MAX_IMAGE_SIDE_PX} px a side)")


def check_camera_matrix(M: np.ndarray, name: str) -> None:
    """Raise CalibrationValueError unless the 3x3 `M` is a camera matrix with positive focal
    lengths."""
    fx, fy = M[0, 0], M[1, 1]
    if not (0 < fx <= MAX_FOCAL_PX and 0 < fy <= MAX_FOCAL_PX):
        _refuse(f"matrix {name} has focal lengths {fx:g}, {fy:g} px (they must be positive and "
                f"at most {MAX_FOCAL_PX:g})")
    if not np.allclose(M[2], (0.0, 0.0, 1.0), atol=1e-9) or M[1, 0] != 0:
        _refuse(f"matrix {name} is not a camera matrix (its last row must be 0 0 1)")


def check_projection_focal(P: np.ndarray, name: str) -> None:
    """Raise CalibrationValueError unless the projection `P` has positive focal lengths."""
    if not (0 < P[0, 0] <= MAX_FOCAL_PX and 0 < P[1, 1] <= MAX_FOCAL_PX):
        _refuse(f"matrix {name} has focal lengths {P[0, 0]:g}, {P[1, 1]:g} px (they must be "
                "positive)")


def q_from_projections(P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    """The disparity-to-depth matrix of a horizontal rectified pair, as cv2.stereoRectify builds
    it (T in the units of P2's translation term)."""
    f, cx, cy = P1[0, 0], P1[0, 2], P1[1, 2]
    tx = P2[0, 3] / P2[0, 0]
    cx2 = P2[0, 2]
    return np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f],
                     [0, 0, -1.0 / tx, (cx - cx2) / tx]], np.float64)


@contextmanager
def from_file(where: str) -> Iterator[None]:
    """A calibration value refused inside (CalibrationValueError) is said as a
    CalibrationFileError naming `where` (the file it was read from)."""
    try:
        yield
    except CalibrationValueError as exc:
        raise CalibrationFileError(f"{where}: {exc}") from None
