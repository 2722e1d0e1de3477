"""Recording the live stereo stream to a folder, and reading such a folder back.

A recording is a folder:

    recording.json     header: format version, image size, frame rate, source name, creation
                       time, frame count, whether it was closed cleanly, what it holds, and
                       the skew between the cameras' frame times (median and worst, ms)
    frames.csv         one line per frame: index, t_left, t_right (seconds, the source's clock,
                       written with full float precision), left, right (image files, relative)
    left/000001.png    the raw left images (PNG: lossless), numbered from 1
    right/000001.png   the raw right images
    stereo.avi         optional: the pairs side by side (left | right) as a video

The `left/` + `right/` layout is one that `stereo_gui.files.pairs.discover_pairs` reads, so a
recording is also a plain folder of pairs. Images are written atomically (temporary file, then
rename); `frames.csv` is append-only and flushed after each frame, and its line is written only
after both images exist, so a crash loses at most the frame being written. The header is
rewritten atomically at the start and at `close()`. The video is written under a temporary name
and renamed at `close()`.

Video codecs the opencv-contrib-python-headless wheel writes (checked): MJPG (.avi, lossy, read
everywhere) and FFV1 (.avi, lossless). Playback prefers the PNG images when both exist.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import logging
import math
import os
import queue
import shutil
import threading
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.timing import SkewStats, skew_stats
from stereo_gui.files.atomic import os_error_text, write_bytes_atomic, write_json_atomic
from stereo_gui.files.readers import read_csv_rows, read_json_object

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
KIND = "stereo-gui recording"
HEADER = "recording.json"
FRAMES = "frames.csv"
VIDEO = "stereo.avi"
FRAME_COLUMNS = ("index", "t_left", "t_right", "left", "right")
VIDEO_CODECS = ("MJPG", "FFV1")


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def frame_file(side: str, number: int) -> str:
    """Relative path of image `number` (from 1) of `side` ("left" or "right")."""
    return f"{side}/{number:06d}.png"


@dataclass(frozen=True)
class RecordedFrame:
    """One recorded frame: its index (from 0), capture times (s) and image files (or None)."""

    index: int
    t_left: float
    t_right: float
    left: Path | None
    right: Path | None


@dataclass(frozen=True)
class Recording:
    """A recording folder as read back by `open_recording`."""

    folder: Path
    size: tuple[int, int]  # (width, height) of one image, px
    fps: float  # the rate recorded (from the frames' times), frames per second
    source_name: str
    created: str
    frames: tuple[RecordedFrame, ...]
    video: Path | None  # the side-by-side video, when one was written
    complete: bool  # closed cleanly (False after a crash: the frames up to it are still there)
    warnings: tuple[str, ...] = field(default=())

    @property
    def has_images(self) -> bool:
        return bool(self.frames) and all(f.left is not None for f in self.frames)

    @property
    def skew(self) -> SkewStats:
        """How far apart in time the two cameras took their pictures, over the whole
        recording (from each frame's t_left and t_right)."""
        return skew_stats([f.t_left for f in self.frames], [f.t_right for f in self.frames])


class RecordableFrame(Protocol):
    """What a recording takes of a frame: a `stereo_gui.sources.base.StereoFrame` is one."""

    @property
    def left(self) -> np.ndarray: ...

    @property
    def right(self) -> np.ndarray: ...

    @property
    def t_left(self) -> float: ...

    @property
    def t_right(self) -> float: ...

    @property
    def index(self) -> int: ...


@dataclass(frozen=True, eq=False)
class _Queued:
    """A frame's images (copied) and times, waiting for the writer thread."""

    left: np.ndarray
    right: np.ndarray
    t_left: float
    t_right: float
    index: int


class RecordingWriter:
    """Writes stereo frames to a new recording folder (see the module doc for the layout).

    Frames are `stereo_gui.sources.base.StereoFrame`s, or anything with `left`, `right` (BGR or
    gray uint8 images), `t_left`, `t_right` (s) and `index`.

    `write()` hands the frame to a background thread (a bounded queue: when the disk cannot keep
    up, `write()` waits rather than drop frames) so the caller's loop is not slowed by PNG
    encoding. An error while writing is raised by the next `write()` or by `close()`.
    Use as a context manager, or call `close()`.
    """

    def __init__(self, folder: str | os.PathLike[str], *, source_name: str = "", fps: float = 30.0,
                 images: bool = True, video: str | None = None, background: bool = True,
                 queue_size: int = 32) -> None:
        if not images and video is None:
            raise InputError("a recording needs images, a video, or both")
        if video is not None and video not in VIDEO_CODECS:
            raise InputError(f"video codec must be one of {', '.join(VIDEO_CODECS)}, not {video!r}")
        if not (fps > 0 and math.isfinite(fps)):
            raise InputError(f"frame rate must be positive, not {fps}")
        self.folder = Path(folder)
        if self.folder.exists() and (not self.folder.is_dir() or any(self.folder.iterdir())):
            raise InputError(f"cannot record into {self.folder}: it exists and is not an empty "
                             "folder (a recording never overwrites anything)")
        self._made_folder = not self.folder.exists()  # (a failed start removes only what it made)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            if images:
                (self.folder / "left").mkdir()
                (self.folder / "right").mkdir()
        except OSError as exc:
            raise InputError(f"cannot create recording folder {self.folder}: "
                             f"{exc.strerror or exc}") from exc
        self.source_name = source_name
        self.fps = float(fps)
        self.images = images
        self.codec = video
        self.created = _now()
        self.size: tuple[int, int] | None = None
        self._count = 0
        self._t_span: tuple[float, float] | None = None  # first and last frame time, s
        self._times: list[tuple[float, float]] = []  # (t_left, t_right) of each frame, s
        self._video: cv2.VideoWriter | None = None
        self._video_tmp = self.folder / f".{VIDEO}.partial.avi"
        self._error: BaseException | None = None
        self._closed = False
        self._lock = threading.Lock()
        try:
            self._csv_file = open(self.folder / FRAMES, "w", newline="", encoding="utf-8")
        except OSError as exc:
            _remove_empty_recording(self.folder, self._made_folder)
            raise InputError(f"cannot write {self.folder / FRAMES}: {os_error_text(exc)}") \
                from exc
        self._csv = csv.writer(self._csv_file, lineterminator="\n")
        try:
            self._csv.writerow(FRAME_COLUMNS)
            self._csv_file.flush()
            self._write_header(complete=False)
        except (OSError, InputError) as exc:  # a full disk: nothing recorded, nothing left
            with contextlib.suppress(OSError):
                self._csv_file.close()
            _remove_empty_recording(self.folder, self._made_folder)
            why = os_error_text(exc) if isinstance(exc, OSError) else str(exc)
            raise InputError(f"cannot record into {self.folder}: {why}") from exc
        self._queue: queue.Queue[_Queued | None] | None = None  # None: the writer stops
        self._thread: threading.Thread | None = None
        if background:
            self._queue = queue.Queue(maxsize=max(1, queue_size))
            self._thread = threading.Thread(target=self._run, args=(self._queue,),
                                            name="recording-writer", daemon=True)
            self._thread.start()

    # ---- public -----------------------------------------------------------------------------
    @property
    def frames_written(self) -> int:
        with self._lock:
            return self._count

    def write(self, frame: RecordableFrame) -> None:
        """Record one frame (raw images and their timestamps)."""
        if self._closed:
            raise InputError(f"recording {self.folder} is closed")
        self._raise_pending()
        if self._queue is not None:
            # copies: the caller may reuse its buffers once write() returns
            self._queue.put(_Queued(np.array(frame.left), np.array(frame.right),
                                    float(frame.t_left), float(frame.t_right), int(frame.index)))
        else:
            self._write_now(frame)

    def flush(self) -> None:
        """Wait until every frame handed to `write()` is on disk; raise a pending error."""
        if self._queue is not None and self._thread is not None and self._thread.is_alive():
            self._queue.join()
        self._raise_pending()

    def close(self) -> Recording:
        """Finish the recording (wait for queued frames), write its header; return it read back."""
        if not self._closed:
            self._closed = True
            if self._thread is not None and self._queue is not None:
                self._queue.put(None)
                self._thread.join()
            try:
                self._csv_file.close()
            except OSError as exc:  # pragma: no cover - disk failures at close
                self._error = self._error or exc
            if self._video is not None:
                self._video.release()
                self._video = None
                try:
                    # cv2.VideoWriter does not report a full disk: the video is read back
                    self._verify_video()
                    os.replace(self._video_tmp, self.folder / VIDEO)
                except (OSError, InputError) as exc:
                    self._error = self._error or exc
            if self._error is None:
                self._write_header(complete=True)
            elif self._count == 0:  # it failed before its first frame: it holds nothing
                _remove_empty_recording(self.folder, self._made_folder)
        self._raise_pending()
        return open_recording(self.folder)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:  # keep what was recorded, but do not hide the original error
            try:
                self.close()
            except Exception:  # noqa: BLE001
                log.warning("closing recording %s after an error failed", self.folder,
                            exc_info=True)

    # ---- internals --------------------------------------------------------------------------
    def _raise_pending(self) -> None:
        err = self._error
        if err is None:
            return
        if isinstance(err, InputError):
            raise err
        msg = os_error_text(err) if isinstance(err, OSError) else str(err)
        kept = (f"; its {self._count} frames recorded are kept" if self._count
                else "; nothing was recorded")
        raise InputError(f"recording to {self.folder} failed: {msg}{kept}") from err

    def _run(self, frames: queue.Queue[_Queued | None]) -> None:
        while True:
            item = frames.get()
            try:
                if item is None:
                    return
                if self._error is None:  # after an error: drain, the caller hears of it
                    self._write_now(item)
            except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                self._error = exc
            finally:
                frames.task_done()

    def _write_now(self, frame: RecordableFrame) -> None:
        left, right = frame.left, frame.right
        size = (int(left.shape[1]), int(left.shape[0]))
        if right.shape[:2] != left.shape[:2]:
            raise InputError("left and right images of a frame differ in size")
        if self.size is None:
            self.size = size
            self._write_header(complete=False)
        elif size != self.size:
            raise InputError(f"frame of {size[0]}x{size[1]} px in a recording of "
                             f"{self.size[0]}x{self.size[1]} px")
        number = self._count + 1
        lrel = rrel = ""
        if self.images:
            lrel, rrel = frame_file("left", number), frame_file("right", number)
            for rel, img in ((lrel, left), (rrel, right)):
                ok, png = cv2.imencode(".png", img)
                if not ok:
                    raise InputError(f"frame {frame.index} could not be encoded as PNG")
                write_bytes_atomic(self.folder / rel, png.tobytes())
        if self.codec is not None:
            self._write_video(self.codec, left, right)
        self._csv.writerow([self._count, repr(float(frame.t_left)), repr(float(frame.t_right)),
                            lrel, rrel])
        self._csv_file.flush()
        t = float(frame.t_left)
        self._times.append((t, float(frame.t_right)))
        self._t_span = (t, t) if self._t_span is None else (self._t_span[0], t)
        with self._lock:
            self._count += 1

    def measured_fps(self) -> float | None:
        """Frames per second as recorded (from the first and last frame's times), None before
        two frames or without a time span."""
        if self._t_span is None or self._count < 2:
            return None
        span = self._t_span[1] - self._t_span[0]
        rate = (self._count - 1) / span if span > 0 and math.isfinite(span) else None
        # frames made faster than any camera (an unpaced source, a replay at full speed): the
        # header cannot hold that rate (the reader refuses one above MAX_FPS); the nominal one goes
        return rate if rate is not None and rate <= MAX_FPS else None

    def _write_video(self, codec: str, left: np.ndarray, right: np.ndarray) -> None:
        def bgr(img: np.ndarray) -> np.ndarray:
            return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img

        sbs = np.hstack([bgr(left), bgr(right)])
        if self._video is None:
            h, w = sbs.shape[:2]
            self._video = cv2.VideoWriter(str(self._video_tmp), cv2.VideoWriter.fourcc(*codec),
                                          self.fps, (w, h))
            if not self._video.isOpened():
                self._video = None
                raise InputError(f"cannot write a {codec} video in {self.folder}")
        self._video.write(np.ascontiguousarray(sbs))

    def _verify_video(self) -> None:
        cap = cv2.VideoCapture(str(self._video_tmp))
        try:
            frames = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else 0
        finally:
            cap.release()
        if frames < self._count:
            raise InputError(f"the video of {self.folder} holds {frames} of {self._count} "
                             "frames (the disk may be full); it is kept as "
                             f"{self._video_tmp.name}")

    def _write_header(self, complete: bool) -> None:
        header = {
            "format_version": FORMAT_VERSION,
            "kind": KIND,
            "created": self.created,
            "source": self.source_name,
            # what was recorded (a source meant for 30 fps may have delivered 10.7), and what
            # the source said it would deliver
            "fps": self.measured_fps() or self.fps,
            "nominal_fps": self.fps,
            "size": list(self.size) if self.size else None,
            "frames": self._count,
            "images": "png" if self.images else None,
            "video": VIDEO if self.codec else None,
            "video_codec": self.codec,
            "complete": complete,
        }
        if self._times:
            st = skew_stats(*zip(*self._times, strict=True))
            # for people and other tools: the frames' own times say the same, frame by frame
            header["skew_ms"] = {"median": round(st.median_ms, 3), "worst": round(st.worst_ms, 3),
                                 "frames": st.frames}
        write_json_atomic(self.folder / HEADER, header)


def is_recording(folder: str | os.PathLike[str]) -> bool:
    return (Path(folder) / HEADER).is_file()


MAX_FPS = 1000.0
# a frame time beyond this (about the year 5138 counted from 1970) is no clock's
MAX_TIME_S = 1e11
MIN_FPS = 1e-4  # a frame every three hours (a time-lapse); fewer is no recording to play back
MAX_SIDE_PX = 100_000
MAX_FRAMES = 10_000_000


def _ends_with_newline(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            fh.seek(0, os.SEEK_END)
            if fh.tell() == 0:
                return True
            fh.seek(-1, os.SEEK_END)
            return fh.read(1) in (b"\n", b"\r")
    except OSError:
        return True


def _header_fields(header: dict[str, Any], hpath: Path
                   ) -> tuple[tuple[int, int], float, str, str, bool, str | None, bool]:
    """size, fps, source, created, complete, video name, images: checked, or InputError naming
    the field."""
    def bad(field: str, text: str) -> InputError:
        return InputError(f"{hpath}: {field} {text}")

    fps = header.get("fps", 30.0)
    if fps is None:
        fps = 30.0
    if isinstance(fps, bool) or not isinstance(fps, int | float) or \
            not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise bad("fps", f"is {fps!r:.40}; it must be a number of frames per second from "
                         f"{MIN_FPS:g} to {MAX_FPS:g}")
    size = header.get("size")
    if size is None:
        size = [0, 0]
    elif not (isinstance(size, list) and len(size) == 2 and all(
            isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_SIDE_PX
            for v in size)):
        raise bad("size", f"is {size!r:.60}; it must be [width, height] in px (1 to "
                          f"{MAX_SIDE_PX})")
    for key in ("source", "created"):
        if not isinstance(header.get(key, ""), str):
            raise bad(key, "should be text")
    complete = header.get("complete", False)
    if not isinstance(complete, bool):
        raise bad("complete", "should be true or false")
    video = header.get("video")
    if video is not None and (not isinstance(video, str) or video != VIDEO):
        raise bad("video", f"should be {VIDEO!r} or null, not {video!r:.60}")
    images = header.get("images", "png")
    if images not in ("png", None):
        raise bad("images", f"should be \"png\" or null, not {images!r:.40}")
    frames = header.get("frames", 0)
    if isinstance(frames, bool) or not isinstance(frames, int) or not 0 <= frames <= MAX_FRAMES:
        raise bad("frames", f"is {frames!r:.40}; it must be a count from 0 to {MAX_FRAMES}")
    return ((int(size[0]), int(size[1])), float(fps), header.get("source", ""),
            header.get("created", ""), complete, video, images is not None)


def _image_path(folder: Path, rel: str, where: str, field: str) -> Path | None:
    if not rel:
        return None
    path = folder / rel
    try:
        inside = not Path(rel).is_absolute() and \
            path.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError, ValueError):
        inside = False
    if not inside:
        raise InputError(f"{where}: {field} {rel[:80]!r} is not a file inside the recording")
    return path


def _read_header(folder: Path) -> tuple[dict[str, Any], Path]:
    """The recording's header as JSON and its path; InputError when it is not ours or newer."""
    hpath = folder / HEADER
    if not hpath.is_file():
        raise InputError(f"{folder} is not a recording (no {HEADER})")
    header = read_json_object(hpath, "recording header")
    if header.get("kind") != KIND:
        raise InputError(f"{hpath} is not a stereo-gui recording header")
    version = header.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version > FORMAT_VERSION:
        raise InputError(f"{hpath} has format version {version!r:.40}; this version reads "
                         f"{FORMAT_VERSION} and older")
    return header, hpath


def _parse_frame_line(row: list[str], images: bool,
                      unfinished: bool) -> tuple[int, float, float, str, str]:
    """(index, t_left, t_right, left image, right image) of a line of frames.csv; ValueError
    when it cannot be read (`unfinished`: the file ends in the middle of it)."""
    if len(row) != len(FRAME_COLUMNS):
        raise ValueError(f"it has {len(row)} fields, not {len(FRAME_COLUMNS)}")
    idx, tl, tr = int(row[0]), float(row[1]), float(row[2])
    lrel, rrel = row[3], row[4]
    if images and not (lrel and rrel):
        raise ValueError("an image file is missing from the line")
    if unfinished:
        raise ValueError("the line is not finished")
    return idx, tl, tr, lrel, rrel


def _read_frames(folder: Path, images: bool, warnings: list[str]) -> list[RecordedFrame]:
    """The frames frames.csv lists whose images are there; a torn last line and frames whose
    images are missing are left out, said in `warnings`."""
    frames: list[RecordedFrame] = []
    fpath = folder / FRAMES
    rows = read_csv_rows(fpath, FRAME_COLUMNS, "a recording's frame list")
    torn_end = not _ends_with_newline(fpath)
    last_index = -1
    last_t = (-math.inf, -math.inf)
    for line, row in enumerate(rows, start=2):
        is_last = line == len(rows) + 1
        where = f"{fpath}, line {line}"
        if not row:
            continue
        try:
            idx, tl, tr, lrel, rrel = _parse_frame_line(row, images, torn_end and is_last)
        except ValueError as exc:
            if is_last:  # the process died while writing it: what came before is whole
                warnings.append(f"{where}: torn last line left out ({exc})")
                continue
            raise InputError(f"{where}: unreadable ({exc})") from None
        if idx < 0 or idx <= last_index:
            raise InputError(f"{where}: index {idx} is negative or does not follow "
                             f"{last_index} (indices must rise)")
        if not (abs(tl) <= MAX_TIME_S and abs(tr) <= MAX_TIME_S):  # (False for NaN)
            raise InputError(f"{where}: t_left/t_right must be seconds of a clock (at most "
                             f"{MAX_TIME_S:g}), not {row[1]!r:.30}, {row[2]!r:.30}")
        if tl < last_t[0] or tr < last_t[1]:
            raise InputError(f"{where}: t_left/t_right go backwards in time")
        last_index, last_t = idx, (tl, tr)
        left = _image_path(folder, lrel, where, "left")
        right = _image_path(folder, rrel, where, "right")
        if (left is not None and not left.is_file()) or (right is not None and not right.is_file()):
            warnings.append(f"{where}: images missing, frame {idx} left out")
            continue
        frames.append(RecordedFrame(idx, tl, tr, left, right))
    return frames


def open_recording(folder: str | os.PathLike[str]) -> Recording:
    """Read a recording folder's header and frame list; raise InputError naming the file and the
    field when it is not one or is damaged (indices that are negative, repeated or go backwards,
    times that are not finite or go backwards, image paths outside the folder, ...).

    A recording cut short by a crash opens with what was written (`complete` False): a torn last
    line of frames.csv and frames whose images are missing are left out with a warning.
    """
    folder = Path(folder)
    header, hpath = _read_header(folder)
    size, fps, source, created, complete, video_name, images = _header_fields(header, hpath)
    warnings: list[str] = []
    frames = _read_frames(folder, images, warnings)
    video = folder / video_name if video_name else None
    if video is not None and not video.is_file():
        warnings.append(f"{folder}: video {video.name} is missing (recording not closed?)")
        video = None
    if not complete:
        warnings.append(f"{folder}: the recording was not closed cleanly; "
                        f"{len(frames)} frame(s) were saved")
    for w in warnings:
        log.warning("%s", w)
    return Recording(folder, size, fps, source, created, tuple(frames), video, complete,
                     tuple(warnings))


def _remove_empty_recording(folder: Path, made: bool) -> None:
    """Remove what a recording that holds no frame made (its empty left/ and right/, its frame
    list and header; the folder itself when `made` by it), as a failed start leaves it; anything
    else there is kept."""
    try:
        for side in ("left", "right"):
            if (folder / side).is_dir() and any((folder / side).iterdir()):
                return
        if any(p.name not in ("left", "right", FRAMES, HEADER) and not p.name.startswith(".")
               for p in folder.iterdir()):
            return
        if made:
            shutil.rmtree(folder)
            return
        for p in folder.iterdir():
            shutil.rmtree(p) if p.is_dir() else p.unlink()
    except OSError as exc:
        log.info("cannot remove the empty recording %s: %s", folder, os_error_text(exc))
