"""Lens models, in one place: projection (with its Jacobian), undistortion, rectification maps.

- "pinhole": OpenCV's standard model with 5 coefficients (k1 k2 p1 p2 k3), the default.
- "rational": the rational model, 8 coefficients (k1 k2 p1 p2 k3 k4 k5 k6; CALIB_RATIONAL_MODEL).
- "fisheye": OpenCV's fisheye (equidistant) model, 4 coefficients (k1 k2 k3 k4), for wide-angle
  webcams; its functions live in cv2.fisheye.

A distortion vector of 4 coefficients means different things in the pinhole and fisheye models,
so nothing may pass D to an OpenCV function without knowing the model: everything that does goes
through here.
"""

from __future__ import annotations

from typing import Literal, get_args, overload

import cv2
import numpy as np

from stereo_gui.core.errors import InputError

LensModel = Literal["pinhole", "rational", "fisheye"]  # written to files as these words
LENS_MODELS: tuple[LensModel, ...] = get_args(LensModel)
DIST_COUNT: dict[str, int] = {"pinhole": 5, "rational": 8, "fisheye": 4}
_PINHOLE_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty")
_FISHEYE_NAMES = ("k1", "k2", "k3", "k4")
# the coefficients that "fix k3 and higher terms" holds at zero, per model
HIGHER_TERMS = {"pinhole": ("k3",), "rational": ("k3", "k4", "k5", "k6"),
                "fisheye": ("k3", "k4")}
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)


def check_model(model: str) -> LensModel:
    """`model` as a LensModel; InputError when it is none."""
    for known in LENS_MODELS:
        if model == known:
            return known
    raise InputError(f"unknown lens model {model!r}: use one of {', '.join(LENS_MODELS)}")


def model_for(model: str, D: np.ndarray) -> str:
    """The model a distortion vector belongs to (a pinhole model with more than 5 coefficients
    is the rational one)."""
    if model == "fisheye":
        return model
    return "rational" if np.asarray(D).size > 5 else "pinhole"


def distortion_names(model: str, count: int | None = None) -> tuple[str, ...]:
    names = _FISHEYE_NAMES if model == "fisheye" else _PINHOLE_NAMES
    return names[: DIST_COUNT[model] if count is None else count]


def _fisheye_d(D: np.ndarray) -> np.ndarray:
    return np.asarray(D, np.float64).reshape(4, 1)


@overload
def project_points(model: str, obj: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
                   M: np.ndarray, D: np.ndarray, jacobian: Literal[False] = False) -> np.ndarray:
    ...


@overload
def project_points(model: str, obj: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
                   M: np.ndarray, D: np.ndarray, jacobian: Literal[True]
                   ) -> tuple[np.ndarray, np.ndarray]:
    ...


