"""The Live tab's calibration-health figure, computed every two seconds off the frame path.

The frame worker hands each processed frame's rectified pair to `HealthMonitor.offer`; at most
one check runs at a time, in a thread of the monitor's own, and only when the last one began
`INTERVAL_S` ago, so the live views never wait for it (a check takes a fifth of a second of
CPU or less: features are found on images at most 320 px wide, and matched with
core.util's one-product matcher). `latest()` gives the newest finished figure. No Qt here.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from stereo_gui.core.health import CalibrationHealth, calibration_health, health_detect_scale
from stereo_gui.pipeline.concurrency import lower_thread_priority

log = logging.getLogger(__name__)

# a check costs a fifth of a second of CPU, and on 2 CPUs that CPU is the frame lanes': checking
# every two seconds halves what checking every second takes from the live views, and a camera's
# turn is no faster news than that
INTERVAL_S = 2.0
# the check's thread runs at this niceness (Linux), below the frame lanes' (qt.workers.threads'
# 10): it takes only the CPU they leave, so that a check never slows the frames beside it (on 2
# CPUs, for the fifth of a second it takes, one lane would otherwise share its core with it)
CHECK_NICE = 19


class HealthMonitor:
    """Runs core.health.calibration_health on the newest rectified pair every `interval_s`."""

    def __init__(self, interval_s: float = INTERVAL_S) -> None:
        self.interval_s = float(interval_s)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="health",
                                        initializer=lower_thread_priority,
                                        initargs=(CHECK_NICE,))
        self._lock = threading.Lock()
        self._pending: Future[CalibrationHealth] | None = None
        self._last_start = -1e18
        self._latest: CalibrationHealth | None = None
        self._closed = False

    def offer(self, left_rect: np.ndarray, right_rect: np.ndarray, now: float | None = None) -> bool:
        """Start a check on this pair if none is running and the last began `interval_s` ago;
        True when one was started (the arrays are copied: the caller may reuse them)."""
        now = time.monotonic() if now is None else now
        with self._lock:
            self._collect()
            if self._closed or self._pending is not None or now - self._last_start < self.interval_s:
                return False
            self._last_start = now
            self._pending = self._pool.submit(calibration_health, left_rect.copy(),
                                              right_rect.copy(),
                                              health_detect_scale(left_rect.shape[1]))
            return True

    def _collect(self) -> None:
        f = self._pending
        if f is not None and f.done():
            self._pending = None
            if f.cancelled():  # closed before it began: nothing failed
                return
            try:
                self._latest = f.result()
            except Exception as exc:  # noqa: BLE001 - a failed check must not stop the live view
                log.warning("calibration health check failed: %s", exc)

    def latest(self) -> CalibrationHealth | None:
        with self._lock:
            self._collect()
            return self._latest

    def wait(self, timeout: float | None = None) -> CalibrationHealth | None:
        """Wait for the running check (tests and the command line); the newest figure."""
        f = self._pending
        if f is not None:
            f.result(timeout)
        return self.latest()

    def reset(self) -> None:
        """Forget the figure (a new calibration is in use)."""
        with self._lock:
            self._latest = None
            self._last_start = -1e18

    def close(self, wait: bool = True) -> None:
        """No more checks; `wait` for a running one to end (False: it ends by itself, and its
        thread with it: the UI thread never waits)."""
        with self._lock:
            self._closed = True
        self._pool.shutdown(wait=wait, cancel_futures=True)
