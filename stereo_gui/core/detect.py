"""Target detection in single images, stereo pairs and many pairs at once, plus pose coverage.

Targets (core.board): chessboards, symmetric and asymmetric circle grids (`findCirclesGrid`),
and ChArUco boards (`cv2.aruco.CharucoDetector`), of which a view may show any part: every
point found carries its id, and a pair uses the corners both cameras found, matched by id.

Chessboard detection defaults to OpenCV's classic detector (`findChessboardCorners`) followed by
`cornerSubPix`; `findChessboardCornersSB` is offered as `method="sb"`. The classic detector is
the default because it gives the more accurate calibration in a fraction of the time, finds the
board in more real webcam pairs, and finds nothing on a partly hidden board where SB can return
a grid shifted by one row (scripts/bench_calibration.py; figures in docs/guide.md).

Coverage guidance follows ROS camera_calibration: each detection is reduced to a pose descriptor
(x, y, size, skew, each normalised to 0..1), and the spread of the kept descriptors along each
axis tells the technician what is still missing.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.board import TARGET_NAMES, BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import Cancel, Cancelled, ProgressCallback, check_cancel, is_cancelled
from stereo_gui.core.util import to_gray

log = logging.getLogger(__name__)

METHODS = ("classic", "sb")


# ---- single images ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Detection:
    """The points of a target found in one image.

    `corners` is (N, 2) float32 in pixels; `ids` (N,) int32 says which of the board's object
    points each one is (None: all of them, in order, as for chessboards and circle grids).
    """

    corners: np.ndarray
    image_size: tuple[int, int]  # (width, height), px
    method: str  # "classic", "sb", "circles" or "charuco"
    ids: np.ndarray | None = None

    @property
    def corners_cv(self) -> np.ndarray:
        """The corners shaped (N, 1, 2) float32, as OpenCV's calibration functions take them."""
        return self.corners.reshape(-1, 1, 2).astype(np.float32, copy=False)

    @property
    def point_ids(self) -> np.ndarray:
        """Ids of the points, (N,) int."""
        return np.arange(len(self.corners)) if self.ids is None else self.ids

    def object_points(self, board: BoardSpec) -> np.ndarray:
        """The board positions (mm, Z = 0) of the points found, (N, 3) float32."""
        points: np.ndarray = board.object_points_mm()[self.point_ids]
        return points

    def reversed(self) -> Detection:
        """The same corners in the opposite order (the board turned by 180 degrees)."""
        return Detection(self.corners[::-1].copy(), self.image_size, self.method)

    def pose(self, board: BoardSpec) -> PoseDescriptor:
        return pose_descriptor(self.corners, board, self.image_size, self.ids)


_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
_CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
_SB_FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_NORMALIZE_IMAGE


def _subpix_radius(corners: np.ndarray, board: BoardSpec) -> int:
    """Half the smallest spacing between neighbouring corners, so the window never reaches a
    neighbouring corner on small or far boards (ROS camera_calibration does the same)."""
    grid = corners.reshape(board.rows, board.cols, 2)
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=2).min()
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=2).min()
    return int(min(11, max(2, math.ceil(0.5 * min(dx, dy)))))


def _blob_detector(min_distance_px: float = 2.0) -> cv2.SimpleBlobDetector:
    """Dark round blobs from a few pixels (far boards) up to large ones (near boards)."""
    params = cv2.SimpleBlobDetector.Params()
    params.minArea = 8.0
    params.maxArea = 40000.0
    params.minDistBetweenBlobs = float(min_distance_px)
    params.filterByConvexity = True
    params.minConvexity = 0.8
    params.filterByInertia = True
    params.minInertiaRatio = 0.05  # tilted boards make ellipses
    return cv2.SimpleBlobDetector.create(params)


CIRCLE_GRID_ATTEMPTS = 3  # random starts of findCirclesGrid per blob setting


