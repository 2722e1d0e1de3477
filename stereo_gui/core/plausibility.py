"""Whether a calibration is a camera pair that could exist: what any camera pair and its
rectification obey, whoever computed them.

A StereoCalibration checks its own values on construction (shapes, finite values, positive focal
lengths); these checks look at the whole (focal lengths for a lens, P1, P2, Q, E and F that
follow from the rest, lens models that map the image's own pixels) and cost a pass of the lens
model over the image, so they run where a calibration enters or leaves the program: when a file
is loaded or saved, and on calibrations imported from other tools.
"""

from __future__ import annotations

from typing import NoReturn

import cv2
import numpy as np
from numpy.typing import ArrayLike

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.lens import ROUND_TRIP_PX, pixel_grid, round_trip_px, undistort_points
from stereo_gui.core.stereo_calibration import (
    ROTATION_TOL,
    StereoCalibration,
    q_from_projections,
)


def _fail(where: str, text: str) -> NoReturn:
    raise CalibrationFileError(f"{where}: {text}")


# Each test names the field that fails it. Tolerances allow a file written with fewer digits
# than ours (a hand-made or another tool's file); damage is orders of magnitude beyond them.
MIN_BASELINE_MM = 1.0  # a metric calibration's cameras are apart by at least this
PLAUSIBLE_BASELINE_MM = 100_000.0  # 100 m: beyond, readings become absurd, not a rig
MIN_FOV_FOCAL = 0.05  # focal length in image widths: below, a pinhole view wider than 174 deg
MAX_FOV_FOCAL = 100.0  # above, a view narrower than 0.6 deg
MAX_FOCAL_RATIO = 3.0  # the two cameras, and the rectified ones, differ in focal length by less
RELATIVE_TOL = 1e-3


