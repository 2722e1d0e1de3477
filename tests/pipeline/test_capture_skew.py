"""Automatic capture with two unsynchronised cameras: a pair is kept only when the board stood
still across both pictures, and a moving board is warned about when the skew is large."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.timing import skew_stats
from stereo_gui.pipeline.capture import (
    STILL_ACROSS_SKEW_PX,
    CaptureAction,
    CaptureRules,
    make_capture_processor,
)
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

FPS = 30.0


def _moved_px(rig: SimRig, truth) -> float:
    """How far the board's corners moved in the right image between the left camera's picture
    and the right camera's (the truth's two poses), px."""
    board = rig.config.board
    a = rig.project(truth.pose.corners_left_mm(board), 1)
    b = rig.project(truth.pose_right.corners_left_mm(board), 1)
    return float(np.abs(a - b).max())


def _auto_capture(offset_s: float, tell_rules_the_right_time: bool, frames: int = 200):
    """Run automatic capture over the rig's board frames (frame times i/30 s; the right camera
    `offset_s` later); returns the true movement across the skew of each pair kept."""
    rig = SimRig(RigConfig(supersample=1, time_offset_s=offset_s))
    # a board that rests a while at each pose, as a technician holds it (3 s per move)
    src = SimSource(rig, mode="board", paced=False, fps=FPS, seed=4, frames_per_move=90)
    proc = make_capture_processor(BoardSpec())
    rules = CaptureRules()
    saved, kept = [], []
    try:
        for i in range(frames):
            f = src.read()
            t = i / FPS
            out = dataclasses.replace(proc(f), time_s=t,
                                      time_right_s=t + offset_s if tell_rules_the_right_time
                                      else None)
            step = rules.step(out, True, lambda: saved, True)
            if step.action is CaptureAction.SAVE:
                saved.append(out.pose)
                kept.append(_moved_px(rig, f.truth))
    finally:
        src.close()
    return kept


@pytest.mark.slow
def test_auto_capture_refuses_a_board_that_moved_between_the_two_pictures():
    offset = 0.030
    blind = _auto_capture(offset, tell_rules_the_right_time=False)
    # without the right camera's time, steadiness in the left image lets moving pairs through
    assert any(m > STILL_ACROSS_SKEW_PX for m in blind), blind
    kept = _auto_capture(offset, tell_rules_the_right_time=True)
    assert kept, "the board rests at each pose: some pairs must still be kept"
    assert all(m < 2 * STILL_ACROSS_SKEW_PX for m in kept), kept
    assert np.mean(kept) < np.mean(blind)


def test_a_manual_pair_waits_for_a_still_board_when_the_skew_is_large():
    rig = SimRig(RigConfig(supersample=1, time_offset_s=0.020))
    src = SimSource(rig, mode="board", paced=False, fps=FPS, seed=4, frames_per_move=12)
    proc = make_capture_processor(BoardSpec())
    rules = CaptureRules()
    tl = [i / FPS for i in range(30)]
    rules.timing = skew_stats(tl, [t + 0.020 for t in tl])
    steps = []
    try:
        for _ in range(4):
            src.read()  # into the first move: the board is on its way
        for i in range(4, 12):
            f = src.read()
            out = dataclasses.replace(proc(f), time_s=i / FPS, time_right_s=i / FPS + 0.020)
            step = rules.step(out, False, list, True)
            steps.append(step)
            if step.action is CaptureAction.FREEZE:
                break
    finally:
        src.close()
    held = [s for s in steps if s.action is CaptureAction.SHOW and "20 ms apart" in s.prompt]
    assert held and held[0].prompt.startswith("Hold the board still")


def test_no_skew_no_change():
    rules = CaptureRules()
    tl = [i / FPS for i in range(30)]
    rules.timing = skew_stats(tl, tl)
    assert not rules.timing.too_large