def _detect_circles(gray: np.ndarray, board: BoardSpec, size: tuple[int, int]
                    ) -> Detection | None:
    """Small far circles need blobs close together; clutter (letters, noise) near large circles
    is merged away with a larger distance. findCirclesGrid's grid search starts from OpenCV's
    random number generator (k-means), so that one image is found or not by chance: its seed is
    set for each of a few attempts, so the answer is the same every time. The first found wins."""
    for min_distance in (2.0, 10.0):
        blobs = _blob_detector(min_distance)
        if len(blobs.detect(gray)) < board.point_count:
            continue
        for seed in range(CIRCLE_GRID_ATTEMPTS):
            det = _detect_circles_with(gray, board, size, blobs, seed)
            if det is not None:
                return det
    return None


def _detect_circles_with(gray: np.ndarray, board: BoardSpec, size: tuple[int, int],
                         blobs: cv2.SimpleBlobDetector,
                         seed: int) -> Detection | None:
    flags = cv2.CALIB_CB_ASYMMETRIC_GRID if board.target == "acircles" else cv2.CALIB_CB_SYMMETRIC_GRID
    cv2.setRNGSeed(seed)
    ok, centers = cv2.findCirclesGrid(gray, board.pattern_size, flags=flags, blobDetector=blobs)
    if not ok or centers is None or len(centers) != board.point_count:
        return None
    centers = centers.reshape(-1, 2).astype(np.float64)
    # findCirclesGrid's blob centres average many thresholds, and a threshold near the paper's
    # white merges noise into the blobs (OpenCV 5.0 then put an outer point of an asymmetric
    # grid 15 px off): the grid gives where each circle is, a local centroid says where exactly
    obj = board.object_points_mm()[:, :2].astype(np.float64)
    H, _ = cv2.findHomography(obj, centers, cv2.RANSAC, 3.0)
    if H is None:
        return None
    guess = cv2.perspectiveTransform(obj.reshape(-1, 1, 2), H).reshape(-1, 2)
    nn = np.linalg.norm(guess[:, None, :] - guess[None, :, :], axis=2)
    np.fill_diagonal(nn, np.inf)
    out = np.empty_like(guess)
    for k, (c, d) in enumerate(zip(guess, nn.min(axis=1))):
        got = _circle_centroid(gray, c, 0.5 * d)
        if got is None:
            return None
        out[k] = got
    fit = cv2.perspectiveTransform(obj.reshape(-1, 1, 2), H).reshape(-1, 2)
    if np.linalg.norm(fit - out, axis=1).max() > 0.3 * float(nn.min()):
        return None  # not that grid in that order
    return Detection(out.astype(np.float32), size, "circles")


