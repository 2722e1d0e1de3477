"""The Calibration tab's state machine: the moves the tab makes are allowed, no other."""

from __future__ import annotations

import itertools

import pytest

from stereo_gui.core.states import TransitionError
from stereo_gui.qt.tabs.calibration_state import CALIBRATION_MOVES, CalibrationState

S = CalibrationState
REAL = {(S.IDLE, S.RUNNING), (S.UNSAVED, S.RUNNING), (S.SAVED, S.RUNNING),  # Calibrate
        (S.FAILED, S.RUNNING), (S.CANCELLED, S.RUNNING),  # Calibrate again
        (S.IDLE, S.UNSAVED),  # use_run: a finished run handed in
        (S.RUNNING, S.CANCELLING),  # Cancel
        (S.RUNNING, S.UNSAVED), (S.CANCELLING, S.UNSAVED),  # done
        (S.RUNNING, S.FAILED), (S.CANCELLING, S.FAILED),  # failed
        (S.RUNNING, S.CANCELLED), (S.CANCELLING, S.CANCELLED),  # cancelled
        (S.UNSAVED, S.SAVED),  # the run's calibration saved
        (S.UNSAVED, S.IDLE), (S.SAVED, S.IDLE)}  # another calibration replaces the run's


@pytest.mark.parametrize("a,b", list(itertools.product(CalibrationState, CalibrationState)))
def test_the_table_allows_the_tabs_moves_only(a, b):
    assert CALIBRATION_MOVES.allows(a, b) == ((a, b) in REAL)


@pytest.mark.parametrize("a,b", [(S.IDLE, S.SAVED), (S.RUNNING, S.RUNNING),
                                 (S.FAILED, S.SAVED), (S.SAVED, S.UNSAVED)])
def test_a_move_no_one_planned_for_is_refused(a, b):
    with pytest.raises(TransitionError, match=f"{a.name} cannot become {b.name}"):
        CALIBRATION_MOVES.check(a, b)
