"""The frame worker: reads the current source and runs the current processor off the UI thread.

QThreads (`threads.WorkerThread`), joined by a slot of size one (newest frame wins, as in ROS
camera_calibration):
- the reader calls `source.read()` as fast as the source delivers, so a camera never backs up;
- a processing lane takes the newest frame, runs the processor function on it (all heavy OpenCV
  work happens here) and keeps the newest `ProcessedFrame`. There are LANES of them; as many as
  the processor's `lanes` attribute allows (1 without it) take frames, so a processor that can
  run two frames at once (`pipeline.live.LiveProcessor`) gets the next frame while the last one
  is still being processed. A result older than one already kept is dropped: results are handed
  out in the order the frames were read, and never more than one frame per lane is in work.

The UI never receives a backlog: the processing lanes post one private notification to the
UI thread at a time (until the UI thread has received it, or `latest()` was called), and there
the public `frameReady` is emitted; `latest()` returns only the newest result. It is re-armed
where it is received, not only by `latest()`: a notification that reached no reader (the tab
shown draws no frames) must not silence the worker for the tab shown next (issue 12: the Capture
view froze after a visit to the Calibration tab). `frameReady` itself is only ever emitted in
the UI thread: PySide crashed when a receiver disconnected (a test's waitSignal) while another
thread emitted the same signal.

A source that raises SourceUnavailable (a camera source opening a vanished camera again) is
kept and read again: the message is shown once, and `streamStatus` says "reconnecting" and later
"ok" when frames come again. Any other read error drops the source ("failed"; `sourceChanged("")`).
The rates shown fall to 0 when no frame arrives.

Only this worker's reader thread touches the source's devices: a camera's controls are read and
written by tasks handed to it with `run_on_source(fn)` (run between two reads, their results
come back with `sourceTaskDone` in the UI thread). It also keeps the skew between the two
cameras' frame times over the last second (`timing()`, core.timing).

A read that does not return (a camera that stopped answering) cannot be interrupted. A watchdog
in the UI thread says so once it has blocked for READ_STALL_S; choosing another source then
leaves the blocked reader behind and starts a new one; `stop()` waits at most its timeout and
leaves a blocked thread to end on its own (threads.py keeps it alive until then, so closing never
aborts).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from PySide6.QtCore import QObject, QTimer, Signal

from stereo_gui.core.errors import SourceError, SourceUnavailable
from stereo_gui.core.timing import SkewMeter, SkewStats
from stereo_gui.pipeline.live import MAX_LANES
from stereo_gui.qt.workers.threads import WorkerThread
from stereo_gui.sources.base import FrameSource, StereoFrame

log = logging.getLogger(__name__)

Processor = Callable[[StereoFrame], object]

_JOIN_TIMEOUT_MS = 2000
READ_STALL_S = 3.0  # a read blocked this long is reported (the device stopped answering)
_WATCHDOG_MS = 500
_FPS_SMOOTHING = 0.1  # weight of the newest interval in the running frame-rate estimate
RATE_STALE_S = 2.0  # no event for this long (or 3 intervals, if longer): the rate is 0
_UNAVAILABLE_PAUSE_S = 0.1  # after SourceUnavailable, the reader asks again this soon
LANES = MAX_LANES  # processing threads; a processor's `lanes` says how many of them work


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
        """The smoothed rate, never more than the time since the last event allows, and 0
        once nothing came for RATE_STALE_S (a stuck read must not keep showing 29.4 fps)."""
        if not self._interval_s or self._last is None:
            return 0.0
        waited = time.monotonic() - self._last
        if waited > max(RATE_STALE_S, 3.0 * self._interval_s):
            return 0.0
        return 1.0 / max(self._interval_s, waited)


@dataclass(frozen=True)
class StreamStatus:
    """How the frames of the source in use come: `state` is "ok" (frames arrive again after a
    problem; `message` is then "" or says so), "reconnecting" (the source opens a vanished camera
    again), "stalled" (a read has not returned for READ_STALL_S) or "failed" (the source stopped
    and was dropped). `message` is what the user was told; `source_name` the source's name."""

    state: str
    message: str
    source_name: str


