"""Is every point of a detected target where the rest of the view puts it?

A corner pulled aside by glare, blur, a speck on the print or an edge of something in front of
the board spoils a calibration, and is seen only afterwards, in the reprojection errors. At
capture it can be seen at once: one view of a flat target fixes the camera's pose and, roughly,
its focal length and radial distortion, so the points of the view predict each other. The view
is fitted alone (a camera with its principal point at the image centre, k1 and k2), its worst
point is left out, the view fitted again without it, and that point compared with where the
second fit puts it.

What a well-placed point misses by is noise and what the small model does not follow (the edges
of a wide-angle lens's image), and both are shared by neighbouring points: the worst point is
misplaced when it lies farther than MISPLACED_RATIO times the median of its nearest neighbours,
and than MISPLACED_PX. A view whose points miss their own fit by more than ROUGH_FIT_PX (median)
is not judged: the model does not follow that lens well enough to tell.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import Detection

MISPLACED_PX = 0.4  # below this distance from its prediction no point is called misplaced, px
MISPLACED_RATIO = 6.0  # ... nor below this many times the median of its neighbours
MIN_POINTS = 8  # fewer points than this are not judged
ROUGH_FIT_PX = 0.25  # a view whose points miss its own fit by more (median) is not judged, px
NEIGHBOURS = 8  # the worst point is compared with this many of its nearest neighbours


@dataclass(frozen=True)
class PointCheck:
    """The worst point of one view against the rest: its index in the detection's points, its
    position (px), its distance from where the other points put it (px), and the median
    distance of its nearest neighbours from that fit (px)."""

    worst_index: int
    worst_xy: tuple[float, float]
    worst_px: float
    median_px: float
    fit_px: float  # the median distance of all the other points from the fit, px

    @property
    def judged(self) -> bool:
        """Whether the view's fit is close enough to tell a misplaced point (a wide-angle lens
        is not followed by the small model: its view is not judged)."""
        return self.fit_px <= ROUGH_FIT_PX

    @property
    def misplaced(self) -> bool:
        return self.judged and self.worst_px > max(MISPLACED_PX,
                                                   MISPLACED_RATIO * self.median_px)


_FLAGS = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT
          | cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3)


# one view fitted alone: camera matrix, distortion, rvec, tvec
_ViewFit = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _fit(obj: np.ndarray, img: np.ndarray, size: tuple[int, int]) -> _ViewFit:
    """One view fitted alone: (camera matrix, distortion, rvec, tvec)."""
    w, h = size
    guess = np.array([[w, 0.0, w / 2.0], [0.0, w, h / 2.0], [0.0, 0.0, 1.0]])
    _rms, m, d, rvecs, tvecs = cv2.calibrateCamera(
        [obj.reshape(-1, 1, 3)], [img.reshape(-1, 1, 2)], (int(w), int(h)), guess, None,
        flags=_FLAGS, criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-6))
    return m, d, rvecs[0], tvecs[0]


def _misses(fit: _ViewFit, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    m, d, rvec, tvec = fit
    proj, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, m, d)
    off: np.ndarray = proj.reshape(-1, 2) - img.reshape(-1, 2)
    misses: np.ndarray = np.hypot(off[:, 0], off[:, 1])
    return misses


def check_points(det: Detection, board: BoardSpec) -> PointCheck | None:
    """Compare the worst point of `det` with where the other points put it (see the module's
    docstring); None for a view of too few points, or one that cannot be fitted."""
    obj = det.object_points(board).astype(np.float32)
    img = np.asarray(det.corners, np.float32).reshape(-1, 2)
    if len(img) < MIN_POINTS:
        return None
    try:
        k = int(np.argmax(_misses(_fit(obj, img, det.image_size), obj, img)))
        rest = np.arange(len(img)) != k
        refit = _fit(obj[rest], img[rest], det.image_size)
    except cv2.error:
        return None
    misses = _misses(refit, obj, img)
    # the median of its nearest neighbours on the board: where the small model does not follow
    # the lens (the image's edges with a wide-angle lens), it misses them all alike
    near = np.argsort(np.linalg.norm(obj[:, :2] - obj[k, :2], axis=1))[1:NEIGHBOURS + 1]
    return PointCheck(k, (float(img[k, 0]), float(img[k, 1])), float(misses[k]),
                      float(np.median(misses[near])), float(np.median(misses[rest])))