def _circle_centroid(gray: np.ndarray, c: np.ndarray, half: float) -> np.ndarray | None:
    """Centre of the dark disc nearest to `c` within a window of half-size `half` px: the
    darkness-weighted centroid of its connected region (anti-aliased edges count by share)."""
    h, w = gray.shape[:2]
    r = max(2, int(math.ceil(half)))
    x0, y0 = int(round(c[0])) - r, int(round(c[1])) - r
    x1, y1 = x0 + 2 * r + 1, y0 + 2 * r + 1
    if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
        return None
    win = gray[y0:y1, x0:x1].astype(np.float32)
    thr, mask = cv2.threshold(win.astype(np.uint8), 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n < 2:
        return None
    k = 1 + int(np.argmin(np.linalg.norm(cents[1:] - (c - (x0, y0)), axis=1)))
    region = cv2.dilate((labels == k).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    if region[0, :].any() or region[-1, :].any() or region[:, 0].any() or region[:, -1].any():
        return None  # the disc runs out of the window: not a clean circle
    dark = float(np.percentile(win[labels == k], 10))
    light = float(np.percentile(win[~region], 90)) if (~region).any() else 255.0
    if light - dark < 20:
        return None
    wgt = np.clip((light - win) / (light - dark), 0.0, 1.0) * region
    total = float(wgt.sum())
    if total <= 0:
        return None
    ys, xs = np.mgrid[0:win.shape[0], 0:win.shape[1]]
    return np.array([x0 + float((wgt * xs).sum()) / total, y0 + float((wgt * ys).sum()) / total])


# the white gap between a ChArUco corner and its markers must span this many pixels
CHARUCO_MIN_GAP_PX = 2.5


def _charuco_detector(board: BoardSpec) -> cv2.aruco.CharucoDetector:
    det = cv2.aruco.CharucoDetector(board.aruco_board())
    params = det.getDetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det.setDetectorParameters(params)
    cp = det.getCharucoParameters()
    cp.tryRefineMarkers = True
    det.setCharucoParameters(cp)
    return det


def _detect_charuco(gray: np.ndarray, board: BoardSpec, size: tuple[int, int]
                    ) -> Detection | None:
    corners, ids, _, _ = _charuco_detector(board).detectBoard(gray)
    if corners is None or ids is None or len(ids) < board.min_points:
        return None
    ids = ids.reshape(-1).astype(np.int32)
    corners = corners.reshape(-1, 2).astype(np.float32)
    order = np.argsort(ids)
    ids, corners = ids[order], corners[order]
    rows, cols = board.grid_shape
    # points on one line cannot fix a camera's pose: ask for two rows and two columns
    if np.unique(ids // cols).size < 2 or np.unique(ids % cols).size < 2:
        return None
    # refine on the image with a window that stays inside the white gap between a corner and
    # the markers next to it (their edges would pull the corner off)
    gap_px = (board.square_mm - board.marker_mm) / (2.0 * board.square_mm) * \
        _spacing_px(corners, ids, cols)
    if gap_px < CHARUCO_MIN_GAP_PX:
        return None  # too small in the image to place its corners to a fraction of a pixel
    r = max(2, int(math.floor(0.9 * gap_px)))
    corners = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2), (r, r), (-1, -1),
                               _SUBPIX_CRITERIA).reshape(-1, 2)
    return Detection(corners.astype(np.float32), size, "charuco", ids)


def _spacing_px(corners: np.ndarray, ids: np.ndarray, cols: int) -> float:
    """The smallest distance between neighbouring ChArUco corners found, px."""
    pos = {int(i): c for i, c in zip(ids, corners)}
    best = math.inf
    for i, c in pos.items():
        for j in ((i + 1) if (i + 1) % cols else None, i + cols):
            if j is not None and j in pos:
                best = min(best, float(np.linalg.norm(pos[j] - c)))
    return best if math.isfinite(best) else 10.0


def detect_board(image: np.ndarray, board: BoardSpec, method: str = "classic") -> Detection | None:
    """Find the target's points in one image with subpixel accuracy, or None.

    `method` chooses the chessboard detector (classic or sb); the other targets have one each.
    """
    if method not in METHODS:
        raise ValueError(f"unknown detection method {method!r}; use one of {METHODS}")
    gray = to_gray(image)
    size = (int(gray.shape[1]), int(gray.shape[0]))
    # a board needs a few pixels a square; OpenCV's detectors assert on smaller images
    if size[0] < 4 * (board.cols + 1) or size[1] < 4 * (board.rows + 1):
        return None
    if board.target in ("circles", "acircles"):
        return _detect_circles(gray, board, size)
    if board.target == "charuco":
        return _detect_charuco(gray, board, size)
    if method == "sb":
        ok, corners = cv2.findChessboardCornersSB(gray, board.pattern_size, flags=_SB_FLAGS)
        if not ok:
            return None
        return Detection(corners.reshape(-1, 2).astype(np.float32), size, "sb")
    ok, corners = cv2.findChessboardCorners(gray, board.pattern_size, flags=_CLASSIC_FLAGS)
    if not ok:
        return None
    r = _subpix_radius(corners.reshape(-1, 2), board)
    corners = cv2.cornerSubPix(gray, corners, (r, r), (-1, -1), _SUBPIX_CRITERIA)
    return Detection(corners.reshape(-1, 2).astype(np.float32), size, "classic")


# ---- pairs -----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PairDetection:
    """Detection result of one stereo pair. It counts for calibration only when both sides have
    the target, with enough points in common for a partly visible one (`found`); otherwise
    `reason` says what is missing."""

    name: str
    left: Detection | None
    right: Detection | None
    image_size: tuple[int, int]  # (width, height), px, of both images
    left_file: str = ""  # file names, for messages; empty for frames from a live source
    right_file: str = ""
    target: str = "chessboard"  # what was looked for (core.board.TARGETS), for messages
    min_common: int = 0  # points both cameras must share (partly visible targets)

    @property
    def found(self) -> bool:
        if self.left is None or self.right is None:
            return False
        return self.min_common <= 0 or len(self.common_ids()) >= self.min_common

    def sides(self) -> tuple[Detection, Detection]:
        """Both cameras' detections of a pair in which both saw the target (ValueError when
        one did not)."""
        if self.left is None or self.right is None:
            raise ValueError(f"{self.name}: the target was not found in both images")
        return self.left, self.right

    def common_ids(self) -> np.ndarray:
        """Ids of the points both cameras found (sorted), (K,) int."""
        if self.left is None or self.right is None:
            return np.zeros(0, int)
        if self.left.ids is None and self.right.ids is None:
            return self.left.point_ids
        return np.intersect1d(self.left.point_ids, self.right.point_ids)

    def common(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ids (K,), left points (K, 2), right points (K, 2)) of the points both cameras found."""
        ids = self.common_ids()
        if self.left is None or self.right is None:
            return ids, np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32)
        if self.left.ids is None and self.right.ids is None:
            return ids, self.left.corners, self.right.corners
        li = np.searchsorted(self.left.point_ids, ids)
        ri = np.searchsorted(self.right.point_ids, ids)
        return ids, self.left.corners[li], self.right.corners[ri]

    @property
    def reason(self) -> str:
        """Why the pair cannot be used ('' when it can)."""
        missing = [f"{side} image{f' ({f})' if f else ''}"
                   for side, det, f in (("left", self.left, self.left_file),
                                        ("right", self.right, self.right_file)) if det is None]
        if missing:
            return f"{TARGET_NAMES.get(self.target, self.target)} not found in the " + \
                " and the ".join(missing)
        if not self.found:
            return (f"the cameras share only {len(self.common_ids())} corners of the board "
                    f"(at least {self.min_common} are needed)")
        return ""


def _consistent_order(left: Detection, right: Detection) -> Detection:
    """Return `right` ordered like `left`.

    The corner grid looks the same after a 180 degree turn, so a detector may number it from
    either end. Both cameras look the same way, so the first-to-last corner direction must agree.
    Points that carry ids (ChArUco) need no such care.
    """
    if left.ids is not None or right.ids is not None:
        return right
    dl = left.corners[-1] - left.corners[0]
    dr = right.corners[-1] - right.corners[0]
    return right.reversed() if float(np.dot(dl, dr)) < 0 else right


def detect_pair(name: str, left: np.ndarray, right: np.ndarray, board: BoardSpec,
                method: str = "classic", left_file: str = "", right_file: str = "") -> PairDetection:
    """Detect the board in both images of a pair (images must have the same size)."""
    if left.shape[:2] != right.shape[:2]:
        raise InputError(
            f"images of different sizes: {left_file or name + ' left'} is "
            f"{left.shape[1]}x{left.shape[0]} but {right_file or name + ' right'} is "
            f"{right.shape[1]}x{right.shape[0]}")
    dl = detect_board(left, board, method)
    dr = detect_board(right, board, method)
    return make_pair(name, dl, dr, (int(left.shape[1]), int(left.shape[0])), board, left_file,
                     right_file)


def make_pair(name: str, left: Detection | None, right: Detection | None,
              image_size: tuple[int, int], board: BoardSpec, left_file: str = "",
              right_file: str = "") -> PairDetection:
    """A PairDetection of two single-image detections (orders the right one like the left)."""
    if left is not None and right is not None:
        right = _consistent_order(left, right)
    return PairDetection(name, left, right, image_size, left_file, right_file, board.target,
                         board.min_points if board.partial else 0)


# an image, or a zero-argument loader that returns it
ImageSource = np.ndarray | Callable[[], np.ndarray]


@dataclass(frozen=True)
class PairInput:
    """One pair to detect: images as arrays, or zero-argument loaders returning arrays (so that
    file reading happens in the pool too)."""

    name: str
    left: ImageSource
    right: ImageSource
    left_file: str = ""
    right_file: str = ""


def _load(x: ImageSource) -> np.ndarray:
    return x() if callable(x) else x


def default_workers() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


def detect_pairs(pairs: Sequence[PairInput | tuple[str, ImageSource, ImageSource]],
                 board: BoardSpec, method: str = "classic",
                 progress: ProgressCallback | None = None,
                 cancel: Cancel = None, workers: int | None = None) -> list[PairDetection]:
    """Detect the board in many pairs on a thread pool (OpenCV releases the GIL), in input order.

    Threads rather than a process pool: no pickling of images and no start-up cost.

    `pairs` holds PairInput or (name, left, right) tuples. Progress is reported from the calling
    thread after each finished pair; cancelling stops at the next finished pair and raises
    Cancelled (pairs not started are dropped).
    """
    items = [p if isinstance(p, PairInput) else PairInput(*p) for p in pairs]
    total = len(items)
    workers = default_workers() if workers is None else max(1, int(workers))
    check_cancel(cancel)

    def job(item: PairInput) -> PairDetection:
        if is_cancelled(cancel):
            return None  # type: ignore[return-value]
        left, right = _load(item.left), _load(item.right)
        return detect_pair(item.name, left, right, board, method, item.left_file, item.right_file)

    results: list[PairDetection | None] = [None] * total
    if workers == 1 or total <= 1:
        for i, item in enumerate(items):
            check_cancel(cancel)
            results[i] = job(item)
            if progress:
                progress(i + 1, total, f"pair {item.name}")
        return results  # type: ignore[return-value]

    # cv2.setNumThreads is left alone on purpose: it is process-wide (it would also slow the live
    # matcher running in another thread), and pinning OpenCV to 1 thread during detection makes
    # no measurable difference.
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="detect") as pool:
        futures = {pool.submit(job, item): i for i, item in enumerate(items)}
        done = 0
        try:
            for fut in as_completed(futures):
                i = futures[fut]
                results[i] = fut.result()
                done += 1
                if progress:
                    progress(done, total, f"pair {items[i].name}")
                if is_cancelled(cancel):
                    raise Cancelled()
        except BaseException:
            for f in futures:
                f.cancel()
            raise
    check_cancel(cancel)
    return results  # type: ignore[return-value]


# ---- pose descriptors and coverage (after ROS camera_calibration) -----------------------------
@dataclass(frozen=True)
class PoseDescriptor:
    """Where and how the board sits in the image, each in 0..1: x, y (position of the board's
    centre across the free image area), size (sqrt of board area / image area), skew (tilt)."""

    x: float
    y: float
    size: float
    skew: float

    def as_tuple(self) -> tuple[float, float, float, float]:
        return (self.x, self.y, self.size, self.skew)

    def distance(self, other: PoseDescriptor) -> float:
        """Sum of absolute differences, as ROS uses to decide whether a sample is new."""
        return float(sum(abs(a - b) for a, b in zip(self.as_tuple(), other.as_tuple())))


def _outside_corners(corners: np.ndarray, board: BoardSpec,
                     ids: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """The four outermost points of the target's grid: up-left, up-right, down-right, down-left.
    For a partial view they are where the board's plane puts them (a homography of the points
    found), so a board half out of the image reads as the large board it is."""
    c = corners.reshape(-1, 2).astype(np.float64)
    rows, cols = board.grid_shape
    if ids is None:
        return c[0], c[cols - 1], c[-1], c[-cols]
    obj = board.object_points_mm()[:, :2].astype(np.float64)
    H, _ = cv2.findHomography(obj[ids], c, 0)
    if H is None:
        return c[0], c[0], c[0], c[0]
    outer = obj[[0, cols - 1, rows * cols - 1, (rows - 1) * cols]].reshape(-1, 1, 2)
    q = cv2.perspectiveTransform(outer, H).reshape(-1, 2)
    return q[0], q[1], q[2], q[3]


def pose_descriptor(corners: np.ndarray, board: BoardSpec, image_size: tuple[int, int],
                    ids: np.ndarray | None = None) -> PoseDescriptor:
    """ROS camera_calibration's (x, y, size, skew) of one detection, each clipped to 0..1."""
    w, h = image_size
    ul, ur, dr, dl = _outside_corners(corners, board, ids)
    # quadrilateral area from its two diagonals
    p, q = dr - ul, dl - ur
    area = abs(p[0] * q[1] - p[1] * q[0]) / 2.0
    # skew: how far the angle at the top-right corner is from 90 degrees
    ab, cb = ul - ur, dr - ur
    cosang = float(np.dot(ab, cb) / max(np.linalg.norm(ab) * np.linalg.norm(cb), 1e-12))
    angle = math.acos(max(-1.0, min(1.0, cosang)))
    skew = min(1.0, 2.0 * abs(math.pi / 2.0 - angle))
    border = math.sqrt(area)
    c = corners.reshape(-1, 2) if ids is None else np.array([ul, ur, dr, dl])
    px = min(1.0, max(0.0, (float(c[:, 0].mean()) - border / 2) / max(w - border, 1e-9)))
    py = min(1.0, max(0.0, (float(c[:, 1].mean()) - border / 2) / max(h - border, 1e-9)))
    size = min(1.0, math.sqrt(area / (w * h)))
    return PoseDescriptor(px, py, size, skew)