class FrameWorker(QObject):
    """Reads frames from a FrameSource and processes them off the UI thread (see module doc)."""

    frameReady = Signal()  # a new ProcessedFrame is available (emitted in the UI thread only)
    _published = Signal()  # processing lanes -> UI thread (queued); never disconnected
    errorOccurred = Signal(str)  # a message for the user (source or processor failure)
    sourceChanged = Signal(str)  # the name of the new source ("" when none)
    streamStatus = Signal(object)  # StreamStatus, when the stream's state changes
    # (task id, what run_on_source's function returned or the exception it raised); UI thread
    sourceTaskDone = Signal(int, object)
    _task_finished = Signal(object)  # reader -> UI thread (queued); never disconnected

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
        self._frame_seq = 0  # its number (frames are numbered as they are read)
        self._latest_seq = -1  # the number of the frame _latest was made of
        self._in_work = 0  # frames being processed now (at most the processor's lanes)
        self._latest: ProcessedFrame | None = None
        self._latest_of: Processor | None = None  # the processor that made _latest
        self._notified = False
        self._source_gen = 0  # set_source() counts up: a result of an older source is dropped
        self._paused = False
        self._stopping = False
        self._camera_rate = _RateMeter()
        self._proc_rate = _RateMeter()
        self._last_error = ""
        self._frames_read = 0
        self._frames_processed = 0
        self._read_started: float | None = None  # monotonic time the current read began
        self._stall_reported = False
        self._stream_state = "ok"  # StreamStatus.state of the stream now
        self._stream_source: FrameSource | None = None  # the source a problem was about
        self._reader_gen = 0  # a reader loop of an older generation ends after its read
        self._skew = SkewMeter()  # the two cameras' frame times over the last second
        self._tasks: list[_SourceTask] = []  # run_on_source's functions not yet run
        self._task_ids = 0
        self._last_frame: StereoFrame | None = None  # the newest frame read (for tasks)
        self._reader: WorkerThread | None = None
        self._workers: list[WorkerThread] = []  # the processing lanes
        self._left_behind: list[WorkerThread] = []  # blocked threads stop() could not join
        self._watchdog = QTimer(self)
        self._watchdog.setInterval(_WATCHDOG_MS)
        self._watchdog.timeout.connect(self._check_read)
        self._published.connect(self._frame_delivered)  # queued: this object lives in the UI thread
        self._task_finished.connect(self._task_delivered)

    # ---- control (UI thread) -----------------------------------------------------------------
    def set_source(self, source: FrameSource | None) -> None:
        """Use `source` from the next read on; the previous source is closed by the reader."""
        with self._cond:
            self._pending_source = source
            self._source_pending = True
            self._source_gen += 1
            self._frame = None
            self._latest = None
            self._last_error = ""
            self._camera_rate.reset()
            self._proc_rate.reset()
            self._skew.reset()
            self._last_frame = None
            self._cond.notify_all()
        self.sourceChanged.emit(getattr(source, "name", "") if source is not None else "")
        self._replace_blocked_reader()
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

    def timing(self) -> SkewStats:
        """The skew between the two cameras' frame times over the last second."""
        with self._cond:
            return self._skew.stats()

    def run_on_source(self, fn: Callable[[FrameSource, StereoFrame | None], object],
                      after_frames: int = 0) -> int:
        """Have the reader thread call `fn(source, frame)` with the source in use and the
        newest frame read (None before the first), once `after_frames` more frames were read
        (0: before the next read; while paused too). Returns the task's id; `sourceTaskDone(id,
        result)` brings what `fn` returned, or the exception it raised, to the UI thread. A
        task waiting when the source is replaced gets a SourceError instead of running on the
        new one; so does one given while there is no source."""
        with self._cond:
            self._task_ids += 1
            tid = self._task_ids
            no_source = self._source is None and not self._source_pending
            if not no_source:
                self._tasks.append(_SourceTask(tid, fn, max(0, int(after_frames)),
                                               self._source_gen))
                self._cond.notify_all()
        if no_source:
            self._task_finished.emit((tid, SourceError("no source is open")))
        return tid

    def _task_delivered(self, done) -> None:
        tid, result = done
        self.sourceTaskDone.emit(tid, result)

    def _due_tasks(self) -> bool:
        """(With the lock held) whether a task may run before the next read."""
        return any(t.frames_left == 0 for t in self._tasks)

    def _run_tasks(self, source: FrameSource | None) -> None:
        """Reader thread: run the tasks that are due on `source` (those of a source since
        replaced, or with none, get a SourceError)."""
        with self._cond:
            due = [t for t in self._tasks if t.frames_left == 0]
            self._tasks = [t for t in self._tasks if t.frames_left > 0]
            gen, frame = self._source_gen, self._last_frame
        for task in due:
            if source is None or task.gen != gen:
                result: object = SourceError("the source changed before the cameras were "
                                             "reached")
            else:
                try:
                    result = task.fn(source, frame)
                except Exception as exc:  # noqa: BLE001 - the asker is told, the reader goes on
                    log.debug("a source task failed", exc_info=True)
                    result = exc
            self._task_finished.emit((task.id, result))

    def latest(self) -> ProcessedFrame | None:
        """The newest frame processed by the processor now set (or None: a result of the one
        before is never handed out, e.g. a frame of the calibration just replaced); re-arms
        `frameReady`."""
        with self._cond:
            self._notified = False
            return self._latest if self._latest_of is self._processor else None

    def _frame_delivered(self) -> None:
        """UI thread: a result's notification has arrived; the next result may notify again,
        and the readers are told."""
        with self._cond:
            self._notified = False
        self.frameReady.emit()

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
    def skipped_frames(self) -> int:
        """Frames the source in use could not decode and left out (0 if it does not count)."""
        return int(getattr(self.source(), "skipped_frames", 0) or 0)

    @property
    def stream_state(self) -> str:
        """The StreamStatus.state now: ok, reconnecting, stalled or failed."""
        with self._cond:
            return self._stream_state

    @property
    def frames_read(self) -> int:
        with self._cond:
            return self._frames_read

    @property
    def frames_processed(self) -> int:
        with self._cond:
            return self._frames_processed

    def is_running(self) -> bool:
        """True while one of its threads runs (a blocked one left behind included)."""
        return any(t is not None and t.isRunning()
                   for t in (self._reader, *self._workers, *self._left_behind))

    @property
    def pending_frames(self) -> int:
        """Frames read and waiting to be processed: 0 or 1, never a queue."""
        with self._cond:
            return 0 if self._frame is None else 1

    def threads(self) -> list[WorkerThread]:
        """The reader and the processing lanes' threads (for tests and diagnostics)."""
        return [t for t in (self._reader, *self._workers) if t is not None]

    def stop(self, timeout_ms: int = _JOIN_TIMEOUT_MS) -> bool:
        """Ask every thread to end, join them, close the source; True if they ended in time.

        Waits at most `timeout_ms` in all. A thread still blocked then (in a source read that
        does not return) is left to end on its own and the source is not closed under it; a
        later stop() returns False at once while it is still blocked.
        """
        self._watchdog.stop()
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        deadline = time.monotonic() + timeout_ms / 1000.0
        for t in (self._reader, *self._workers):
            if t is not None and not t.join(max(1, int((deadline - time.monotonic()) * 1000))):
                self._left_behind.append(t)
        self._left_behind = [t for t in self._left_behind if t.isRunning()]
        ok = not self._left_behind
        if not ok:
            log.warning("frame worker did not stop within %d ms (a source read is blocking)",
                        timeout_ms)
        with self._cond:
            sources = [s for s in (self._source, self._pending_source) if s is not None]
            if ok:
                self._source = None
                self._pending_source = None
                self._source_pending = False
        self._reader = None
        self._workers = []
        if ok:
            for s in sources:
                close_quietly(s)
            with self._cond:
                self._stopping = False
        return ok

    # ---- threads -----------------------------------------------------------------------------
    def _request_stop(self) -> None:
        with self._cond:
            self._stopping = True
            self._cond.notify_all()

    def _ensure_started(self) -> None:
        with self._cond:
            if self._stopping:
                return  # a stop() left a blocked thread behind: this worker is done
            gen = self._reader_gen
        if self._reader is None:
            self._reader = WorkerThread(lambda: self._read_loop(gen), "frame-reader",
                                        self._request_stop)
            self._reader.start()
        if not self._workers:
            for lane in range(LANES):
                t = WorkerThread(lambda lane=lane: self._process_loop(lane),
                                 f"frame-processor-{lane + 1}", self._request_stop)
                self._workers.append(t)
                t.start()
        self._watchdog.start()

    def _blocked_for(self) -> float:
        """Seconds the current read has been blocked (0 when none is under way)."""
        with self._cond:
            t0 = self._read_started
        return 0.0 if t0 is None else time.monotonic() - t0

    def _check_read(self) -> None:
        """Watchdog (UI thread): say once when a read has been blocked for READ_STALL_S."""
        stalled = self._blocked_for()
        if stalled < READ_STALL_S:
            self._stall_reported = False
            return
        if not self._stall_reported:
            self._stall_reported = True
            with self._cond:
                name = getattr(self._source, "name", "the source")
            text = (f"{name}: no frame for {stalled:.0f} s; the device is not answering "
                    "(unplugged, or in use by another program?)")
            self.errorOccurred.emit(text)
            log.warning("%s: a read has been blocked for %.1f s", name, stalled)
            self._set_stream("stalled", text)

    def _replace_blocked_reader(self) -> None:
        """A new source must not wait for a read of the old one that does not return: leave
        such a reader behind (it ends after its read) and let a new one start."""
        if self._reader is None or self._blocked_for() < READ_STALL_S:
            return
        with self._cond:
            self._reader_gen += 1
            old = self._source
            self._source = None  # closed by nobody while its read is under way
        log.warning("leaving a reader blocked in %s behind", getattr(old, "name", "a source"))
        self._left_behind.append(self._reader)
        self._reader = None
        self._stall_reported = False

    def _set_stream(self, state: str, message: str, source: FrameSource | None = None) -> None:
        """Enter stream `state` (not "ok") and say so once."""
        with self._cond:
            if state == self._stream_state and source is self._stream_source:
                return
            self._stream_state = state
            if source is not None or state == "stalled":
                self._stream_source = source if source is not None else self._source
            name = getattr(self._stream_source, "name", "")
        self.streamStatus.emit(StreamStatus(state, message, name))

    def _stream_ok(self, source: FrameSource) -> None:
        """A frame of `source` arrived: a problem before it is over (reader thread)."""
        with self._cond:
            if self._stream_state == "ok":
                return
            same = source is self._stream_source
            self._stream_state = "ok"
            self._stream_source = None
            self._last_error = ""  # the same problem again is said again
        name = getattr(source, "name", "source")
        self.streamStatus.emit(StreamStatus(
            "ok", f"{name}: frames again" if same else "", name))

    def _report(self, text: str) -> None:
        """Emit an error once (a failing source or processor would otherwise repeat it per frame)."""
        with self._cond:
            if text == self._last_error:
                return
            self._last_error = text
        log.warning("%s", text)
        self.errorOccurred.emit(text)

    def _read_loop(self, gen: int) -> None:
        while True:
            with self._cond:
                while not self._stopping and gen == self._reader_gen and (
                        (self._paused and not self._due_tasks()) or (
                        self._source is None and not self._source_pending)):
                    self._cond.wait()
                if self._stopping or gen != self._reader_gen:
                    return
                old = None
                if self._source_pending:
                    old, self._source = self._source, self._pending_source
                    self._pending_source = None
                    self._source_pending = False
                source = self._source
                paused = self._paused
            if old is not None and old is not source:
                close_quietly(old)
            self._run_tasks(source)
            if source is None or paused:
                continue
            with self._cond:
                self._read_started = time.monotonic()
            try:
                frame = source.read()
            except SourceUnavailable as exc:  # a camera being reconnected: keep the source
                with self._cond:
                    left_behind = gen != self._reader_gen
                    if not left_behind:
                        self._read_started = None
                if left_behind:
                    close_quietly(source)
                    return
                text = f"{getattr(source, 'name', 'source')}: {exc}"
                self._report(text)
                self._set_stream("reconnecting", text, source)
                with self._cond:  # not a busy loop, whatever the source does
                    if not self._stopping and not self._source_pending:
                        self._cond.wait(_UNAVAILABLE_PAUSE_S)
                continue
            except Exception as exc:  # noqa: BLE001 - any failure of a device becomes a message
                with self._cond:
                    left_behind = gen != self._reader_gen
                    if not left_behind:
                        self._read_started = None
                if left_behind:  # the source is no longer used: close it now its read is over
                    close_quietly(source)
                    return
                text = f"{getattr(source, 'name', 'source')}: {exc}"
                self._report(text)
                with self._cond:
                    # stop reading a failed source; a new set_source() starts again
                    dropped = self._source is source and not self._source_pending
                    if self._source is source:
                        self._source = None
                        self._camera_rate.reset()
                        self._proc_rate.reset()
                close_quietly(source)
                if dropped:  # the status bar must not keep the dead source's name
                    self.sourceChanged.emit("")
                    self._set_stream("failed", text, source)
                continue
            with self._cond:
                left_behind = gen != self._reader_gen
                if not left_behind:
                    self._read_started = None
            if left_behind:  # drop the frame, close the source no longer used, end
                close_quietly(source)
                return
            with self._cond:
                if self._source is not source or self._source_pending:
                    continue  # a frame of the previous source: drop it
                self._frame = frame
                self._frames_read += 1
                self._frame_seq = self._frames_read
                self._camera_rate.tick(time.monotonic())
                self._skew.add(frame.t_left, frame.t_right)
                self._last_frame = frame
                for task in self._tasks:
                    task.frames_left = max(0, task.frames_left - 1)
                self._cond.notify_all()
                tap = self._tap
            self._stream_ok(source)
            if tap is not None:
                try:
                    tap(frame)
                except Exception as exc:  # noqa: BLE001 - a failing tap must not stop reading
                    log.debug("frame tap failed", exc_info=True)
                    with self._cond:
                        if self._tap is tap:
                            self._tap = None
                    self._report(f"recording the frames failed: {exc}")

    def _may_take(self, lane: int) -> bool:
        """Whether `lane` may take a frame now (called with the lock held): lane 0 always, the
        others while the processor allows that many frames at once."""
        if lane == 0:
            return True
        lanes = _lanes_of(self._processor)
        return lane < lanes and self._in_work < lanes

    def _process_loop(self, lane: int = 0) -> None:
        while True:
            with self._cond:
                while not self._stopping and (self._paused or self._frame is None
                                              or not self._may_take(lane)):
                    self._cond.wait()
                if self._stopping:
                    return
                frame, self._frame = self._frame, None
                seq = self._frame_seq
                fn = self._processor
                gen = self._source_gen
                self._in_work += 1
            try:
                t0 = time.perf_counter()
                output = None
                if fn is not None:
                    try:
                        output = fn(frame)
                    except Exception as exc:  # noqa: BLE001 - shown to the user, the loop goes on
                        log.debug("processor failed", exc_info=True)
                        with self._cond:
                            current = self._processor is fn
                        if current:  # (a replaced processor may be closed: that is no news)
                            self._report(f"processing failed: {exc}")
                        continue
                ms = (time.perf_counter() - t0) * 1000.0
            finally:
                with self._cond:
                    self._in_work -= 1
                    self._cond.notify_all()  # a lane waiting for its turn may take a frame
            with self._cond:
                if self._processor is not fn:
                    continue  # made for a processor that has since been replaced
                if self._source_gen != gen:
                    continue  # a frame of the previous source (issue 12: a stale frozen pair)
                if seq <= self._latest_seq and self._latest_of is fn:
                    continue  # another lane has already kept a newer frame: newest wins
                self._latest_seq = seq
                self._proc_rate.tick(time.monotonic())
                self._frames_processed += 1
                self._latest = ProcessedFrame(frame, output, self._camera_rate.fps,
                                              self._proc_rate.fps, ms)
                self._latest_of = fn
                notify = not self._notified
                self._notified = True
            if notify:
                self._published.emit()


@dataclass(eq=False)
class _SourceTask:
    """A function to run on the source in the reader thread (see run_on_source)."""

    id: int
    fn: Callable
    frames_left: int
    gen: int


def _lanes_of(fn: Processor | None) -> int:
    """How many frames `fn` may process at once (its `lanes` attribute; 1 without it)."""
    try:
        return max(1, int(getattr(fn, "lanes", 1)))
    except (TypeError, ValueError):
        return 1


def close_quietly(source: FrameSource) -> None:
    try:
        source.close()
    except Exception:  # noqa: BLE001 - closing a broken device must not stop the app
        log.warning("closing %s failed", getattr(source, "name", source), exc_info=True)
