"""The Capture tab's state machine: the moves the tab makes are allowed, no other."""

from __future__ import annotations

import itertools

import pytest

from stereo_gui.qt.tabs.capture_state import CAPTURE_MOVES, CaptureState

LIVE, REVIEW, SAVED = CaptureState.LIVE, CaptureState.REVIEW, CaptureState.SAVED
REAL = {(LIVE, LIVE),  # go_live while live (Cancel after Back to live, a new source)
        (LIVE, REVIEW),  # both cameras see the board: the pair freezes
        (LIVE, SAVED), (REVIEW, SAVED), (SAVED, SAVED),  # a saved pair clicked in the list
        (REVIEW, LIVE), (SAVED, LIVE)}  # Save, Cancel, Back to live, the pair shown deleted


@pytest.mark.parametrize("a,b", list(itertools.product(CaptureState, CaptureState)))
def test_the_table_allows_the_tabs_moves_only(a, b):
    assert CAPTURE_MOVES.allows(a, b) == ((a, b) in REAL)