# the spread each axis needs for full coverage (ROS camera_calibration's param_ranges)
COVERAGE_RANGES = {"x": 0.7, "y": 0.7, "size": 0.4, "skew": 0.5}
RECOMMENDED_PAIRS = 20  # enough views for a stable solve with a 5-coefficient distortion model
ENOUGH_PAIRS = 40  # ROS unlocks calibration at this many samples even without full coverage
NEW_POSE_DISTANCE = 0.2  # ROS's minimum descriptor distance for a sample to count as new


@dataclass(frozen=True)
class AxisCoverage:
    """Spread of one pose axis over the kept samples: min, max (0..1) and progress (0..1)."""

    name: str
    low: float
    high: float
    progress: float


@dataclass(frozen=True)
class Coverage:
    """Coverage of a set of detections, for the capture tab's bars."""

    axes: tuple[AxisCoverage, ...]  # x, y, size, skew in that order
    count: int
    recommended_count: int
    min_count: int
    ready: bool  # enough pairs, and coverage full or samples plenty

    @property
    def progress(self) -> float:
        """Overall progress 0..1: the weakest axis, and the count towards the recommendation."""
        axes = min((a.progress for a in self.axes), default=0.0)
        return min(axes, self.count / self.recommended_count)

    def missing(self) -> list[str]:
        """Short hints on what to do next, for the user."""
        hints = {"x": "move the board left and right", "y": "move the board up and down",
                 "size": "bring the board closer and farther", "skew": "tilt the board more"}
        out = [hints[a.name] for a in self.axes if a.progress < 1.0]
        if self.count < self.recommended_count:
            out.append(f"capture {self.recommended_count - self.count} more pairs")
        return out


