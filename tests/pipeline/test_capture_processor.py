"""The Capture tab's frame processor and capture rules without Qt: the board in both images of
a simulated frame; when a live frame is frozen, taken automatically, or only shown."""

import dataclasses

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.pipeline.capture import (
    STEADY_FRAMES,
    STEADY_PX,
    CaptureOutput,
    CaptureRules,
    display_rgb,
    make_capture_processor,
)
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource


@pytest.fixture(scope="module")
def board_output() -> CaptureOutput:
    """A processed simulated frame in which both cameras see the board."""
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    try:
        for _ in range(30):
            out = proc(src.read())
            if out.detection.found:
                return out
    finally:
        src.close()
    pytest.fail("the simulated rig never showed the board to both cameras")


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
    assert rules.step(board_output, False, no_saved, True).action == "freeze"
    again = rules.step(board_output, False, no_saved, True)
    assert again.action == "show" and "new pose" in again.prompt
    hint = rules.step(_without_right(board_output), False, no_saved, True)
    assert hint.action == "show" and "Only the left camera" in hint.prompt
    # the board left a view: the same pose may be frozen again
    assert rules.step(board_output, False, no_saved, True).action == "freeze"


def test_automatic_capture_waits_for_a_steady_new_pose_and_a_session(board_output):
    rules = CaptureRules()
    steps = [rules.step(board_output, True, list, True) for _ in range(STEADY_FRAMES)]
    assert [s.action for s in steps] == ["show"] * (STEADY_FRAMES - 1) + ["save"]
    assert "hold the board still" in steps[0].prompt and "Pair taken" in steps[-1].prompt
    # moving more than STEADY_PX between frames is not steady
    rules = CaptureRules()
    moving = [rules.step(_moved(board_output, k * 2 * STEADY_PX), True, list, True).action
              for k in range(STEADY_FRAMES + 2)]
    assert "save" not in moving
    # a pose already saved, or no session: nothing is taken
    rules = CaptureRules()
    seen = [rules.step(board_output, True, lambda: [board_output.pose], True)
            for _ in range(STEADY_FRAMES)]
    assert {s.action for s in seen} == {"show"} and "already captured" in seen[-1].prompt
    rules = CaptureRules()
    no_session = [rules.step(board_output, True, list, False) for _ in range(STEADY_FRAMES)]
    assert no_session[-1].action == "show" and "needs a session" in no_session[-1].prompt
