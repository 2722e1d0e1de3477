"""How the application uses the CPU's cores: the one concurrency model, stated here.

Frames are processed in *lanes*. A lane is one thread that processes one frame at a time, from
start to end: rectify, match, filter, colour map, display images. Frames in flight are the only
parallelism of the frame path:
- the frame worker (`qt.workers.frame_worker`) has one reader thread and MAX_LANES lanes; the
  processor is set with how many of them it may use (`lanes_for`): "parallel" (a preset's
  `parallel`, "use two CPU cores" in the parameter panel) means one frame in flight per CPU, at
  most MAX_LANES; otherwise one. Frames in flight share no work, so they keep the cores busy
  without hand-offs, and the newest frame wins: nothing queues up;
- within a frame nothing runs in parallel of ours: `core.matching.StereoPipeline` runs the
  stages one after the other in the calling thread. It is not safe for two threads at once,
  so the Live tab's processor (`pipeline.live.LiveProcessor`) gives each frame in flight a
  pipeline of its own (a pool with one pipeline per lane in use: resources, not a level of
  concurrency);
- OpenCV's own thread pool gets the CPUs the lanes leave (`opencv_threads_beside_lanes`): on
  2 CPUs none, every OpenCV call then runs in the lane that makes it. The command line, which
  processes one frame at a time without lanes, leaves OpenCV its default pool (all CPUs).
  OpenCV's thread count is process-wide: it is set here and nowhere else (`set_opencv_threads`),
  by `run_app` and the benches for the lanes, and by whoever runs a preset whose `cv_threads`
  asks for a count (`use_preset_threads`); `core.matching.StereoPipeline` leaves it alone.

Batch work runs in one job thread (`qt.workers`), the same way: chessboard detection over saved
pairs (`core.detect.detect_pairs`) is the one batch that splits into a pool of threads, one
pair per thread (pairs, like frames, share no work).

Beside the frame path run threads that wait most of the time: the calibration health check
(`pipeline.health`, one check every few seconds), the job runner and generator jobs
(`qt.workers`), a recording's writer (`files.recording`). Worker threads run at a lower priority
than the UI thread (`qt.workers.threads`), and the health check lower still: it takes only the
CPU the lanes leave (`lower_thread_priority`). No Qt here.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import cv2

from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.stereo_calibration import StereoCalibration

log = logging.getLogger(__name__)

MAX_LANES = 2  # frames processed at once at most (the frame worker has as many lanes)


def lower_thread_priority(nice: int) -> None:
    """Lower the calling thread's scheduling priority to niceness `nice` (never raise it).

    On Linux niceness is per thread (and inherited by the threads it starts, e.g. OpenCV's pool),
    while thread priorities do nothing under the default scheduler. Elsewhere the thread keeps
    its priority."""
    if not sys.platform.startswith("linux"):
        return
    try:
        tid = threading.get_native_id()
        current = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, max(current, int(nice)))
    except OSError as exc:  # (a sandbox may refuse it: the thread runs on at its priority)
        log.debug("could not lower the thread's priority to niceness %d: %s", nice, exc)


def lanes_for(parallel: bool, cpus: int | None = None) -> int:
    """How many frames to process at once: one per CPU, at most MAX_LANES, when `parallel`;
    else 1."""
    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    return max(1, min(MAX_LANES, cpus)) if parallel else 1


def opencv_threads_beside_lanes(cpus: int | None = None) -> int:
    """The OpenCV thread count the application runs with: the CPUs the lanes leave, plus one
    (on 2 CPUs: 1, every OpenCV call in the thread that makes it, no pool of OpenCV's own).
    OpenCV's pool on top of the lanes only adds hand-offs and spinning. With more CPUs, the
    first lane to call OpenCV gets its pool and the others run their calls in their own
    threads."""
    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    return max(1, cpus - MAX_LANES + 1)


def set_opencv_threads(count: int) -> int:
    """Set OpenCV's process-wide thread count (the one place it is set); return the count
    before."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(int(count))
    return before


def use_opencv_threads_beside_lanes() -> int:
    """Set `opencv_threads_beside_lanes()` (`run_app`); return the thread count set before."""
    return set_opencv_threads(opencv_threads_beside_lanes())


@contextmanager
def opencv_threads_for_lanes() -> Iterator[None]:
    """OpenCV with the threads `run_app` gives it while the block runs (the benches time the
    presets so), the count found before set again after."""
    before = use_opencv_threads_beside_lanes()
    try:
        yield
    finally:
        set_opencv_threads(before)


def use_preset_threads(params: Preset | MatcherParams) -> None:
    """Set the OpenCV thread count a preset asks for (`cv_threads`; None: leave it as it is),
    before its frames are processed."""
    count = Preset.of(params).threads.cv_threads
    if count is not None:
        set_opencv_threads(count)


def preset_pipeline(calibration: StereoCalibration,
                    params: Preset | MatcherParams) -> StereoPipeline:
    """A StereoPipeline for `params`, OpenCV's thread count first set as the preset asks (the
    commands that process frames one at a time)."""
    use_preset_threads(params)
    return StereoPipeline(calibration, params)
