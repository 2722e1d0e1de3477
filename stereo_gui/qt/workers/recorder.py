"""Recording the live stereo stream from the window: the frame worker hands raw frames to a
`stereo_gui.files.recording.RecordingWriter` in its reader thread.

Threads: the reader thread calls the tap (the writer copies the frame and queues it for its own
writing thread); the UI thread only starts, stops and polls counters; closing the writer (which
waits for queued frames) runs on a job thread of its own, so stopping never stalls the window.
A write error (a full disk) stops the recording and says so; what was written stays readable.
"""

from __future__ import annotations

import datetime as _dt
import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.core.jobs import JobControl
from stereo_gui.files.recording import RecordingWriter, open_recording
from stereo_gui.files.settings import Settings
from stereo_gui.qt.workers.frame_worker import FrameWorker
from stereo_gui.qt.workers.job_runner import JobRunner
from stereo_gui.sources.base import StereoFrame

log = logging.getLogger(__name__)

DEFAULT_RECORDINGS_DIR = Path.home() / "stereo-gui-recordings"


def recordings_dir(settings: Settings) -> Path:
    """The folder new recordings go into by default (remembered in the settings)."""
    remembered = settings.recordings_dir
    return Path(remembered) if remembered else DEFAULT_RECORDINGS_DIR


def new_recording_folder(base: str | Path, now: _dt.datetime | None = None) -> Path:
    """A new, not yet existing folder `rec-YYYYmmdd-HHMMSS` (with -2, -3… if taken) in `base`."""
    stamp = (now or _dt.datetime.now()).strftime("rec-%Y%m%d-%H%M%S")
    base = Path(base)
    folder, n = base / stamp, 2
    while folder.exists():
        folder, n = base / f"{stamp}-{n}", n + 1
    return folder


def format_elapsed(seconds: float) -> str:
    s = int(max(seconds, 0.0))
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


@dataclass(frozen=True)
class RecordingResult:
    """What a finished recording left: its folder, frames on disk, the recording read back (None
    if unreadable), and the error that stopped it ("" when stopped by the user)."""

    folder: Path
    frames: int
    duration_s: float
    recording: object | None  # files.recording.Recording
    error: str = ""
    note: str = ""  # why it stopped when the user did not stop it and it is not an error


