"""Where the Calibration tab's run stands, as a state machine (`CalibrationState`, its moves in
CALIBRATION_MOVES): the line under the options says it, the table says what may follow what."""

from __future__ import annotations

from enum import StrEnum

from stereo_gui.core.states import Transitions


class CalibrationState(StrEnum):
    IDLE = "idle"  # no run of this tab in use: none yet, or a calibration loaded replaced it
    RUNNING = "running"  # a calibration is being computed
    CANCELLING = "cancelling"  # Cancel pressed: the job stops at its next step
    UNSAVED = "unsaved"  # the run's calibration is in use and not saved to a file
    SAVED = "saved"  # the run's calibration is in use and saved since
    FAILED = "failed"  # the last run failed (an earlier run's calibration may still be in use)
    CANCELLED = "cancelled"  # the last run was cancelled (likewise)


_S = CalibrationState
CALIBRATION_MOVES: Transitions[CalibrationState] = Transitions("calibration", {
    # Calibrate; a finished run handed to the tab (use_run) without a run of its own
    _S.IDLE: {_S.RUNNING, _S.UNSAVED},
    # Cancel; done; failed; cancelled without Cancel (the window closing stops the job)
    _S.RUNNING: {_S.CANCELLING, _S.UNSAVED, _S.FAILED, _S.CANCELLED},
    # a job that had ended before it saw the cancel ends as it did
    _S.CANCELLING: {_S.UNSAVED, _S.FAILED, _S.CANCELLED},
    # saved; Recalibrate; a calibration loaded (or the true one) replaces the run's
    _S.UNSAVED: {_S.SAVED, _S.RUNNING, _S.IDLE},
    # saved again elsewhere is no move: the line keeps the first file's name
    _S.SAVED: {_S.RUNNING, _S.IDLE},
    # a run that ended without a calibration: only another run changes the line
    _S.FAILED: {_S.RUNNING},
    _S.CANCELLED: {_S.RUNNING},
})
