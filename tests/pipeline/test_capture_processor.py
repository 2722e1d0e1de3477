"""The Capture tab's frame processor and capture rules without Qt: the board in both images of
a simulated frame; when a live frame is frozen, taken automatically, or only shown."""

import dataclasses

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.pipeline.capture import (
    STEADY_FRAMES,
    STEADY_PX,
    CaptureAction,
    CaptureOutput,
    CaptureRules,
    detect_live,
    display_rgb,
    make_capture_processor,
)
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

SHOW, FREEZE, SAVE = CaptureAction.SHOW, CaptureAction.FREEZE, CaptureAction.SAVE


@pytest.fixture(scope="module")
def board_frame():
    """A simulated frame in which both cameras see the board."""
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    try:
        for _ in range(30):
            frame = src.read()
            if proc(frame).detection.found:
                return frame
    finally:
        src.close()
    pytest.fail("the simulated rig never showed the board to both cameras")


@pytest.fixture(scope="module")
def board_output(board_frame) -> CaptureOutput:
    """The processed frame in which both cameras see the board."""
    return make_capture_processor(BoardSpec())(board_frame)


def _moved(out: CaptureOutput, dx_px: float) -> CaptureOutput:
    """The same output with the left corners shifted by dx_px."""
    left = dataclasses.replace(out.detection.left, corners=out.detection.left.corners + dx_px)
    return dataclasses.replace(out, detection=dataclasses.replace(out.detection, left=left))


def _without_right(out: CaptureOutput) -> CaptureOutput:
    return dataclasses.replace(out, detection=dataclasses.replace(out.detection, right=None))


def test_board_found_in_both_images_with_rgb_views():
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    try:
        outs = [proc(src.read()) for _ in range(12)]
    finally:
        src.close()
    found = [o for o in outs if o.detection.found]
    assert found, "the simulated rig never showed the board to both cameras"
    o = found[0]
    assert isinstance(o, CaptureOutput) and o.pose is not None
    assert o.detection.left.corners.reshape(-1, 2).shape == (BoardSpec().cols * BoardSpec().rows, 2)
    assert o.left_rgb.flags.c_contiguous and o.left_rgb.shape == (480, 640, 3)


def test_display_rgb_swaps_channels_and_expands_gray():
    bgr = np.zeros((2, 3, 3), np.uint8)
    bgr[..., 0] = 10  # blue
    assert (display_rgb(bgr)[..., 2] == 10).all() and display_rgb(bgr).flags.c_contiguous
    gray = np.full((2, 3), 7, np.uint8)
    assert display_rgb(gray).shape == (2, 3, 3) and (display_rgb(gray) == 7).all()


def test_manual_capture_freezes_once_per_pose(board_output):
    rules = CaptureRules()
    no_saved = list
    assert rules.step(board_output, False, no_saved, True).action is FREEZE
    again = rules.step(board_output, False, no_saved, True)
    assert again.action is SHOW and "new pose" in again.prompt
    hint = rules.step(_without_right(board_output), False, no_saved, True)
    assert hint.action is SHOW and "Only the left camera" in hint.prompt
    # the board left a view: the same pose may be frozen again
    assert rules.step(board_output, False, no_saved, True).action is FREEZE


def test_automatic_capture_waits_for_a_steady_new_pose_and_a_session(board_output):
    rules = CaptureRules()
    steps = [rules.step(board_output, True, list, True) for _ in range(STEADY_FRAMES)]
    assert [s.action for s in steps] == [SHOW] * (STEADY_FRAMES - 1) + [SAVE]
    assert "hold the board still" in steps[0].prompt and "Pair taken" in steps[-1].prompt
    # moving more than STEADY_PX between frames is not steady
    rules = CaptureRules()
    moving = [rules.step(_moved(board_output, k * 2 * STEADY_PX), True, list, True).action
              for k in range(STEADY_FRAMES + 2)]
    assert SAVE not in moving
    # a pose already saved, or no session: nothing is taken
    rules = CaptureRules()
    seen = [rules.step(board_output, True, lambda: [board_output.pose], True)
            for _ in range(STEADY_FRAMES)]
    assert {s.action for s in seen} == {SHOW} and "already captured" in seen[-1].prompt
    rules = CaptureRules()
    no_session = [rules.step(board_output, True, list, False) for _ in range(STEADY_FRAMES)]
    assert no_session[-1].action is SHOW and "needs a session" in no_session[-1].prompt


