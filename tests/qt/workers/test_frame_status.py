"""The frame worker's stream state machine (frame_status): its table and how news is taken."""

from __future__ import annotations

import itertools

import pytest

from stereo_gui.qt.workers.frame_status import STREAM_MOVES, StreamMachine, StreamState

OK, RECONNECTING, STALLED, FAILED = (StreamState.OK, StreamState.RECONNECTING,
                                     StreamState.STALLED, StreamState.FAILED)


class _Source:
    def __init__(self, name: str) -> None:
        self.name = name


# what the worker does: a camera reopened, a read that blocks, one that raises, frames again
REAL = {(OK, RECONNECTING), (OK, STALLED), (OK, FAILED),
        (RECONNECTING, OK), (RECONNECTING, STALLED), (RECONNECTING, FAILED),
        (STALLED, OK), (STALLED, RECONNECTING), (STALLED, FAILED)}


@pytest.mark.parametrize("a,b", list(itertools.product(StreamState, StreamState)))
def test_the_table_allows_the_real_moves_only(a, b):
    assert STREAM_MOVES.allows(a, b) == ((a, b) in REAL)


def test_a_failed_source_is_heard_of_no_more():
    m, cam = StreamMachine(), _Source("cam")
    assert m.enter(STALLED, "no frame", cam).state is STALLED
    assert m.enter(FAILED, "gone", cam).state is FAILED
    # the watchdog's stall of the read that has failed since: stale, dropped
    assert m.enter(STALLED, "no frame", cam) is None and m.state is FAILED
    assert m.frames_again(cam) is None and m.state is FAILED
    # another source starts afresh: any state, and no "frames again" for it
    other = _Source("other")
    status = m.frames_again(other)
    assert (status.state, status.message, status.source_name) == (OK, "", "other")
    assert m.enter(FAILED, "gone too", other).state is FAILED


def test_news_about_the_same_source_is_said_once_and_frames_again_end_it():
    m, cam = StreamMachine(), _Source("cam")
    assert m.frames_again(cam) is None  # frames, and all was well
    assert m.enter(RECONNECTING, "reopening", cam).message == "reopening"
    assert m.enter(RECONNECTING, "reopening", cam) is None  # no news
    assert m.enter(STALLED, "no frame", cam).state is STALLED
    status = m.frames_again(cam)
    assert (status.state, status.message) == (OK, "cam: frames again")
    assert m.frames_again(cam) is None
