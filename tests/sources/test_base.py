"""FramePacer: frames 1/fps apart, and a bounded catch-up after a stall (on a fake clock)."""

from __future__ import annotations

import pytest

from stereo_gui.sources import base
from stereo_gui.sources.base import FramePacer


@pytest.fixture
def clock(monkeypatch):
    now = {"t": 100.0, "slept": 0.0}

    def sleep(dt):
        now["t"] += dt
        now["slept"] += dt

    monkeypatch.setattr(base.time, "monotonic", lambda: now["t"])
    monkeypatch.setattr(base.time, "sleep", sleep)
    return now


def test_frames_come_one_period_apart(clock):
    pacer = FramePacer()
    for _ in range(5):
        pacer.wait(10.0)
    assert clock["t"] == pytest.approx(100.4)


def test_after_a_stall_catch_up_is_at_most_half_a_second(clock):
    pacer = FramePacer()
    pacer.wait(10.0)
    clock["t"] += 3.0  # the consumer stalled for 3 s (30 frames at 10 fps)
    at_once = 0
    while clock["slept"] == 0.0 and at_once < 40:
        pacer.wait(10.0)
        at_once += 1
    # the overdue frame and about half a second's worth (5) come at once, not all 30
    assert 6 <= at_once <= 8
    slept = clock["slept"]
    pacer.wait(10.0)  # then the pace is one period again
    assert clock["slept"] - slept == pytest.approx(0.1)
