"""The Capture tab's frame processor (runs in the frame worker's thread): find the chessboard in
both images of a live frame and hand the tab RGB images to draw; and the job that reads a
session's saved pairs back for coverage and thumbnails. No Qt here."""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from enum import StrEnum

import cv2
import numpy as np

from stereo_gui.core.board import TARGET_NAMES, BoardSpec
from stereo_gui.core.corner_check import check_points
from stereo_gui.core.coverage import regions_in_words
from stereo_gui.core.detect import (
    NEW_POSE_DISTANCE,
    Detection,
    PairDetection,
    PoseDescriptor,
    detect_board,
    detect_pair,
    is_new_pose,
    make_pair,
    pair_pose,
)
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.jobs import JobControl, Progress
from stereo_gui.core.timing import SkewStats
from stereo_gui.core.util import to_gray
from stereo_gui.files.pairs import load_image
from stereo_gui.files.session import PairEntry
from stereo_gui.pipeline.images import display_rgb
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

STEADY_FRAMES = 4  # automatic capture: the board must hold still over this many frames
STEADY_PX = 2.0  # ... moving its corners less than this, px
STEADY_S = 0.1  # ... or over frames this long apart, s (when frames are processed slowly)
STEADY_MAX_S = 0.5  # frames older than this do not count (a pause, a stalled source), s
# the board may move at most this much between the two cameras' pictures (the skew), px:
# about what a corner is found to, so that the skew adds no error of its own to a pair
STILL_ACROSS_SKEW_PX = 0.25


@dataclass(frozen=True, eq=False)
class CaptureOutput:
    """What the capture processor makes of a frame: RGB images for display and the detection."""

    left_rgb: np.ndarray  # HxWx3 uint8, C-contiguous
    right_rgb: np.ndarray
    detection: PairDetection
    board: BoardSpec
    time_s: float | None = None  # the frame's capture time (left camera), s; None if unknown
    time_right_s: float | None = None  # the right camera's capture time, s; None if unknown
    # why the pair cannot be taken although both cameras see the board: a point of the target
    # lies off where its neighbours put it (core.corner_check); "" when every point agrees
    misplaced: str = ""

    @property
    def skew_s(self) -> float | None:
        """How much later the right camera took its picture than the left, s."""
        if self.time_s is None or self.time_right_s is None:
            return None
        return float(self.time_right_s - self.time_s)

    @property
    def pose(self) -> PoseDescriptor | None:
        return pair_pose(self.detection, self.board)


