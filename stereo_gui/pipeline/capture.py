"""The Capture tab's frame processor (runs in the frame worker's thread): find the chessboard in
both images of a live frame and hand the tab RGB images to draw; and the job that reads a
session's saved pairs back for coverage and thumbnails. No Qt here."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import (
    Detection,
    PairDetection,
    PoseDescriptor,
    detect_board,
    detect_pair,
    make_pair,
    pair_pose,
)
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.util import to_gray
from stereo_gui.files.pairs import load_image
from stereo_gui.pipeline.jobs import Progress
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class CaptureOutput:
    """What the capture processor makes of a frame: RGB images for display and the detection."""

    left_rgb: np.ndarray  # HxWx3 uint8, C-contiguous
    right_rgb: np.ndarray
    detection: PairDetection
    board: BoardSpec

    @property
    def pose(self) -> PoseDescriptor | None:
        return pair_pose(self.detection, self.board)


def _maybe_board(gray: np.ndarray, board: BoardSpec) -> bool:
    """A fast test whether a chessboard may be in the image (a full search without a board takes
    a few hundred ms; this quick check a few ms), so live frames without a board stay cheap.
    The other targets' detectors are quick to say no by themselves."""
    if board.target != "chessboard":
        return True
    ok, _ = cv2.findChessboardCorners(
        gray, board.pattern_size,
        flags=cv2.CALIB_CB_FAST_CHECK | cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    return bool(ok)


def detect_live(frame: StereoFrame, board: BoardSpec) -> CaptureOutput:
    """Detect the target in both images of a live frame (subpixel where found)."""
    size = frame.size
    dets: list[Detection | None] = []
    for img in (frame.left, frame.right):
        gray = to_gray(img)
        dets.append(detect_board(gray, board) if _maybe_board(gray, board) else None)
    left, right = dets
    # same rules as core.detect_pair: both cameras number the grid from the same end, and a
    # partly visible target counts when they share enough of its points
    pair = make_pair(f"frame {frame.index}", left, right, size, board)
    return CaptureOutput(display_rgb(frame.left), display_rgb(frame.right), pair, board)


def make_capture_processor(board: BoardSpec):
    """The frame worker processor of the capture tab, for `board`."""
    def process(frame: StereoFrame) -> CaptureOutput:
        return detect_live(frame, board)
    return process


def display_rgb(bgr: np.ndarray) -> np.ndarray:
    """A BGR (or gray) image as C-contiguous RGB uint8 for pyqtgraph."""
    if bgr.ndim == 2:
        return np.ascontiguousarray(np.repeat(bgr[:, :, None], 3, axis=2))
    return np.ascontiguousarray(bgr[:, :, 2::-1])


def session_scan_job(pairs, board: BoardSpec, thumb_size: tuple[int, int]):
    """A JobWorker job over a session's saved pairs (files.session pairs): detect the board in
    each (for coverage) and shrink both images to `thumb_size` (w, h) px for thumbnails.

    Returns [(name, PairDetection or None, [left, right] BGR or None)]; an unreadable pair is
    logged and listed with None.
    """

    def job(cancel):
        out = []
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