class Recorder(QObject):
    """Records the frame worker's raw frames (see module doc). One recording at a time."""

    started = Signal(str)  # folder
    stopped = Signal(RecordingResult)
    _tapFailed = Signal(str)  # from the reader thread to the UI thread

    def __init__(self, frames: FrameWorker, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.frames = frames
        self._writer: RecordingWriter | None = None
        self._folder: Path | None = None
        self._t0 = 0.0
        self._last: tuple[int, float] | None = None  # (index, t_left) of the last frame taken
        self._lock = threading.Lock()
        self._closer = JobRunner("recording-closer", self)
        self._closer.finished.connect(self._closed)
        self._closer.failed.connect(lambda _id, msg: log.error("closing a recording: %s", msg))
        self._closing_ids: set[int] = set()
        self._tapFailed.connect(self._on_tap_failed)
        # frames of another source (another size, another camera) do not belong in this recording
        frames.sourceChanged.connect(
            lambda _name: self.stop_recording(note="stopped because the source changed"))

    # ---- state ------------------------------------------------------------------------------
    @property
    def is_recording(self) -> bool:
        return self._writer is not None

    @property
    def is_closing(self) -> bool:
        return self._closer.is_busy()

    @property
    def folder(self) -> Path | None:
        return self._folder

    @property
    def frames_written(self) -> int:
        w = self._writer
        return w.frames_written if w is not None else 0

    @property
    def last_frame_taken(self) -> tuple[int, float] | None:
        """(index, t_left) of the newest frame handed to the recording; None before the first."""
        return self._last

    @property
    def elapsed_s(self) -> float:
        return time.monotonic() - self._t0 if self._writer is not None else 0.0

    # ---- control (UI thread) ----------------------------------------------------------------
    def start(self, folder: str | Path, source_name: str = "", fps: float = 30.0) -> Path:
        """Start recording into the new folder `folder`; raise StereoGuiError if it cannot."""
        if self._writer is not None:
            raise InputError(f"already recording into {self._folder}")
        fps = float(fps) if fps and fps > 0 else 30.0
        writer = RecordingWriter(folder, source_name=source_name, fps=fps)
        self._folder = Path(folder)
        self._t0 = time.monotonic()
        self._last = None
        self._writer = writer
        self.frames.set_frame_tap(self._tap)
        log.info("recording into %s", folder)
        self.started.emit(str(folder))
        return self._folder

    def stop_recording(self, error: str = "", note: str = "") -> int | None:
        """Stop taking frames and close the writer off the UI thread; `stopped` follows."""
        writer = self._writer
        if writer is None:
            return None
        if self.frames.frame_tap() == self._tap:
            self.frames.set_frame_tap(None)
        with self._lock:
            self._writer = None
        duration = time.monotonic() - self._t0
        folder = writer.folder  # (the folder start() was given)

        def close(_control: JobControl) -> RecordingResult:
            why = error
            try:
                rec = writer.close()
            except StereoGuiError as exc:
                why = why or str(exc)
                try:
                    rec = open_recording(folder)  # what was written before the error
                except StereoGuiError:
                    rec = None
            n = len(rec.frames) if rec is not None else 0
            return RecordingResult(folder, n, duration, rec, why, note)

        job = self._closer.submit(close).id
        self._closing_ids.add(job)
        return job

    def stop(self, timeout_ms: int = 2000) -> bool:
        """At exit: stop recording and close the writer (waiting for its queued frames), then
        end the closing thread; True when everything ended within `timeout_ms` (about)."""
        deadline = time.monotonic() + timeout_ms / 1000.0
        writer = self._writer
        if writer is not None:
            self.frames.set_frame_tap(None)
            with self._lock:
                self._writer = None
            try:
                writer.close()
            except StereoGuiError as exc:
                log.warning("recording %s: %s", self._folder, exc)
        while self._closer.is_busy() and time.monotonic() < deadline:
            time.sleep(0.01)  # shutdown only: a close requested just before is finishing
        return self._closer.stop(timeout_ms=max(1, int((deadline - time.monotonic()) * 1000)))

    # ---- threads ----------------------------------------------------------------------------
    def _tap(self, frame: StereoFrame) -> None:
        """Reader thread: hand the raw frame to the writer (it copies and queues it)."""
        with self._lock:
            writer = self._writer
        if writer is None:
            return
        key = (int(frame.index), float(frame.t_left))
        if key == self._last:
            return  # a paused playback delivers its held frame again: not a new capture
        self._last = key
        try:
            writer.write(frame)
        except Exception as exc:  # noqa: BLE001 - becomes the message that stops recording
            self.frames.set_frame_tap(None)
            with self._lock:
                failed = self._writer is writer
            if failed:
                self._tapFailed.emit(str(exc) or type(exc).__name__)

    def _on_tap_failed(self, message: str) -> None:
        if self._writer is not None:
            self.stop_recording(error=message)

    def _closed(self, job_id: int, result: RecordingResult) -> None:
        if job_id not in self._closing_ids:
            return
        self._closing_ids.discard(job_id)
        self.stopped.emit(result)


def describe_result(r: RecordingResult) -> str:
    """One line for the status bar / error bar about a finished recording."""
    kept = f"{r.frames} frames ({format_elapsed(r.duration_s)}) in {r.folder}"
    if r.error:
        return f"Recording stopped: {r.error}. The {kept} written before are kept."
    return f"Recorded {kept}" + (f" ({r.note})." if r.note else ".")