def may_show_board(gray: np.ndarray, board: BoardSpec) -> bool:
    """A quicker test whether a chessboard may be in the image, so live frames without a board
    stay cheaper: a full search that finds nothing takes more than twice as long as this check.
    With a board in view the check costs more than the search itself, so `detect_live` skips
    it while the board was found in the frame before. The other targets' detectors are quick to
    say no by themselves."""
    if board.target != "chessboard":
        return True
    ok, _ = cv2.findChessboardCorners(
        gray, board.pattern_size,
        flags=cv2.CALIB_CB_FAST_CHECK | cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    return bool(ok)


def detect_live(frame: StereoFrame, board: BoardSpec,
                seen: tuple[bool, bool] = (False, False)) -> CaptureOutput:
    """Detect the target in both images of a live frame (subpixel where found). `seen` says in
    which images (left, right) the board was found in the frame before: those are searched at
    once, without the quick pre-check (a board in view rarely leaves it between two frames)."""
    size = frame.size
    dets: list[Detection | None] = []
    for img, was_seen in zip((frame.left, frame.right), seen, strict=True):
        gray = to_gray(img)
        dets.append(detect_board(gray, board) if was_seen or may_show_board(gray, board) else None)
    left, right = dets
    # same rules as core.detect_pair: both cameras number the grid from the same end, and a
    # partly visible target counts when they share enough of its points
    pair = make_pair(f"frame {frame.index}", left, right, size, board)
    return CaptureOutput(display_rgb(frame.left), display_rgb(frame.right), pair, board,
                         float(frame.t_left), float(frame.t_right),
                         misplaced_point(pair, board) if pair.found else "")


def misplaced_point(pair: PairDetection, board: BoardSpec) -> str:
    """Why a pair both cameras see must not be taken: a point of the target that lies off where
    its neighbours put it (core.corner_check), in words; "" when every point agrees."""
    for side in ("left", "right"):
        det = getattr(pair, side)
        check = check_points(det, board) if det is not None else None
        if check is not None and check.misplaced:
            x, y = check.worst_xy
            return (f"a point of the target in the {side} image, at ({x:.0f}, {y:.0f}), lies "
                    f"{check.worst_px:.2f} px from where its neighbours put it (the others "
                    f"{check.median_px:.2f} px): glare, blur, a speck or a bent board?")
    return ""


def make_capture_processor(board: BoardSpec) -> Callable[[StereoFrame], CaptureOutput]:
    """The frame worker processor of the capture tab, for `board` (it runs in the worker's one
    processing thread, and remembers in which images the board was found last)."""
    seen = [False, False]

    def process(frame: StereoFrame) -> CaptureOutput:
        out = detect_live(frame, board, (seen[0], seen[1]))
        seen[0] = out.detection.left is not None
        seen[1] = out.detection.right is not None
        return out
    return process


# a scanned pair: (name, PairDetection or None, [left, right] thumbnails BGR or None)
ScannedPair = tuple[str, PairDetection | None, list[np.ndarray] | None]


def session_scan_job(pairs: Sequence[PairEntry], board: BoardSpec, thumb_size: tuple[int, int]
                     ) -> Callable[[JobControl], Generator[Progress, None, list[ScannedPair]]]:
    """A JobWorker job over a session's saved pairs (files.session pairs): detect the board in
    each (for coverage) and shrink both images to `thumb_size` (w, h) px for thumbnails.

    Returns [(name, PairDetection or None, [left, right] BGR or None)]; an unreadable pair is
    logged and listed with None.
    """

    def job(cancel: JobControl) -> Generator[Progress, None, list[ScannedPair]]:
        out: list[ScannedPair] = []
        for i, p in enumerate(pairs):
            cancel.check()
            yield Progress(i, len(pairs), f"reading pair {p.name}")
            try:
                left, right = load_image(p.left), load_image(p.right)
                det = detect_pair(p.name, left, right, board)
                small = [cv2.resize(im, thumb_size, interpolation=cv2.INTER_AREA)
                         for im in (left, right)]
            except (StereoGuiError, ValueError, cv2.error) as exc:
                log.warning("pair %s: %s", p.name, exc)
                det, small = None, None
            out.append((p.name, det, small))
        return out

    return job


class CaptureAction(StrEnum):
    """What the Capture tab does with a live frame."""

    SHOW = "show"  # go on showing live frames
    FREEZE = "freeze"  # hold the pair for review
    SAVE = "save"  # take it (automatic capture)


@dataclass(frozen=True)
class CaptureStep:
    """What the Capture tab does with a live frame (`action`); `prompt` is what the tab says to
    the technician ("" for FREEZE: the review prompt says it)."""

    action: CaptureAction
    prompt: str


def live_hint(det: PairDetection, board: BoardSpec | None = None) -> str:
    """What to do when the board is not in both views (or too little of it is shared)."""
    if det.left is not None and det.right is not None:  # a partial view, too little shared
        return f"Both cameras see part of the board: {det.reason}"
    if det.left is None and det.right is None:
        if board is not None and board.partial:
            return "Hold the ChArUco board so that both cameras see a good part of it"
        what = TARGET_NAMES[board.target] if board is not None else "chessboard"
        return f"Hold the {what} so that both cameras see all of it"
    side = "right" if det.right is None else "left"
    return f"Only the {'left' if side == 'right' else 'right'} camera sees the board: " \
           f"move it into the {side} camera's view"


class CaptureRules:
    """When a live frame becomes a pair (the Capture tab's rules, without Qt).

    A pair with a point of the target off where its neighbours put it is never frozen nor
    taken (`CaptureOutput.misplaced`). Manual capture freezes a pair that both cameras see,
    unless its pose is close to the one
    reviewed last (until the board leaves a view). Automatic capture takes a pair once the board
    has held still (corners moving less than STEADY_PX over STEADY_FRAMES frames, or over frames
    STEADY_S apart when fewer are processed: the board must hold still for as long whatever the
    processing rate, or a slow machine would ask for a stillness a hand-held board, or the
    simulated rig's board resting only a moment at each pose, hardly ever gives) in a pose that
    differs from those saved, or that reaches an image region still empty (then a smaller
    difference will do, though not the very same view).

    Two webcams take their pictures at different moments (the skew, right time minus left
    time). Automatic capture keeps a pair only when the board stood still across both
    pictures: both cameras' corners steady over a stretch of time at least as long as the
    skew, and the board's speed over it moving it less than STILL_ACROSS_SKEW_PX in the skew's
    time. While the source's typical skew (`timing`, core.timing.SkewStats, kept current by the
    tab) exceeds a third of a frame interval and the board moves, the prompt says so, and a
    manual pair is not frozen until the board holds still.
    """

    def __init__(self) -> None:
        # (frame time s or None, left corners (N, 2)) of the recent frames, oldest first
        self.recent_corners: deque[tuple[float | None, np.ndarray]] = deque(maxlen=16)
        # the same for the right camera: (its frame time s or None, right corners (N, 2))
        self.recent_right: deque[tuple[float | None, np.ndarray]] = deque(maxlen=16)
        self.last_reviewed_pose: PoseDescriptor | None = None
        self.timing: SkewStats | None = None  # of the source now, None when unknown
        self._last_seen: np.ndarray | None = None  # left corners of the frame before

    def reset_steadiness(self) -> None:
        """Forget the recent corners (the board, the mode or the view changed)."""
        self.recent_corners.clear()
        self.recent_right.clear()
        self._last_seen = None

    def _skew_note(self) -> str:
        t = self.timing
        if t is None or not t.too_large:
            return ""
        return (f" The cameras take their pictures {abs(t.median_ms):.0f} ms apart (more than a "
                "third of a frame): a moving board is seen at two moments.")

    def _moving(self, out: CaptureOutput) -> bool | None:
        """Whether the board moved since the frame before (left corners, STEADY_PX); None
        when there is no frame before to tell."""
        now = out.detection.left.corners.reshape(-1, 2)  # type: ignore[union-attr]
        before, self._last_seen = self._last_seen, now
        if before is None:
            return None
        return before.shape != now.shape or float(np.abs(before - now).max()) >= STEADY_PX

    def step(self, out: CaptureOutput, auto: bool,
             saved_poses: Callable[[], list[PoseDescriptor]], have_session: bool,
             board: BoardSpec | None = None,
             fills: Callable[[PairDetection], dict[str, list[str]]] | None = None,
             empty_regions: Callable[[], dict[str, list[str]]] | None = None) -> CaptureStep:
        """The step for live frame `out`; `saved_poses()` gives the poses of the saved pairs,
        `fills(detection)` the regions (per camera) still empty that the detection reaches and
        `empty_regions()` those still empty (core.coverage's readiness)."""
        det = out.detection
        if not det.found:
            self.reset_steadiness()
            if det.left is None or det.right is None:
                self.last_reviewed_pose = None  # the board left a view: the next pose is new
            return CaptureStep(CaptureAction.SHOW, live_hint(det, board))
        if out.misplaced:  # neither frozen for review nor taken: it would spoil the solve
            self.recent_corners.clear()
            return CaptureStep(CaptureAction.SHOW,
                               f"Not taken: {out.misplaced} Move or turn the board a little")
        pose = out.pose
        moving = self._moving(out)
        if moving is not False and self._skew_note() and not auto:
            # (a first sight cannot tell: one more frame says whether the board holds still)
            return CaptureStep(CaptureAction.SHOW, "Hold the board still." + self._skew_note())
        if auto:
            assert pose is not None  # (the board found in both images: pair_pose gives one)
            return self._auto_step(out, pose, saved_poses(), have_session,
                                   fills(det) if fills is not None else {},
                                   empty_regions if empty_regions is not None else dict)
        if (self.last_reviewed_pose is not None and pose is not None
                and pose.distance(self.last_reviewed_pose) < NEW_POSE_DISTANCE / 2):
            return CaptureStep(CaptureAction.SHOW,
                               "Move the board to a new pose (or out of view and back)")
        self.last_reviewed_pose = pose
        return CaptureStep(CaptureAction.FREEZE, "")

    def _steady(self, skew_s: float | None = None) -> bool:
        """The board held still in both cameras' images (see the class doc)."""
        skew = abs(skew_s or 0.0)
        left = _steady_over(self.recent_corners, skew)
        if left is None:
            return False
        if len(self.recent_right) != len(self.recent_corners):
            return True  # (no right corners kept: the left camera's word)
        right = _steady_over(self.recent_right, skew)
        if right is None:
            return False
        # the board's speed over the stretch, times the skew: how far it moved between the
        # two pictures of the pair
        return skew == 0.0 or max(left, right) * skew < STILL_ACROSS_SKEW_PX

    def _auto_step(self, out: CaptureOutput, pose: PoseDescriptor,
                   saved: list[PoseDescriptor], have_session: bool,
                   fills: dict[str, list[str]],
                   empty_regions: Callable[[], dict[str, list[str]]]) -> CaptureStep:
        corners = out.detection.left.corners.reshape(-1, 2)  # type: ignore[union-attr]
        self.recent_corners.append((out.time_s, corners))
        skew = out.skew_s
        if skew is not None and abs(skew) <= STEADY_MAX_S:
            self.recent_right.append((out.time_right_s,
                                      out.detection.right.corners.reshape(-1, 2)))  # type: ignore[union-attr]
        else:  # no right time, or one from another clock: the left camera's word alone
            skew = None
            self.recent_right.clear()
        steady = self._steady(skew)
        distinct = is_new_pose(pose, saved, NEW_POSE_DISTANCE / 4)  # not the very same view
        new = (any(fills.values()) and distinct) or is_new_pose(pose, saved)
        if not (new and distinct):
            fills = {}
        if not new:
            where = regions_in_words(empty_regions())
            return CaptureStep(CaptureAction.SHOW, "Pose already captured: " + (
                f"move the board to {where} (not yet covered)" if where
                else "move or tilt the board somewhere new"))
        if not steady:
            reach = f" reaching {regions_in_words(fills)}" if any(fills.values()) else ""
            return CaptureStep(CaptureAction.SHOW, f"New pose{reach}: hold the board still…"
                               + self._skew_note())
        if not have_session:
            return CaptureStep(CaptureAction.SHOW,
                               "Automatic capture needs a session: choose New session…")
        self.recent_corners.clear()
        return CaptureStep(CaptureAction.SAVE, "Pair taken. Move the board to the next pose")


def _steady_over(recent: deque[tuple[float | None, np.ndarray]],
                 min_span_s: float = 0.0) -> float | None:
    """Whether the newest corners of `recent` ((time s or None, corners) oldest first) moved
    less than STEADY_PX from each of the frames before them, back over STEADY_FRAMES frames or
    STEADY_S seconds, whichever comes first, and over at least `min_span_s`: the corners' speed
    over that stretch (px/s; 0 without times), or None when they did not hold still."""
    if not recent:
        return None
    t_now, now = recent[-1]
    frames = 1
    moved = 0.0
    for t, c in reversed(list(recent)[:-1]):
        dt = None if (t is None or t_now is None) else t_now - t
        if dt is not None and dt > STEADY_MAX_S:
            return None
        if c.shape != now.shape:
            return None
        moved = max(moved, float(np.abs(c - now).max()))
        if moved >= STEADY_PX:
            return None
        frames += 1
        spanned = dt is None or dt >= min_span_s
        if spanned and (frames >= STEADY_FRAMES or (dt is not None and dt >= STEADY_S)):
            return moved / dt if dt else 0.0
    return None
