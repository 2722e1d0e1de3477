"""Chessboard detection: subpixel accuracy, pairs, parallel runs with progress and cancel, coverage."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import (
    Cancelled,
    Detection,
    PairInput,
    PoseDescriptor,
    coverage,
    detect_board,
    detect_pair,
    detect_pairs,
    is_new_pose,
    make_pair,
    pose_descriptor,
)
from stereo_gui.core.errors import InputError

BOARD = BoardSpec(9, 6, 25.0)
SS = 8  # supersampling of the synthetic board


def synthetic_board(size=(320, 240), square_px=21.3, origin=(57.4, 43.7), noise=0.0, seed=0):
    """An axis-aligned chessboard rendered at 8x and area-averaged down (anti-aliased), and the
    true inner-corner positions in OpenCV pixel coordinates (pixel centres at integers)."""
    w, h = size
    hi = np.full((h * SS, w * SS), 230, np.uint8)
    sq = square_px * SS
    ox, oy = origin[0] * SS, origin[1] * SS  # edge coordinates (pixel corner at 0) of the board
    for r in range(BOARD.rows + 1):
        for c in range(BOARD.cols + 1):
            if (r + c) % 2 == 0:
                x0, y0 = ox + c * sq, oy + r * sq
                hi[int(round(y0)):int(round(y0 + sq)), int(round(x0)):int(round(x0 + sq))] = 25
    img = cv2.resize(hi, (w, h), interpolation=cv2.INTER_AREA).astype(np.float64)
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, img.shape)
    img = np.clip(img, 0, 255).astype(np.uint8)
    # inner corner (c, r) sits at edge coordinate origin + (c + 1, r + 1) * square
    cs, rs = np.meshgrid(np.arange(1, BOARD.cols + 1), np.arange(1, BOARD.rows + 1))
    ex = np.round(ox + cs * sq) / SS  # square edges fall where the drawing rounded them
    ey = np.round(oy + rs * sq) / SS
    truth = np.stack([ex.ravel(), ey.ravel()], axis=1) - 0.5
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), truth


def _sorted_like(corners, truth):
    """Corners reordered to the truth's order when the detector numbered from the other end."""
    if np.linalg.norm(corners[0] - truth[0]) > np.linalg.norm(corners[-1] - truth[0]):
        return corners[::-1]
    return corners


def test_classic_detection_is_subpixel_accurate():
    img, truth = synthetic_board(noise=2.0)
    det = detect_board(img, BOARD)
    assert det is not None and det.method == "classic"
    assert det.corners.shape == (54, 2) and det.corners.dtype == np.float32
    err = np.linalg.norm(_sorted_like(det.corners, truth) - truth, axis=1)
    assert err.max() < 0.15, err.max()
    assert err.mean() < 0.1, err.mean()
    assert det.image_size == (320, 240)


def test_sb_detection_also_finds_the_board():
    """findChessboardCornersSB finds it too, less accurately here (why classic is the default)."""
    img, truth = synthetic_board()
    det = detect_board(img, BOARD, method="sb")
    assert det is not None and det.method == "sb"
    err = np.linalg.norm(_sorted_like(det.corners, truth) - truth, axis=1)
    assert err.mean() < 0.35 and err.max() < 0.75


def test_no_board_gives_none_and_unknown_method_raises():
    blank = np.full((120, 160, 3), 128, np.uint8)
    assert detect_board(blank, BOARD) is None
    with pytest.raises(ValueError):
        detect_board(blank, BOARD, method="magic")


def test_pair_counts_only_with_board_in_both_images():
    img, _ = synthetic_board()
    blank = np.full_like(img, 128)
    p = detect_pair("7", img, blank, BOARD, left_file="left7.png", right_file="right7.png")
    assert not p.found and p.left is not None and p.right is None
    assert p.reason == "chessboard not found in the right image (right7.png)"
    both = detect_pair("8", blank, blank, BOARD)
    assert "left image" in both.reason and "right image" in both.reason
    ok = detect_pair("9", img, img, BOARD)
    assert ok.found and ok.reason == ""


def test_pair_of_different_sizes_is_refused_naming_files():
    img, _ = synthetic_board()
    with pytest.raises(InputError, match="left3.png is 320x240 but right3.png is 160x120"):
        detect_pair("3", img, img[:120, :160], BOARD, left_file="left3.png", right_file="right3.png")


def test_right_corners_are_numbered_like_the_left():
    img, _ = synthetic_board()
    det = detect_board(img, BOARD)
    size = (img.shape[1], img.shape[0])
    for right in (det.reversed(), det):  # numbered from the other end, or the same one
        pair = make_pair("p", det, right, size, BOARD)
        assert np.array_equal(pair.right.corners, det.corners)