def test_a_pair_with_a_misplaced_point_is_neither_frozen_nor_taken(board_frame):
    """A speck beside a corner pulls it aside: the processor says so, and neither manual nor
    automatic capture takes the pair (auto-capture kept such a pair before)."""
    import cv2

    from stereo_gui.sources.base import StereoFrame

    board = BoardSpec()
    clean = detect_live(board_frame, board)
    assert clean.detection.found and clean.misplaced == ""
    x, y = clean.detection.left.corners[len(clean.detection.left.corners) // 2]
    left = board_frame.left.copy()
    cv2.circle(left, (int(round(x + 3)), int(round(y + 1))), 2, (255, 255, 255), -1)
    f = board_frame
    out = detect_live(StereoFrame(left, f.right, f.t_left, f.t_right, f.index), board)
    assert out.detection.found
    assert "left image" in out.misplaced and "from where its neighbours put it" in out.misplaced
    rules = CaptureRules()
    manual = rules.step(out, False, list, True)
    assert manual.action is SHOW and manual.prompt.startswith("Not taken: a point")
    rules = CaptureRules()
    auto = [rules.step(out, True, list, True) for _ in range(2 * STEADY_FRAMES)]
    assert {s.action for s in auto} == {SHOW}
    rules = CaptureRules()
    assert [rules.step(clean, True, list, True) for _ in range(STEADY_FRAMES)][-1].action is SAVE


def _at(out: CaptureOutput, t_s: float) -> CaptureOutput:
    return dataclasses.replace(out, time_s=t_s)


def test_steadiness_is_time_not_frame_count_when_frames_come_slowly(board_output):
    """At a few processed frames a second, four frames would mean a second of stillness; the
    board must hold still for STEADY_S (or STEADY_FRAMES frames), whichever comes first."""
    from stereo_gui.pipeline.capture import STEADY_MAX_S, STEADY_S

    gap = 1.5 * STEADY_S
    rules = CaptureRules()
    steps = [rules.step(_at(board_output, k * gap), True, list, True).action for k in range(2)]
    assert steps == [SHOW, SAVE]  # two frames STEADY_S apart, the corners still
    rules = CaptureRules()  # moving STEADY_PX or more in that time: not still
    moved = [rules.step(_at(_moved(board_output, k * STEADY_PX), k * gap), True, list,
                        True).action for k in range(4)]
    assert SAVE not in moved
    rules = CaptureRules()  # frames close together: STEADY_FRAMES of them, as before
    quick = [rules.step(_at(board_output, k * 0.001), True, list, True).action
             for k in range(STEADY_FRAMES)]
    assert quick == [SHOW] * (STEADY_FRAMES - 1) + [SAVE]
    rules = CaptureRules()  # a frame from long ago (a pause) says nothing about now
    old = [rules.step(_at(board_output, t), True, list, True).action
           for t in (0.0, 2 * STEADY_MAX_S)]
    assert old == [SHOW, SHOW]


def test_the_processor_skips_the_quick_check_while_the_board_stays_in_view(monkeypatch):
    """The pre-check costs more than the search when a board is in view:
    once found, the next frame is searched at once."""
    import stereo_gui.pipeline.capture as capture

    calls = []
    real = capture.may_show_board
    monkeypatch.setattr(capture, "may_show_board", lambda g, b: calls.append(1) or real(g, b))
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=50)
    proc = make_capture_processor(BoardSpec())
    try:
        first = proc(src.read())
        assert first.detection.found and len(calls) == 2  # both images checked first
        second = proc(src.read())
    finally:
        src.close()
    assert second.detection.found and len(calls) == 2  # not again: the board was in view
    assert second.time_s is not None and second.time_s >= first.time_s