def _near(a: ArrayLike, b: ArrayLike, tol: float = RELATIVE_TOL) -> bool:
    """Each element of `a` within `tol` of its own size of `b`'s (zeros: of the largest's)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1e-300)
    return bool(np.all(np.abs(a - b) <= tol * np.maximum(np.abs(a), np.abs(b)) + 1e-9 * scale))


def _is_rotation(m: np.ndarray) -> bool:
    return (np.allclose(m.T @ m, np.eye(3), atol=ROTATION_TOL)
            and abs(np.linalg.det(m) - 1.0) < ROTATION_TOL)


def _same_up_to_scale(a: np.ndarray, b: np.ndarray) -> bool:
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if not (na > 0 and nb > 0):
        return False
    a, b = a / na, b / nb  # unit norm: compared against 1, whatever each element's size
    return bool(min(np.max(np.abs(a - b)), np.max(np.abs(a + b))) <= RELATIVE_TOL)


def _q_of(P1: np.ndarray, P2: np.ndarray, vertical: bool) -> np.ndarray:
    """The disparity-to-depth matrix cv2.stereoRectify builds from the rectified projections."""
    if not vertical:
        return q_from_projections(P1, P2)
    f, cx, cy = P1[1, 1], P1[0, 2], P1[1, 2]
    ty = P2[1, 3] / P2[1, 1]
    return np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f],
                     [0, 0, -1.0 / ty, (cy - P2[1, 2]) / ty]], np.float64)


def check_plausible(calib: StereoCalibration, where: str) -> None:
    """Raise CalibrationFileError naming the field of `calib` that no camera pair has, or that
    disagrees with the rest: focal lengths for no lens (or two cameras, or the rectified ones,
    far apart), a principal point outside the image, a lens model that does not map the image's
    own pixels, a baseline of less than a millimetre or more than 100 m, rectification
    rotations that are not rotations or do not share one frame, P1/P2 that are not a rectified
    pair or show the images in a corner of theirs, Q, E or F that do not follow from the rest.

    Hartley's rectification has no metric baseline and homographies for R1/R2: only what it
    shares with the others is checked. An already rectified pair ("identity") is its P1/P2."""
    with np.errstate(all="ignore"):
        _check_plausible(calib, where)


MIN_FOOTPRINT = 0.5  # share of the rectified image's width and height a raw image covers


def _check_lenses(calib: StereoCalibration, where: str) -> None:
    """Each camera's lens model maps the pixels of its own image to rays and back (a
    distortion that folds over inside the image does not), and its rectification shows the
    image over a good part of the rectified one (not squeezed into a corner of it)."""
    w, h = calib.width, calib.height
    pts = pixel_grid(w, h)
    sides = (("1", calib.M1, calib.D1, calib.R1, calib.P1), ("2", calib.M2, calib.D2, calib.R2,
                                                             calib.P2))
    for k, M, D, R, P in sides:
        off, (x, y) = round_trip_px(calib.model, M, D, (w, h))
        if off == float("inf"):
            _fail(where, f"distortion D{k} cannot be applied to the image of camera {k}")
        if not off <= ROUND_TRIP_PX:
            _fail(where, f"distortion D{k} does not describe camera {k}'s lens: pixel "
                         f"({x:.0f}, {y:.0f}) comes back {off:.3g} px away "
                         "(a lens model folding over inside the image)")
        try:
            rect = undistort_points(calib.model, pts, M, D, R=R, P=P)
        except cv2.error:
            _fail(where, f"distortion D{k} cannot be applied to the image of camera {k}")
        span = np.ptp(rect, axis=0) if np.all(np.isfinite(rect)) else np.zeros(2)
        if not (span[0] >= MIN_FOOTPRINT * w and span[1] >= MIN_FOOTPRINT * h):
            _fail(where, f"matrices R{k} and P{k} with distortion D{k} show camera {k}'s image "
                         f"in {span[0]:.0f} x {span[1]:.0f} px of the {w}x{h} rectified image: "
                         "they do not belong together")


def _check_plausible(calib: StereoCalibration, where: str) -> None:
    _check_cameras(calib, where)
    vertical = _check_rectified(calib, where)
    _check_epipolar(calib, where)
    _check_lenses(calib, where)
    if calib.method == "hartley":
        return
    _check_metric_pose(calib, where, vertical)


def _check_cameras(calib: StereoCalibration, where: str) -> None:
    """Each camera's focal lengths and principal point are a lens's, and the two cameras' focal
    lengths those of one rig."""
    w, h = calib.width, calib.height
    least = MIN_FOV_FOCAL * (2.0 if calib.model == "fisheye" else 1.0)
    for name, M in (("M1", calib.M1), ("M2", calib.M2)):
        fx, fy = M[0, 0], M[1, 1]
        if not least * w <= fx <= MAX_FOV_FOCAL * w or not 0.5 <= fy / fx <= 2.0:
            _fail(where, f"matrix {name} has focal lengths {fx:g}, {fy:g} px, which no lens "
                         f"has for an image {w} px wide (a focal length of {least * w:g} to "
                         f"{MAX_FOV_FOCAL * w:g} px, the same within a factor 2 across)")
        if calib.method != "identity" and not (0 <= M[0, 2] <= w and 0 <= M[1, 2] <= h):
            _fail(where, f"matrix {name} puts the principal point at ({M[0, 2]:g}, {M[1, 2]:g}) "
                         f"px, outside the {w}x{h} image")
    f1, f2 = calib.M1[0, 0], calib.M2[0, 0]
    if max(f1, f2) > MAX_FOCAL_RATIO * min(f1, f2):
        _fail(where, f"matrices M1 and M2 have focal lengths {f1:g} and {f2:g} px: more than "
                     f"{MAX_FOCAL_RATIO:g} times apart, they are not the two cameras of one rig")


def _check_rectified(calib: StereoCalibration, where: str) -> bool:
    """P1, P2 and Q are one rectified pair's (of these cameras); whether its baseline is
    vertical (the images' columns match, not their rows)."""
    w, h = calib.width, calib.height
    f1, f2 = calib.M1[0, 0], calib.M2[0, 0]
    P1, P2 = np.asarray(calib.P1, np.float64), np.asarray(calib.P2, np.float64)
    for name, P in (("P1", P1), ("P2", P2)):
        if not _near(P[2], (0.0, 0.0, 1.0, 0.0), 1e-6) or abs(P[0, 1]) > 1e-6 * P[0, 0] \
                or P[1, 0] != 0:
            _fail(where, f"matrix {name} is not a rectified camera's projection (its last row "
                         "must be 0 0 1 0, without skew)")
    if np.any(P1[:, 3] != 0):
        _fail(where, "matrix P1 has a translation term: the left rectified camera is the origin")
    if not (_near(P1[0, 0], P2[0, 0]) and _near(P1[1, 1], P2[1, 1])):
        _fail(where, f"matrices P1 and P2 have different focal lengths ({P1[0, 0]:g}, "
                     f"{P2[0, 0]:g} px): they are not one rectified pair")
    vertical = bool(P2[0, 3] == 0)
    if not (_near(P1[0, 2], P2[0, 2]) if vertical else _near(P1[1, 2], P2[1, 2])):
        _fail(where, "matrices P1 and P2 put their principal points on different "
                     f"{'columns' if vertical else 'rows'}: rows of the two images would not "
                     "match")
    if vertical and P2[1, 3] == 0 or not vertical and P2[1, 3] != 0:
        _fail(where, "matrix P2 has a baseline term along both image axes")
    rect_f = P1[0, 0]
    cams = min(f1, f2), max(f1, f2)
    if not cams[0] / MAX_FOCAL_RATIO <= rect_f <= cams[1] * MAX_FOCAL_RATIO:
        _fail(where, f"the rectified focal length (P1, P2) is {rect_f:g} px but the cameras' "
                     f"(M1, M2) are {f1:g} and {f2:g} px: they do not belong together")
    if not (-w <= P1[0, 2] <= 2 * w and -h <= P1[1, 2] <= 2 * h):
        _fail(where, f"matrix P1 puts the rectified principal point at ({P1[0, 2]:g}, "
                     f"{P1[1, 2]:g}) px, far outside the {w}x{h} image")
    if not _near(calib.Q, _q_of(P1, P2, vertical), 1e-6):
        _fail(where, "matrix Q does not follow from P1 and P2: it would turn disparities into "
                     "distances of another rig")
    return vertical


def _check_epipolar(calib: StereoCalibration, where: str) -> None:
    """E follows from R and T (not for Hartley's, which has no metric pose), F from E, M1, M2."""
    hartley = calib.method == "hartley"
    R, T = np.asarray(calib.R, np.float64), np.asarray(calib.T, np.float64).reshape(3)
    E, F = np.asarray(calib.E, np.float64), np.asarray(calib.F, np.float64)
    tx = np.array([[0, -T[2], T[1]], [T[2], 0, -T[0]], [-T[1], T[0], 0]])
    if not hartley and not _same_up_to_scale(E, tx @ R):
        _fail(where, "matrix E does not follow from R and T")
    F_of_E = np.linalg.inv(calib.M2).T @ E @ np.linalg.inv(calib.M1)
    if not _same_up_to_scale(F, F_of_E):
        _fail(where, "matrix F does not follow from E, M1 and M2")


def _check_metric_pose(calib: StereoCalibration, where: str, vertical: bool) -> None:
    """A rig's baseline, rotations R1, R2 consistent with R, the baseline along the rectified
    rows (or columns, `vertical`) and P2's baseline T's."""
    R, T = np.asarray(calib.R, np.float64), np.asarray(calib.T, np.float64).reshape(3)
    P2 = np.asarray(calib.P2, np.float64)
    baseline = float(np.linalg.norm(T))
    if not MIN_BASELINE_MM <= baseline <= PLAUSIBLE_BASELINE_MM:
        _fail(where, f"T gives a baseline of {baseline:g} mm (a rig's cameras are "
                     f"{MIN_BASELINE_MM:g} mm to {PLAUSIBLE_BASELINE_MM / 1000:g} m apart)")
    R1, R2 = np.asarray(calib.R1, np.float64), np.asarray(calib.R2, np.float64)
    for name, m in (("R1", R1), ("R2", R2)):
        if not _is_rotation(m):
            _fail(where, f"matrix {name} is not a rotation")
    if not np.allclose(R1, R2 @ R, atol=ROTATION_TOL):
        _fail(where, "matrices R1, R2 and R disagree: the rectified cameras would not look the "
                     "same way")
    t_rect = R2 @ T  # the baseline in the rectified frame: along the rows (or columns) alone
    axis = 1 if vertical else 0
    across = np.delete(t_rect, axis)
    if np.max(np.abs(across)) > RELATIVE_TOL * baseline * 10:
        _fail(where, "matrix R2 does not turn the baseline T along the image rows: rows of the "
                     "rectified images would not match")
    b_p2 = P2[axis, 3] / P2[axis, axis]
    if not _near(b_p2, t_rect[axis], 10 * RELATIVE_TOL):
        _fail(where, f"matrix P2 holds a baseline of {abs(b_p2):g} mm but T one of "
                     f"{baseline:g} mm: distances would be off by a factor "
                     f"{abs(b_p2) / baseline:.3g}")
