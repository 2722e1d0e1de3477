"""Fixtures of the worker tests."""

from __future__ import annotations

import pytest

from stereo_gui.qt.workers.frame_worker import FrameWorker


@pytest.fixture
def worker(qtbot):
    """A frame worker, stopped (within 2 s) after the test."""
    w = FrameWorker()
    yield w
    assert w.stop(2000)
    assert not w.is_running()
