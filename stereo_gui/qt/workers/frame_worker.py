"""The frame worker: reads the current source and runs the current processor off the UI thread.

Two daemon threads, joined by a slot of size one (newest frame wins, as in ROS camera_calibration):
- the reader calls `source.read()` as fast as the source delivers, so a camera never backs up;
- the processor takes the newest frame, runs the processor function on it (all heavy OpenCV work
  happens here) and keeps the newest `ProcessedFrame`.

The UI never receives a backlog: `frameReady` is emitted at most once until `latest()` is called,
and `latest()` returns only the newest result.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from PySide6.QtCore import QObject, Signal

from stereo_gui.sources.base import FrameSource, StereoFrame

log = logging.getLogger(__name__)

Processor = Callable[[StereoFrame], object]

_JOIN_TIMEOUT_MS = 2000
_FPS_SMOOTHING = 0.1  # weight of the newest interval in the running frame-rate estimate


@dataclass(frozen=True, eq=False)
class ProcessedFrame:
    """One processed frame: the raw stereo frame, the processor's output (None without one).

    `camera_fps` is the rate the source delivers frames, `processing_fps` the rate results are
    produced, `processing_ms` the processor's time for this frame (milliseconds).
    """

    frame: StereoFrame
    output: object
    camera_fps: float
    processing_fps: float
    processing_ms: float = 0.0


class _RateMeter:
    """A smoothed events-per-second estimate from the intervals between events."""

    def __init__(self) -> None:
        self._last: float | None = None
        self._interval_s: float | None = None

    def tick(self, now: float) -> None:
        if self._last is not None:
            dt = max(now - self._last, 1e-6)
            self._interval_s = dt if self._interval_s is None else (
                (1 - _FPS_SMOOTHING) * self._interval_s + _FPS_SMOOTHING * dt)
        self._last = now

    def reset(self) -> None:
        self._last = None
        self._interval_s = None

    @property
    def fps(self) -> float:
        return 0.0 if not self._interval_s else 1.0 / self._interval_s


WORKER_NICE = 10  # Linux niceness of frame threads: under CPU load the UI thread wins


def _lower_thread_priority() -> None:
    """Make the calling thread yield to the UI thread when CPUs are busy.

    On Linux niceness is per thread (and inherited by threads it starts, e.g. OpenCV's pool),
    while thread priorities do nothing under the default scheduler. Elsewhere the threads run
    at normal priority.
    """
    if hasattr(os, "setpriority") and sys.platform.startswith("linux"):
        try:
            tid = threading.get_native_id()
            current = os.getpriority(os.PRIO_PROCESS, tid)
            os.setpriority(os.PRIO_PROCESS, tid, max(current, WORKER_NICE))
        except OSError as exc:
            log.debug("could not lower the frame thread's priority: %s", exc)


class _LoopThread(threading.Thread):
    """A daemon thread running a plain Python loop function until asked to stop.

    Not a QThread on purpose: a source read can block for longer than the 2 s the window waits
    at closing (a camera being opened, the rig building its textures on a loaded machine). A
    QThread destroyed while running aborts the process; a daemon thread is simply left behind
    and ends with it.
    """

    def __init__(self, loop: Callable[[], None], name: str) -> None:
        super().__init__(name=name, daemon=True)
        self._loop = loop

    def run(self) -> None:  # runs in the new thread
        _lower_thread_priority()
        self._loop()


class FrameWorker(QObject):
    """Reads frames from a FrameSource and processes them off the UI thread (see module doc)."""

    frameReady = Signal()  # a new ProcessedFrame is available; at most once until latest()
    errorOccurred = Signal(str)  # a message for the user (source or processor failure)
    sourceChanged = Signal(str)  # the name of the new source ("" when none)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._cond = threading.Condition()
        # everything below is guarded by self._cond
        self._source: FrameSource | None = None
        self._pending_source: FrameSource | None = None
        self._source_pending = False
        self._processor: Processor | None = None
        self._tap: Callable[[StereoFrame], None] | None = None
        self._frame: StereoFrame | None = None  # newest frame not yet processed
        self._latest: ProcessedFrame | None = None
        self._notified = False
        self._paused = False
        self._stopping = False
        self._camera_rate = _RateMeter()
        self._proc_rate = _RateMeter()
        self._last_error = ""
        self._frames_read = 0
        self._frames_processed = 0
        self._reader: _LoopThread | None = None
        self._worker: _LoopThread | None = None

    # ---- control (UI thread) -----------------------------------------------------------------
    def set_source(self, source: FrameSource | None) -> None:
        """Use `source` from the next read on; the previous source is closed by the reader."""
        with self._cond:
            self._pending_source = source
            self._source_pending = True
            self._frame = None
            self._latest = None
            self._last_error = ""
            self._camera_rate.reset()
            self._proc_rate.reset()
            self._cond.notify_all()
        self.sourceChanged.emit(getattr(source, "name", "") if source is not None else "")
        self._ensure_started()

    def source(self) -> FrameSource | None:
        """The source in use (or about to be used)."""
        with self._cond:
            return self._pending_source if self._source_pending else self._source

    def set_processor(self, fn: Processor | None) -> None:
        """Run `fn(frame)` on every frame from the next one on (None: frames pass unprocessed)."""
        with self._cond:
            self._processor = fn
            self._last_error = ""

    def processor(self) -> Processor | None:
        with self._cond:
            return self._processor

    def set_frame_tap(self, fn: Callable[[StereoFrame], None] | None) -> None:
        """Call `fn(frame)` in the reader thread with every raw frame read from the source
        (recording: the frame is handed over where it arrives, never copied on the UI thread).

        `fn` runs after the frame was passed on to processing, so a slow `fn` delays reading,
        never the view. If it raises, the tap is removed and the error reported.
        """
        with self._cond:
            self._tap = fn

    def frame_tap(self) -> Callable[[StereoFrame], None] | None:
        with self._cond:
            return self._tap

    def latest(self) -> ProcessedFrame | None:
        """The newest processed frame (or None); re-arms `frameReady`."""
        with self._cond:
            self._notified = False
            return self._latest

    def pause(self) -> None:
        """Stop reading and processing until `resume()`; the last result stays available."""
        with self._cond:
            self._paused = True
            self._cond.notify_all()

    def resume(self) -> None:
        with self._cond:
            self._paused = False
            self._camera_rate.reset()
            self._proc_rate.reset()
            self._cond.notify_all()

    @property
    def paused(self) -> bool:
        with self._cond:
            return self._paused

    @property
    def fps_camera(self) -> float:
        """Frames per second delivered by the source (0 when idle)."""
        with self._cond:
            return self._camera_rate.fps

    @property
    def fps_processing(self) -> float:
        """Processed frames per second (0 when idle)."""
        with self._cond:
            return self._proc_rate.fps

    @property
    def frames_read(self) -> int:
        with self._cond:
            return self._frames_read

    @property
    def frames_processed(self) -> int:
        with self._cond:
            return self._frames_processed

    def is_running(self) -> bool:
        return any(t is not None and t.is_alive() for t in (self._reader, self._worker))

    def stop(self, timeout_ms: int = _JOIN_TIMEOUT_MS) -> bool:
        """Ask both threads to end, join them, close the source; True if they ended in time."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        ok = True
        deadline = time.monotonic() + timeout_ms / 1000.0
        for t in (self._reader, self._worker):
            if t is not None:
                t.join(max(0.001, deadline - time.monotonic()))
                ok = not t.is_alive() and ok
        if not ok:
            log.warning("frame worker did not stop within %d ms (a source read is blocking)",
                        timeout_ms)
        with self._cond:
            sources = [s for s in (self._source, self._pending_source) if s is not None]
            if ok:
                self._source = None
                self._pending_source = None
                self._source_pending = False
        if ok:
            for s in sources:
                close_quietly(s)
            self._reader = None
            self._worker = None
            with self._cond:
                self._stopping = False
        return ok

    # ---- threads -----------------------------------------------------------------------------
    def _ensure_started(self) -> None:
        if self._reader is None:
            self._reader = _LoopThread(self._read_loop, "frame-reader")
            self._reader.start()
        if self._worker is None:
            self._worker = _LoopThread(self._process_loop, "frame-processor")
            self._worker.start()

    def _report(self, text: str) -> None:
        """Emit an error once (a failing source or processor would otherwise repeat it per frame)."""
        with self._cond:
            if text == self._last_error:
                return
            self._last_error = text
        log.warning("%s", text)
        self.errorOccurred.emit(text)

    def _read_loop(self) -> None:
        while True:
            with self._cond:
                while not self._stopping and (self._paused or (
                        self._source is None and not self._source_pending)):
                    self._cond.wait()
                if self._stopping:
                    return
                old = None
                if self._source_pending:
                    old, self._source = self._source, self._pending_source
                    self._pending_source = None
                    self._source_pending = False
                source = self._source
            if old is not None and old is not source:
                close_quietly(old)
            if source is None:
                continue
            try:
                frame = source.read()
            except Exception as exc:  # noqa: BLE001 - any failure of a device becomes a message
                self._report(f"{getattr(source, 'name', 'source')}: {exc}")
                with self._cond:
                    # stop reading a failed source; a new set_source() starts again
                    if self._source is source:
                        self._source = None
                        self._camera_rate.reset()
                close_quietly(source)
                continue
            with self._cond:
                if self._source is not source or self._source_pending:
                    continue  # a frame of the previous source: drop it
                self._frame = frame
                self._frames_read += 1
                self._camera_rate.tick(time.monotonic())
                self._cond.notify_all()
                tap = self._tap
            if tap is not None:
                try:
                    tap(frame)
                except Exception as exc:  # noqa: BLE001 - a failing tap must not stop reading
                    log.debug("frame tap failed", exc_info=True)
                    with self._cond:
                        if self._tap is tap:
                            self._tap = None
                    self._report(f"recording the frames failed: {exc}")

    def _process_loop(self) -> None:
        while True:
            with self._cond:
                while not self._stopping and (self._paused or self._frame is None):
                    self._cond.wait()
                if self._stopping:
                    return
                frame, self._frame = self._frame, None
                fn = self._processor
            t0 = time.perf_counter()
            output = None
            if fn is not None:
                try:
                    output = fn(frame)
                except Exception as exc:  # noqa: BLE001 - shown to the user, the loop goes on
                    log.debug("processor failed", exc_info=True)
                    self._report(f"processing failed: {exc}")
                    continue
            ms = (time.perf_counter() - t0) * 1000.0
            with self._cond:
                if self._processor is not fn:
                    continue  # made for a processor that has since been replaced
                self._proc_rate.tick(time.monotonic())
                self._frames_processed += 1
                self._latest = ProcessedFrame(frame, output, self._camera_rate.fps,
                                              self._proc_rate.fps, ms)
                notify = not self._notified
                self._notified = True
            if notify:
                self.frameReady.emit()


def close_quietly(source: FrameSource) -> None:
    try:
        source.close()
    except Exception:  # noqa: BLE001 - closing a broken device must not stop the app
        log.warning("closing %s failed", getattr(source, "name", source), exc_info=True)