def coverage(poses: Sequence[PoseDescriptor], min_count: int = 5,
             recommended_count: int = RECOMMENDED_PAIRS) -> Coverage:
    """Summarise the spread of pose descriptors per axis as ROS camera_calibration does."""
    arr = np.array([p.as_tuple() for p in poses], np.float64).reshape(-1, 4)
    axes = []
    for i, (name, need) in enumerate(COVERAGE_RANGES.items()):
        if len(arr):
            lo, hi = float(arr[:, i].min()), float(arr[:, i].max())
            if name in ("size", "skew"):
                lo = 0.0  # ROS counts size and skew from zero: only the largest matters
            axes.append(AxisCoverage(name, lo, hi, min(1.0, (hi - lo) / need)))
        else:
            axes.append(AxisCoverage(name, 0.0, 0.0, 0.0))
    full = all(a.progress >= 1.0 for a in axes)
    n = len(poses)
    ready = n >= min_count and (full or n >= ENOUGH_PAIRS)
    return Coverage(tuple(axes), n, recommended_count, min_count, ready)


def is_new_pose(pose: PoseDescriptor, kept: Sequence[PoseDescriptor],
                min_distance: float = NEW_POSE_DISTANCE) -> bool:
    """True when `pose` differs enough from every kept pose to be worth keeping."""
    return all(pose.distance(k) > min_distance for k in kept)


def pair_pose(pair: PairDetection, board: BoardSpec) -> PoseDescriptor | None:
    """The pose descriptor of a usable pair (from the left camera, as ROS does), else None."""
    if not pair.found:
        return None
    return pair.left.pose(board)  # type: ignore[union-attr]
