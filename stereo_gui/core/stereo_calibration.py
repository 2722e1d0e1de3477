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
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import CalibrationFileError


@dataclass(frozen=True)
class PairError:
    """Mean reprojection error of one calibration pair, pixels, per camera."""

    name: str
    error_left: float
    error_right: float


@dataclass(frozen=True)
class RectifyMaps:
    """Maps for cv2.remap of left and right raw images into rectified images (fixed-point)."""

    left_x: np.ndarray
    left_y: np.ndarray
    right_x: np.ndarray
    right_y: np.ndarray
    size: tuple[int, int]  # (width, height) of the rectified images, px


@dataclass(frozen=True, eq=False)
class StereoCalibration:
    """A stereo calibration. Arrays are float64; T and distances are in millimetres."""

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
    method: str = "bouguet"  # "bouguet", "hartley" (no metric scale) or "identity"
    alpha: float = 0.0
    optimal_M1: np.ndarray | None = None  # getOptimalNewCameraMatrix(alpha=1), shown as in the report
    optimal_M2: np.ndarray | None = None
    created: str = field(default_factory=lambda: _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    # (width, height) the calibration was made at when it was scaled to image_size by scaled_to();
    # the RMS figures and per-pair errors stay in pixels of that original size
    scaled_from: tuple[int, int] | None = None
    model: str = "pinhole"  # lens model of both cameras (core.lens): pinhole, rational, fisheye
    uncertainty: object | None = None  # core.uncertainty.CalibrationUncertainty (1 sigma)
    origin: str = ""  # how it was made ("calibrated from 20 pairs ...", "refined from the scene ...")
    warnings: tuple = ()  # core.uncertainty.CalibrationWarning found when it was made
    # made from pairs whose left and right images were exchanged (the cameras were found
    # swapped): frames from the same source must be exchanged before they are rectified
    swapped_inputs: bool = False
    # (pair name, why) of the pairs it was not made from: rejected when it was made (no board
    # in both images, an outlier) or excluded by the technician
    left_out: tuple[tuple[str, str], ...] = ()
    # core.camera_settings.PairSettings: the cameras' controls (focus, exposure...) when the
    # pairs were captured, as this calibration names the cameras; None when not known
    camera_controls: object | None = None
    # core.shading.PairShading: how much darker each camera's corners are, measured on the white
    # squares of the pairs (undone before matching); None when not measured
    lens_shading: object | None = None

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
        from stereo_gui.core.lens import rectify_map

        size = (self.width, self.height)
        lx, ly = rectify_map(self.model, self.M1, self.D1, self.R1, self.P1, size, cv2.CV_16SC2)
        rx, ry = rectify_map(self.model, self.M2, self.D2, self.R2, self.P2, size, cv2.CV_16SC2)
        return RectifyMaps(lx, ly, rx, ry, size)

    def rectify_points(self, side: str, pts: np.ndarray) -> np.ndarray:
        """Raw pixels (N, 2) of one camera ("left" or "right") -> rectified pixels (N, 2)."""
        from stereo_gui.core.lens import undistort_points

        M, D, R, P = ((self.M1, self.D1, self.R1, self.P1) if side == "left"
                      else (self.M2, self.D2, self.R2, self.P2))
        return undistort_points(self.model, pts, M, D, R=R, P=P)

    def with_updates(self, **changes) -> StereoCalibration:
        return replace(self, **changes)

    def scaled_to(self, new_size: tuple[int, int]) -> StereoCalibration:
        """This calibration for images resized to `new_size` (width, height) px.

        Only a uniform scale is meaningful (the same lenses seen through a resized sensor), so
        the aspect ratio must stay the same; otherwise CalibrationError says why. Pixel
        coordinates follow OpenCV's convention (pixel centres at integers): c' = (c + 0.5) s - 0.5.
        R, T, D, R1, R2 and E do not change; M, P, Q and F do.
        """
        from stereo_gui.core.errors import CalibrationError

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

        def cam(M: np.ndarray | None) -> np.ndarray | None:
            if M is None:
                return None
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
                       optimal_M1=cam(self.optimal_M1), optimal_M2=cam(self.optimal_M2),
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


def check_matrices(values: dict[str, np.ndarray | None], where: str) -> None:
    """Raise CalibrationFileError naming the first matrix that is missing, mis-shaped or not finite."""
    for name, shape in MATRIX_SHAPES.items():
        m = values.get(name)
        if m is None:
            raise CalibrationFileError(f"{where}: matrix {name} is missing")
        m = np.asarray(m)
        if m.shape != shape:
            got = "x".join(map(str, m.shape)) or "a scalar"
            raise CalibrationFileError(
                f"{where}: matrix {name} should be {'x'.join(map(str, shape))}, found {got}")
        if not np.all(np.isfinite(m)):
            raise CalibrationFileError(f"{where}: matrix {name} holds values that are not finite")
    for name in ("D1", "D2"):
        d = values.get(name)
        if d is None:
            raise CalibrationFileError(f"{where}: distortion {name} is missing")
        d = np.asarray(d).reshape(-1)
        if d.size not in (4, 5, 8, 12, 14):
            raise CalibrationFileError(
                f"{where}: distortion {name} should have 4, 5, 8, 12 or 14 coefficients, found {d.size}")
        if not np.all(np.isfinite(d)):
            raise CalibrationFileError(f"{where}: distortion {name} holds values that are not finite")
