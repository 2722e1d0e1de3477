"""The frame worker: reads the current source and runs the current processor off the UI thread.

Threads (`threads.WorkerThread`), as `stereo_gui.pipeline.concurrency` describes them:
- the reader calls `source.read()` as fast as the source delivers, so a camera never backs up,
  and puts each frame into a slot of size one (newest frame wins: a frame not yet taken is
  replaced, nothing queues up), with the moment the read returned it (`ProcessedFrame.read_at`,
  where the latency to the screen is counted from);
- LANES processing lanes take the frame in the slot and run the processor on it (all heavy
  OpenCV work happens here). The processor is set with the number of lanes it may use
  (`set_processor(fn, lanes)`): lane 0 always takes frames, the others only while fewer than
  that many frames are in work. A result older than one already kept is dropped: results are
  handed out in the order the frames were read.

Each lock guards only what two threads share, and none is held while another is taken, except
the rate meters' (a leaf):
- `_reader_cv`: the source hand-over (UI thread -> reader), pause/stop, the tasks on the source;
- `_lanes_cv`: the frame slot, the processor, the newest result (reader -> lanes -> UI thread);
- `ReadClock`: when the current read began (reader -> the watchdog in the UI thread);
- `Meters`: frame rates, counts and the cameras' skew (reader and lanes -> UI thread);
- `StreamMachine`: the stream's state machine (reader and watchdog -> UI thread).
(These three, `StreamState` and `WorkerStatus` are in `frame_status`.)
The UI reads them together as one frozen `WorkerStatus` (`status()`).

The UI never receives a backlog: the lanes post one private notification to the UI thread at a
time (until it has arrived, or `latest()` was called), and there the public `frameReady` is
emitted; `latest()` returns only the newest result. The notification re-arms where it is
received, not only in `latest()`: one that reached no reader (the tab shown draws no frames)
must not silence the worker for the tab shown next. `frameReady` is only ever emitted in the UI
thread: a receiver disconnecting while another thread emits the same signal crashes PySide.

The stream's state (`StreamState`, announced by `streamStatus`): a source that raises
SourceUnavailable (a camera being opened again) is kept and read again, RECONNECTING; a read
blocked for READ_STALL_S is STALLED (the watchdog in the UI thread says so); any other read error
drops the source, FAILED (`sourceChanged("")`); frames arriving again make it OK. The rates
shown fall to 0 when no frame arrives.

Only the reader thread touches the source's devices: a camera's controls are read and written
by tasks handed to it with `run_on_source(fn)` (run between two reads; their results come back
with `sourceTaskDone` in the UI thread). It also keeps the skew between the two cameras' frame
times over the last second (`timing()`, core.timing).

A read that does not return cannot be interrupted: choosing another source while one is blocked
leaves that reader behind (it closes its source and ends once its read returns) and starts a new
one; `stop()` waits at most its timeout and leaves a blocked thread to end on its own
(threads.py keeps it alive until then, so closing never aborts).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

from PySide6.QtCore import QObject, QTimer, Signal

from stereo_gui.core.errors import SourceError, SourceUnavailable
from stereo_gui.core.timing import SkewStats
from stereo_gui.pipeline.concurrency import MAX_LANES
from stereo_gui.qt.workers.frame_status import (
    Meters,
    ReadClock,
    StreamMachine,
    StreamState,
    StreamStatus,
    WorkerStatus,
)
from stereo_gui.qt.workers.threads import WorkerThread
from stereo_gui.sources.base import FrameSource, StereoFrame

log = logging.getLogger(__name__)

Processor = Callable[[StereoFrame], object]
SourceTask = Callable[[FrameSource, StereoFrame | None], object]

_JOIN_TIMEOUT_MS = 2000
READ_STALL_S = 3.0  # a read blocked this long is reported (the device stopped answering)
_WATCHDOG_MS = 500
_UNAVAILABLE_PAUSE_S = 0.1  # after SourceUnavailable, the reader asks again this soon
LANES = MAX_LANES  # processing threads; set_processor's `lanes` says how many of them work

__all__ = ["FrameWorker", "ProcessedFrame", "StreamState", "StreamStatus", "WorkerStatus",
           "close_quietly"]


@dataclass(frozen=True, eq=False)
class ProcessedFrame:
    """One processed frame: the raw stereo frame, the processor's output (None without one).

    `camera_fps` is the rate the source delivers frames, `processing_fps` the rate results are
    produced, `processing_ms` the processor's time for this frame (milliseconds). `read_at` is
    when the reader got the frame from the source (`time.monotonic()`, seconds; NaN unknown):
    where the latency to the screen starts.
    """

    frame: StereoFrame
    output: object
    camera_fps: float
    processing_fps: float
    processing_ms: float = 0.0
    read_at: float = math.nan


@dataclass(eq=False)
class _SourceTask:
    """A function to run on the source in the reader thread (see run_on_source)."""

    id: int
    fn: SourceTask
    frames_left: int
    source_gen: int


class FrameWorker(QObject):
    """Reads frames from a FrameSource and processes them off the UI thread (see module doc)."""

    frameReady = Signal()  # a new ProcessedFrame is available (emitted in the UI thread only)
    _published = Signal()  # processing lanes -> UI thread (queued); never disconnected
    errorOccurred = Signal(str)  # a message for the user (source or processor failure)
    sourceChanged = Signal(str)  # the name of the new source ("" when none)
    streamStatus = Signal(StreamStatus)  # when the stream's state changes
    # (task id, what run_on_source's function returned or the exception it raised: object, it
    # can be anything); UI thread
    sourceTaskDone = Signal(int, object)
    # (task id, result) from the reader to the UI thread (queued); never disconnected
    _task_finished = Signal(tuple)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        # the source hand-over, pause/stop and the tasks: UI thread <-> reader
        self._reader_cv = threading.Condition()
        self._source: FrameSource | None = None  # the source the reader reads
        self._next_source: FrameSource | None = None  # set_source's, until the reader takes it
        self._source_changing = False  # set_source() was called and the reader has not yet
        self._source_gen = 0  # set_source() counts up: a frame of an older source is dropped
        self._reader_gen = 0  # counts up when a blocked reader is left behind: it then ends
        self._reader_paused = False
        self._reader_stopping = False
        self._tap: Callable[[StereoFrame], None] | None = None
        self._tasks: list[_SourceTask] = []  # run_on_source's functions not yet run
        self._task_ids = 0
        self._last_frame: StereoFrame | None = None  # the newest frame read (for tasks)
        # the frame slot, the processor and the newest result: reader -> lanes -> UI thread
        self._lanes_cv = threading.Condition()
        self._frame: StereoFrame | None = None  # the newest frame not yet taken by a lane
        self._frame_read_at = math.nan  # when the reader got it (time.monotonic())
        self._frame_seq = 0  # its number (frames are numbered as they are read)
        self._frame_gen = 0  # the source generation frames are taken of (older: dropped)
        self._processor: Processor | None = None
        self._lane_count = 1  # how many lanes the processor may use
        self._in_work = 0  # frames being processed now (at most _lane_count)
        self._latest: ProcessedFrame | None = None
        self._latest_seq = -1  # the number of the frame _latest was made of
        self._latest_of: Processor | None = None  # the processor that made _latest
        self._notified = False  # a notification is on its way to the UI thread
        self._lanes_paused = False
        self._lanes_stopping = False
        # shared, each with a lock of its own
        self._meters = Meters()
        self._stream = StreamMachine()
        self._clock = ReadClock()  # the current reader's (replaced with it)
        # UI thread only
        self._reader: WorkerThread | None = None
        self._lanes: list[WorkerThread] = []
        self._left_behind: list[WorkerThread] = []  # blocked threads: they end on their own
        self._stall_reported = False
        self._watchdog = QTimer(self)
        self._watchdog.setInterval(_WATCHDOG_MS)
        self._watchdog.timeout.connect(self._check_read)
        self._published.connect(self._frame_delivered)  # queued: this object lives in the UI thread
        self._task_finished.connect(self._task_delivered)

    # ---- control (UI thread) -----------------------------------------------------------------
    def set_source(self, source: FrameSource | None) -> None:
        """Use `source` from the next read on; the previous source is closed by the reader."""
        with self._reader_cv:
            self._next_source = source
            self._source_changing = True
            self._source_gen += 1
            gen = self._source_gen
            self._last_frame = None
            self._reader_cv.notify_all()
        with self._lanes_cv:
            self._frame_gen = gen
            self._frame = None
            self._latest = None
        self._meters.reset()
        self._stream.forget_said()
        self.sourceChanged.emit(source.name if source is not None else "")
        self._replace_blocked_reader()
        self._ensure_started()

    def source(self) -> FrameSource | None:
        """The source in use (or about to be used)."""
        with self._reader_cv:
            return self._next_source if self._source_changing else self._source

    def set_processor(self, fn: Processor | None, lanes: int = 1) -> None:
        """Run `fn(frame)` on every frame from the next one on (None: frames pass unprocessed),
        at most `lanes` frames at once (in as many lanes; at most LANES). Calling it again with
        the same `fn` keeps its newest result; its error, if it fails, is said again."""
        with self._lanes_cv:
            self._processor = fn
            self._lane_count = max(1, min(LANES, int(lanes)))
            self._lanes_cv.notify_all()
        self._stream.forget_said()

    def processor(self) -> Processor | None:
        with self._lanes_cv:
            return self._processor

    def set_frame_tap(self, fn: Callable[[StereoFrame], None] | None) -> None:
        """Call `fn(frame)` in the reader thread with every raw frame read from the source
        (recording: the frame is handed over where it arrives, never copied on the UI thread).

        `fn` runs after the frame was passed on to processing, so a slow `fn` delays reading,
        never the view. If it raises, the tap is removed and the error reported.
        """
        with self._reader_cv:
            self._tap = fn

    def frame_tap(self) -> Callable[[StereoFrame], None] | None:
        with self._reader_cv:
            return self._tap

    def timing(self) -> SkewStats:
        """The skew between the two cameras' frame times over the last second."""
        return self._meters.skew()

    def run_on_source(self, fn: SourceTask, after_frames: int = 0) -> int:
        """Have the reader thread call `fn(source, frame)` with the source in use and the
        newest frame read (None before the first), once `after_frames` more frames were read
        (0: before the next read; while paused too). Returns the task's id; `sourceTaskDone(id,
        result)` brings what `fn` returned, or the exception it raised, to the UI thread. A
        task waiting when the source is replaced gets a SourceError instead of running on the
        new one; so does one given while there is no source."""
        with self._reader_cv:
            self._task_ids += 1
            tid = self._task_ids
            no_source = self._source is None and not self._source_changing
            if not no_source:
                self._tasks.append(_SourceTask(tid, fn, max(0, int(after_frames)),
                                               self._source_gen))
                self._reader_cv.notify_all()
        if no_source:
            self._task_finished.emit((tid, SourceError("no source is open")))
        return tid

    def latest(self) -> ProcessedFrame | None:
        """The newest frame processed by the processor now set (or None: a result of the one
        before is never handed out, e.g. a frame of the calibration just replaced); re-arms
        `frameReady`."""
        with self._lanes_cv:
            self._notified = False
            return self._latest if self._latest_of is self._processor else None

    def pause(self) -> None:
        """Stop reading and processing until `resume()`; the last result stays available."""
        self._set_paused(True)

    def resume(self) -> None:
        self._meters.reset(skew=False)
        self._set_paused(False)

    @property
    def paused(self) -> bool:
        with self._reader_cv:
            return self._reader_paused

    def _set_paused(self, paused: bool) -> None:
        with self._reader_cv:
            self._reader_paused = paused
            self._reader_cv.notify_all()
        with self._lanes_cv:
            self._lanes_paused = paused
            self._lanes_cv.notify_all()

    def status(self) -> WorkerStatus:
        """What the worker is doing now, in one snapshot."""
        source, paused = self.source(), self.paused
        with self._lanes_cv:
            pending = 0 if self._frame is None else 1
        camera_fps, processing_fps, read, processed = self._meters.rates()
        return WorkerStatus(
            stream=self._stream.state,
            source_name=source.name if source is not None else "",
            paused=paused,
            camera_fps=camera_fps,
            processing_fps=processing_fps,
            frames_read=read,
            frames_processed=processed,
            pending_frames=pending,
            skipped_frames=int(source.skipped_frames) if source is not None else 0,
            source_cpu_s=self._meters.source_cpu())

    def is_running(self) -> bool:
        """True while one of its threads runs (a blocked one left behind included)."""
        return any(t.isRunning() for t in (*self.threads(), *self._left_behind))

    def threads(self) -> list[WorkerThread]:
        """The reader's and the processing lanes' threads (for tests and diagnostics)."""
        return [t for t in (self._reader, *self._lanes) if t is not None]

    def stop(self, timeout_ms: int = _JOIN_TIMEOUT_MS) -> bool:
        """Ask every thread to end, join them, close the source; True if they ended in time.

        Waits at most `timeout_ms` in all. A thread still blocked then (in a source read that
        does not return) is left to end on its own and the source is not closed under it; a
        later stop() returns False at once while it is still blocked.
        """
        self._watchdog.stop()
        self._request_stop()
        deadline = time.monotonic() + timeout_ms / 1000.0
        for t in self.threads():
            if not t.join(max(1, int((deadline - time.monotonic()) * 1000))):
                self._left_behind.append(t)
        self._left_behind = [t for t in self._left_behind if t.isRunning()]
        self._reader = None
        self._lanes = []
        if self._left_behind:
            log.warning("frame worker did not stop within %d ms (a source read is blocking)",
                        timeout_ms)
            return False
        with self._reader_cv:
            sources = [s for s in (self._source, self._next_source) if s is not None]
            self._source = self._next_source = None
            self._source_changing = False
            self._reader_stopping = False
        with self._lanes_cv:
            self._lanes_stopping = False
        for s in sources:
            close_quietly(s)
        return True

    # ---- threads -----------------------------------------------------------------------------
    def _request_stop(self) -> None:
        with self._reader_cv:
            self._reader_stopping = True
            self._reader_cv.notify_all()
        with self._lanes_cv:
            self._lanes_stopping = True
            self._lanes_cv.notify_all()

    def _ensure_started(self) -> None:
        with self._reader_cv:
            if self._reader_stopping:
                return  # a stop() left a blocked thread behind: this worker is done
            gen = self._reader_gen
        if self._reader is None:
            clock = self._clock = ReadClock()
            self._reader = WorkerThread(lambda: self._read_loop(gen, clock), "frame-reader",
                                        self._request_stop)
            self._reader.start()
        if not self._lanes:
            for lane in range(LANES):
                t = WorkerThread(partial(self._lane_loop, lane),
                                 f"frame-lane-{lane + 1}", self._request_stop)
                self._lanes.append(t)
                t.start()
        self._watchdog.start()

    def _check_read(self) -> None:
        """Watchdog (UI thread): say once when a read has been blocked for READ_STALL_S."""
        stalled = self._clock.blocked_for()
        if stalled < READ_STALL_S:
            self._stall_reported = False
            return
        if self._stall_reported:
            return
        self._stall_reported = True
        with self._reader_cv:
            source = self._source
        name = source.name if source is not None else "the source"
        text = (f"{name}: no frame for {stalled:.0f} s; the device is not answering "
                "(unplugged, or in use by another program?)")
        self.errorOccurred.emit(text)
        log.warning("%s: a read has been blocked for %.1f s", name, stalled)
        self._enter(StreamState.STALLED, text, source)

    def _replace_blocked_reader(self) -> None:
        """A new source must not wait for a read of the old one that does not return: leave
        such a reader behind (it ends after its read) and let a new one start."""
        if self._reader is None or self._clock.blocked_for() < READ_STALL_S:
            return
        with self._reader_cv:
            self._reader_gen += 1
            old = self._source
            self._source = None  # closed by nobody while its read is under way
        log.warning("leaving a reader blocked in %s behind",
                    old.name if old is not None else "a source")
        self._left_behind.append(self._reader)
        self._reader = None
        self._stall_reported = False

    def _enter(self, state: StreamState, message: str, source: FrameSource | None) -> None:
        status = self._stream.enter(state, message, source)
        if status is not None:
            self.streamStatus.emit(status)

    def _report(self, text: str) -> None:
        """Emit an error once (a failing source or processor would otherwise repeat it per frame)."""
        if self._stream.say(text):
            log.warning("%s", text)
            self.errorOccurred.emit(text)

    def _read_loop(self, gen: int, clock: ReadClock) -> None:
        """The reader (generation `gen`): take the source set, run due tasks, read a frame."""
        while True:
            with self._reader_cv:
                while not self._reader_stopping and gen == self._reader_gen and (
                        (self._reader_paused and not self._due_tasks()) or (
                        self._source is None and not self._source_changing)):
                    self._reader_cv.wait()
                if self._reader_stopping or gen != self._reader_gen:
                    return
                old = None
                if self._source_changing:
                    old, self._source = self._source, self._next_source
                    self._next_source = None
                    self._source_changing = False
                source, paused, source_gen = self._source, self._reader_paused, self._source_gen
            if old is not None and old is not source:
                close_quietly(old)
            self._run_tasks(source)
            if source is None or paused:
                continue
            clock.start()
            cpu0 = time.thread_time()
            try:
                frame, error = source.read(), None
            except Exception as exc:  # noqa: BLE001 - any failure of a device becomes a message
                frame, error = None, exc
            self._meters.read_cpu(time.thread_time() - cpu0)
            clock.stop()
            read_at = time.monotonic()  # where the latency to the screen starts
            with self._reader_cv:
                left_behind = gen != self._reader_gen
            if left_behind:  # the source is no longer used: close it now its read is over, end
                close_quietly(source)
                return
            if isinstance(error, SourceUnavailable):
                self._source_unavailable(source, error)
            elif error is not None:
                self._source_failed(source, error)
            else:
                assert frame is not None  # (read() gives a frame or raises)
                self._frame_read(source, source_gen, frame, read_at)

    def _source_unavailable(self, source: FrameSource, exc: SourceUnavailable) -> None:
        """Reader: a camera of `source` is being opened again: keep the source, ask again."""
        text = f"{source.name}: {exc}"
        self._report(text)
        self._enter(StreamState.RECONNECTING, text, source)
        with self._reader_cv:  # not a busy loop, whatever the source does
            if not self._reader_stopping and not self._source_changing:
                self._reader_cv.wait(_UNAVAILABLE_PAUSE_S)

    def _source_failed(self, source: FrameSource, exc: Exception) -> None:
        """Reader: `source` failed: stop reading it (a new set_source() starts again)."""
        text = f"{source.name}: {exc}"
        self._report(text)
        with self._reader_cv:
            in_use = self._source is source
            dropped = in_use and not self._source_changing
            if in_use:
                self._source = None
        if in_use:
            self._meters.reset(skew=False)
        close_quietly(source)
        if dropped:  # the status bar must not keep the dead source's name
            self.sourceChanged.emit("")
            self._enter(StreamState.FAILED, text, source)

    def _frame_read(self, source: FrameSource, source_gen: int, frame: StereoFrame,
                    read_at: float) -> None:
        """Reader: put the frame into the slot (replacing one not yet taken), then the tap.
        `read_at` (time.monotonic()) is when the read returned it; it goes with the frame."""
        with self._reader_cv:
            if self._source is not source or self._source_changing:
                return  # a frame of the previous source: drop it
            self._last_frame = frame
            for task in self._tasks:
                task.frames_left = max(0, task.frames_left - 1)
            tap = self._tap
        self._meters.read(frame)
        with self._lanes_cv:
            if source_gen == self._frame_gen:  # (else set_source() is replacing the source)
                self._frame = frame
                self._frame_read_at = read_at
                self._frame_seq += 1
                self._lanes_cv.notify_all()
        status = self._stream.frames_again(source)
        if status is not None:
            self.streamStatus.emit(status)
        if tap is not None:
            try:
                tap(frame)
            except Exception as exc:  # noqa: BLE001 - a failing tap must not stop reading
                log.debug("frame tap failed", exc_info=True)
                with self._reader_cv:
                    if self._tap is tap:
                        self._tap = None
                self._report(f"recording the frames failed: {exc}")

    def _due_tasks(self) -> bool:
        """(With _reader_cv held) whether a task may run before the next read."""
        return any(t.frames_left == 0 for t in self._tasks)

    def _run_tasks(self, source: FrameSource | None) -> None:
        """Reader: run the tasks that are due on `source` (those of a source since replaced,
        or with none, get a SourceError)."""
        with self._reader_cv:
            due = [t for t in self._tasks if t.frames_left == 0]
            self._tasks = [t for t in self._tasks if t.frames_left > 0]
            gen, frame = self._source_gen, self._last_frame
        for task in due:
            if source is None or task.source_gen != gen:
                result: object = SourceError("the source changed before the cameras were "
                                             "reached")
            else:
                try:
                    result = task.fn(source, frame)
                except Exception as exc:  # noqa: BLE001 - the asker is told, the reader goes on
                    log.debug("a source task failed", exc_info=True)
                    result = exc
            self._task_finished.emit((task.id, result))

    def _task_delivered(self, done: tuple[int, object]) -> None:
        tid, result = done
        self.sourceTaskDone.emit(tid, result)

    def _may_take(self, lane: int) -> bool:
        """(With _lanes_cv held) whether `lane` may take a frame now: lane 0 always, the others
        while the processor may have that many frames in work."""
        return lane == 0 or (lane < self._lane_count and self._in_work < self._lane_count)

    def _lane_loop(self, lane: int) -> None:
        """A processing lane: take the newest frame, process it, keep the result if newest."""
        while True:
            with self._lanes_cv:
                while not self._lanes_stopping and (
                        self._lanes_paused or self._frame is None or not self._may_take(lane)):
                    self._lanes_cv.wait()
                if self._lanes_stopping:
                    return
                frame, self._frame = self._frame, None
                assert frame is not None  # (the wait above ends with one, or returns)
                seq, fn, gen = self._frame_seq, self._processor, self._frame_gen
                read_at = self._frame_read_at
                self._in_work += 1
            output, failure = None, None
            t0 = time.perf_counter()
            try:
                if fn is not None:
                    output = fn(frame)
            except Exception as exc:  # noqa: BLE001 - shown to the user, the loop goes on
                log.debug("processor failed", exc_info=True)
                failure = exc
            ms = (time.perf_counter() - t0) * 1000.0
            with self._lanes_cv:
                self._in_work -= 1
                self._lanes_cv.notify_all()  # a lane waiting for its turn may take a frame
                current = self._processor is fn
            if failure is not None:
                if current:  # (a replaced processor may be closed: that is no news)
                    self._report(f"processing failed: {failure}")
                continue
            self._keep(frame, seq, gen, fn, output, ms, read_at)

    def _keep(self, frame: StereoFrame, seq: int, gen: int, fn: Processor | None,
              output: object, ms: float, read_at: float) -> None:
        """A lane's result becomes the newest unless it is stale; the UI thread is told once."""
        with self._lanes_cv:
            if self._processor is not fn or self._frame_gen != gen:
                return  # made for a processor or of a source since replaced
            if seq <= self._latest_seq and self._latest_of is fn:
                return  # another lane has already kept a newer frame: newest wins
            camera_fps, processing_fps = self._meters.processed()
            self._latest_seq = seq
            self._latest = ProcessedFrame(frame, output, camera_fps, processing_fps, ms,
                                          read_at)
            self._latest_of = fn
            notify = not self._notified
            self._notified = True
        if notify:
            self._published.emit()

    def _frame_delivered(self) -> None:
        """UI thread: a result's notification has arrived; the next result may notify again."""
        with self._lanes_cv:
            self._notified = False
        self.frameReady.emit()


def close_quietly(source: FrameSource) -> None:
    """Close `source`, logging (not raising) what goes wrong: a broken device must not stop
    the application."""
    try:
        source.close()
    except Exception:  # noqa: BLE001 - closing a broken device must not stop the app
        log.warning("closing %s failed", source.name, exc_info=True)
