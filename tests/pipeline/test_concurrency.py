"""OpenCV's process-wide thread count: set in pipeline.concurrency only, by who runs a preset."""

from __future__ import annotations

import ast
import os
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

import stereo_gui
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.concurrency import (
    lower_thread_priority,
    opencv_threads_beside_lanes,
    opencv_threads_for_lanes,
    preset_pipeline,
    set_opencv_threads,
)
from stereo_gui.pipeline.live import LiveProcessor
from stereo_gui.sources.base import StereoFrame

PACKAGE = Path(stereo_gui.__file__).parent
W, H = 160, 120


@pytest.fixture
def threads():
    """OpenCV's thread count before the test, set again after it."""
    before = cv2.getNumThreads()
    yield before
    set_opencv_threads(before)


def _preset(cv_threads: int | None) -> Preset:
    return Preset.of(MatcherParams(num_disparities=16, block_size=5)).replace(
        cv_threads=cv_threads)


def _calibration() -> StereoCalibration:
    return StereoCalibration.identity((W, H), 300.0, 100.0)


def test_only_pipeline_concurrency_sets_opencv_threads():
    callers = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "setNumThreads"):
                callers.append(f"{path.relative_to(PACKAGE)}:{node.lineno}")
    assert [c.split(":")[0] for c in callers] == ["pipeline/concurrency.py"], callers


def test_a_pipeline_leaves_the_thread_count_to_who_runs_its_preset(threads):
    other = 3 if threads != 3 else 2
    set_opencv_threads(other)
    with StereoPipeline(_calibration(), _preset(1)):
        assert cv2.getNumThreads() == other  # building it changes nothing process-wide
    with preset_pipeline(_calibration(), _preset(None)):
        assert cv2.getNumThreads() == other  # None: left as it is
    with preset_pipeline(_calibration(), _preset(1)):
        assert cv2.getNumThreads() == 1


def test_the_live_processor_sets_its_presets_threads_on_the_frames_they_run(threads):
    other = 3 if threads != 3 else 2
    set_opencv_threads(other)
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
    frame = StereoFrame(img, img.copy(), 0.0, 0.0, 0)
    proc = LiveProcessor(_calibration(), _preset(1))
    try:
        assert cv2.getNumThreads() == other  # not before its first frame
        proc(frame)
        assert cv2.getNumThreads() == 1
        set_opencv_threads(other)
        proc(frame)
        assert cv2.getNumThreads() == other  # once per preset, not on every frame
        proc.set_params(_preset(2))
        proc(frame)
        assert cv2.getNumThreads() == 2
    finally:
        proc.close()


def test_the_benches_give_opencv_the_applications_threads_and_set_the_count_back(threads):
    other = opencv_threads_beside_lanes() + 1
    set_opencv_threads(other)
    with opencv_threads_for_lanes():
        assert cv2.getNumThreads() == opencv_threads_beside_lanes()
    assert cv2.getNumThreads() == other


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a thread's own niceness is Linux's")
def test_a_threads_priority_is_lowered_never_raised_and_only_its_own():
    """lower_thread_priority sets the calling thread's niceness to at least the one asked for:
    a thread already lower keeps its priority, and other threads keep theirs."""
    mine = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    seen: list[int] = []

    def run() -> None:
        tid = threading.get_native_id()
        lower_thread_priority(mine + 5)
        seen.append(os.getpriority(os.PRIO_PROCESS, tid))
        lower_thread_priority(mine + 2)  # higher than its own now: no change
        seen.append(os.getpriority(os.PRIO_PROCESS, tid))

    t = threading.Thread(target=run)
    t.start()
    t.join()
    expected = min(mine + 5, 19)
    assert seen == [expected, expected]
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == mine