def project_points(model: str, obj: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
                   M: np.ndarray, D: np.ndarray, jacobian: bool = False
                   ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Project (N, 3) points (mm) seen from pose (rvec, tvec) into pixels, (N, 2) float64.

    With `jacobian`, also returns d(pixels)/d(params) as (2N, 10 + len(D)) in OpenCV's pinhole
    column order for every model: rvec (3), tvec (3), fx fy, cx cy, distortion.
    """
    obj = np.asarray(obj, np.float64).reshape(-1, 1, 3)
    rvec = np.asarray(rvec, np.float64).reshape(3, 1)
    tvec = np.asarray(tvec, np.float64).reshape(3, 1)
    M = np.asarray(M, np.float64)
    if model == "fisheye":
        pts, J = cv2.fisheye.projectPoints(obj, rvec, tvec, M, _fisheye_d(D))
        pts = pts.reshape(-1, 2)
        if not jacobian:
            return pts
        # fisheye order: f (2), c (2), k (4), rvec (3), tvec (3), alpha (1)
        J = np.asarray(J, np.float64)
        return pts, np.hstack([J[:, 8:11], J[:, 11:14], J[:, 0:2], J[:, 2:4], J[:, 4:8]])
    D = np.asarray(D, np.float64).reshape(-1)
    pts, J = cv2.projectPoints(obj, rvec, tvec, M, D)
    pts = pts.reshape(-1, 2)
    return (pts, np.asarray(J, np.float64)) if jacobian else pts


def undistort_points(model: str, pts: np.ndarray, M: np.ndarray, D: np.ndarray,
                     R: np.ndarray | None = None, P: np.ndarray | None = None) -> np.ndarray:
    """Raw pixels (N, 2) -> undistorted points: normalised coordinates, or pixels of P when
    given, after rotation R when given; (N, 2) float64."""
    p = np.asarray(pts, np.float64).reshape(-1, 1, 2)
    if p.shape[0] == 0:
        return np.zeros((0, 2))
    M = np.asarray(M, np.float64)
    R = None if R is None else np.asarray(R, np.float64)
    P = None if P is None else np.asarray(P, np.float64)
    if model == "fisheye":
        out = cv2.fisheye.undistortPoints(p, M, _fisheye_d(D), R=R if R is not None else np.eye(3),
                                          P=P if P is not None else np.eye(3),
                                          criteria=_UNDISTORT_CRITERIA)
    else:
        out = cv2.undistortPoints(p, M, np.asarray(D, np.float64).reshape(1, -1), R=R, P=P,
                                  criteria=_UNDISTORT_CRITERIA)
    return out.reshape(-1, 2)


def rectify_map(model: str, M: np.ndarray, D: np.ndarray, R: np.ndarray, P: np.ndarray,
                size: tuple[int, int], m1type: int = cv2.CV_16SC2
                ) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps of one camera into its rectified image (size = (w, h))."""
    size = (int(size[0]), int(size[1]))
    if model == "fisheye":
        return cv2.fisheye.initUndistortRectifyMap(np.asarray(M, np.float64), _fisheye_d(D),
                                                   np.asarray(R, np.float64),
                                                   np.asarray(P, np.float64), size, m1type)
    return cv2.initUndistortRectifyMap(M, np.asarray(D, np.float64).reshape(1, -1), R, P, size,
                                       m1type)


def stereo_rectify(model: str, M1: np.ndarray, D1: np.ndarray, M2: np.ndarray, D2: np.ndarray,
                   size: tuple[int, int], R: np.ndarray, T: np.ndarray, alpha: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bouguet rectification (CALIB_ZERO_DISPARITY): R1, R2, P1, P2, Q.

    For the fisheye model `alpha` is the balance between the smallest and the largest focal
    length (cv2.fisheye.stereoRectify); -1 means OpenCV's default for the pinhole models.
    """
    size = (int(size[0]), int(size[1]))
    R = np.asarray(R, np.float64)
    T = np.asarray(T, np.float64).reshape(3, 1)
    if model == "fisheye":
        R1, R2, P1, P2, Q = cv2.fisheye.stereoRectify(
            np.asarray(M1, np.float64), _fisheye_d(D1), np.asarray(M2, np.float64),
            _fisheye_d(D2), size, R, T, cv2.CALIB_ZERO_DISPARITY,
            balance=float(max(alpha, 0.0)), fov_scale=1.0)
        return R1, R2, P1, P2, Q
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(
        M1, np.asarray(D1, np.float64).reshape(1, -1), M2, np.asarray(D2, np.float64).reshape(1, -1),
        size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
    return R1, R2, P1, P2, Q


def optimal_new_camera(model: str, M: np.ndarray, D: np.ndarray, size: tuple[int, int]
                       ) -> np.ndarray:
    """The reference program's getOptimalNewCameraMatrix(alpha=1) (for fisheye: balance 1)."""
    size = (int(size[0]), int(size[1]))
    if model == "fisheye":
        return cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(
            np.asarray(M, np.float64), _fisheye_d(D), size, np.eye(3), balance=1.0)
    opt, _ = cv2.getOptimalNewCameraMatrix(M, np.asarray(D, np.float64).reshape(1, -1), size, 1,
                                           size)
    return opt


ROUND_TRIP_PX = 1.0  # a pixel undistorted and distorted again lands this near itself


def pixel_grid(width: int, height: int, n: int = 9) -> np.ndarray:
    """An n x n grid of pixels over the whole image, corners included, (n*n, 2)."""
    g = np.linspace(0.0, 1.0, n)
    u, v = np.meshgrid(g * (width - 1), g * (height - 1))
    return np.stack([u.ravel(), v.ravel()], 1)


def round_trip_px(model: str, M: np.ndarray, D: np.ndarray, image_size: tuple[int, int]
                  ) -> tuple[float, tuple[float, float]]:
    """How far a grid of the image's own pixels lands from itself when undistorted to rays and
    distorted back (the largest distance, px, and that pixel): a lens model that folds over
    inside the image sends its corners elsewhere (more than ROUND_TRIP_PX). Infinite where
    OpenCV cannot apply the model."""
    pts = pixel_grid(*image_size)
    with np.errstate(all="ignore"):
        try:
            rays = undistort_points(model, pts, M, D)
            back = project_points(model, np.hstack([rays, np.ones((len(rays), 1))]),
                                  np.zeros(3), np.zeros(3), M, D)
        except cv2.error:
            return float("inf"), (float(pts[0, 0]), float(pts[0, 1]))
        off = np.linalg.norm(back - pts, axis=1)
    off = np.where(np.isfinite(off), off, np.inf)
    i = int(np.argmax(off))
    return float(off[i]), (float(pts[i, 0]), float(pts[i, 1]))