def _inputs(n):
    img, _ = synthetic_board()
    blank = np.full_like(img, 128)
    return [PairInput(str(i), img if i % 3 else blank, (lambda im=img: im)) for i in range(n)]


def test_detect_pairs_keeps_order_reports_progress_and_matches_serial():
    calls = []
    par = detect_pairs(_inputs(6), BOARD, workers=2, progress=lambda d, t, s: calls.append((d, t)))
    ser = detect_pairs(_inputs(6), BOARD, workers=1)
    assert [p.name for p in par] == [str(i) for i in range(6)]
    assert [p.found for p in par] == [bool(i % 3) for i in range(6)]
    assert [d for d, _ in calls] == list(range(1, 7)) and all(t == 6 for _, t in calls)
    for a, b in zip(par, ser):
        if a.found:
            assert np.array_equal(a.left.corners, b.left.corners)


def test_detect_pairs_accepts_tuples():
    img, _ = synthetic_board()
    out = detect_pairs([("a", img, img)], BOARD)
    assert out[0].name == "a" and out[0].found


def test_cancel_before_and_during_detection():
    ev = threading.Event()
    ev.set()
    with pytest.raises(Cancelled):
        detect_pairs(_inputs(4), BOARD, cancel=ev)
    ev2 = threading.Event()
    with pytest.raises(Cancelled):
        detect_pairs(_inputs(8), BOARD, cancel=ev2, workers=2,
                     progress=lambda d, t, s: ev2.set() if d == 2 else None)
    stop = {"now": False}
    with pytest.raises(Cancelled):
        detect_pairs(_inputs(4), BOARD, cancel=lambda: stop["now"], workers=1,
                     progress=lambda d, t, s: stop.update(now=True))


def test_pose_descriptor_of_centred_frontal_board():
    w, h = 640, 480
    # a frontal board centred in the image, covering a quarter of its area
    bw, bh = w / 2, h / 2
    xs = np.linspace(w / 2 - bw / 2, w / 2 + bw / 2, BOARD.cols)
    ys = np.linspace(h / 2 - bh / 2, h / 2 + bh / 2, BOARD.rows)
    corners = np.stack(np.meshgrid(xs, ys), axis=2).reshape(-1, 2).astype(np.float32)
    p = pose_descriptor(corners, BOARD, (w, h))
    assert p.x == pytest.approx(0.5, abs=1e-6) and p.y == pytest.approx(0.5, abs=1e-6)
    assert p.size == pytest.approx(0.5, abs=1e-6)
    assert p.skew == pytest.approx(0.0, abs=1e-6)
    # the same board in the top-left corner of the image
    q = pose_descriptor(corners - np.float32([w / 4, h / 4]), BOARD, (w, h))
    assert q.x < 0.1 and q.y < 0.1  # ROS's formula keeps a margin of half the board's size
    # a sheared board has skew
    sheared = corners.copy()
    sheared[:, 0] += (sheared[:, 1] - h / 2) * 0.5
    assert pose_descriptor(sheared, BOARD, (w, h)).skew > 0.5
    det = Detection(corners, (w, h), "classic")
    assert det.pose(BOARD) == p


def test_coverage_summary():
    empty = coverage([])
    assert empty.count == 0 and not empty.ready and empty.progress == 0.0
    assert [a.name for a in empty.axes] == ["x", "y", "size", "skew"]
    poses = [PoseDescriptor(0.1, 0.1, 0.2, 0.1), PoseDescriptor(0.9, 0.9, 0.5, 0.6)]
    poses += [PoseDescriptor(0.5, 0.5, 0.3, 0.3)] * 3
    cov = coverage(poses)
    x = cov.axes[0]
    assert (x.low, x.high) == (0.1, 0.9) and x.progress == 1.0
    assert cov.axes[2].progress == 1.0  # size counts from 0: 0.5 / 0.4 capped at 1
    assert cov.ready and cov.count == 5
    narrow = coverage([PoseDescriptor(0.5, 0.5, 0.2, 0.1)] * 6)
    assert not narrow.ready and narrow.axes[0].progress == 0.0
    assert "move the board left and right" in narrow.missing()
    assert coverage([PoseDescriptor(0.5, 0.5, 0.2, 0.1)] * 40).ready  # plenty of samples


def test_is_new_pose():
    a = PoseDescriptor(0.5, 0.5, 0.3, 0.2)
    assert is_new_pose(a, [])
    assert not is_new_pose(PoseDescriptor(0.55, 0.5, 0.3, 0.2), [a])
    assert is_new_pose(PoseDescriptor(0.8, 0.5, 0.3, 0.2), [a])
