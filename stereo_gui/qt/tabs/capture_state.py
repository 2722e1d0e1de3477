"""What the Capture tab shows, as a state machine: live frames, a live pair frozen for review,
or a saved pair of the session (`CaptureState`, its moves in CAPTURE_MOVES)."""

from __future__ import annotations

from enum import StrEnum

from stereo_gui.core.states import Transitions


class CaptureState(StrEnum):
    LIVE = "live"  # live frames, the board detected in each
    REVIEW = "review"  # a live pair frozen: Save or Cancel
    SAVED = "saved"  # a saved pair of the session on screen: Delete, or back to live


CAPTURE_MOVES: Transitions[CaptureState] = Transitions("capture", {
    # a pair frozen; a saved pair clicked; going live while live changes nothing
    CaptureState.LIVE: {CaptureState.LIVE, CaptureState.REVIEW, CaptureState.SAVED},
    # saved or cancelled; a saved pair clicked while a pair waits (it is dropped). Never a
    # second freeze: live frames wait while a pair is under review
    CaptureState.REVIEW: {CaptureState.LIVE, CaptureState.SAVED},
    # back to live; another saved pair. Never a freeze: live frames wait meanwhile
    CaptureState.SAVED: {CaptureState.LIVE, CaptureState.SAVED},
})
