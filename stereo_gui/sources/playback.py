"""Playing recorded stereo frames back as a live source, with pause, step, seek and loop.

`PlaybackSource(path)` reads
- a recording folder written by `stereo_gui.files.recording.RecordingWriter` (its PNG pairs,
  or its side-by-side video when it holds no images), with the recorded timestamps;
- a plain folder of pairs in any layout `stereo_gui.files.pairs.discover_pairs` knows;
- a side-by-side video file (left half | right half).

Paced playback delivers frame i at the recorded time offset (t_left[i] - t_left[0]) after the
start, or at a fixed `fps` when given or when there are no timestamps. While paused, `read()`
delivers the current frame again (at most `STILL_FPS` times a second when paced) so that the live
view keeps processing it while parameters are tuned; `step()` and `seek()` change that frame.
When playback reaches the end with `loop=False` it holds the last frame (paused and `finished`),
or with `at_end="raise"` makes the next `read()` raise SourceError.

Thread safety: one worker thread calls `read()` while the UI calls `pause()`, `resume()`,
`step()`, `seek()`, `set_loop()`; a condition variable guards the playback state and wakes a
waiting `read()` at once, and `close()` wakes it too.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.errors import SourceError, StereoGuiError
from stereo_gui.files.pairs import discover_pairs, load_image
from stereo_gui.files.recording import Recording, is_recording, open_recording
from stereo_gui.sources.base import FrameSource, StereoFrame

log = logging.getLogger(__name__)

PLAIN_FOLDER_FPS = 5.0  # a folder of still pairs (calibration shots) is shown at this rate
STILL_FPS = 10.0  # how often a paused frame is delivered again when paced
_BEHIND_S = 0.5  # further behind schedule than this, playback re-anchors instead of rushing
VIDEO_EXTENSIONS = (".avi", ".mp4", ".mkv", ".mov", ".m4v", ".webm")


# ---- frame stores ---------------------------------------------------------------------------
class _ImageStore:
    """Frames as pairs of image files."""

    def __init__(self, files: list[tuple[Path, Path]]) -> None:
        self.files = files
        self.count = len(files)

    def load(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        left, right = self.files[i]
        try:
            images = load_image(left), load_image(right)
        except StereoGuiError as exc:
            raise SourceError(str(exc)) from exc
        (hl, wl), (hr, wr) = images[0].shape[:2], images[1].shape[:2]
        if (wl, hl) != (wr, hr):  # as a camera pair must: nothing downstream can use such a pair
            raise SourceError(f"{left.name} is {wl}x{hl} but {right.name} is {wr}x{hr}: both "
                              "images of a pair must have the same size")
        return images

    def close(self) -> None:
        pass


class _VideoStore:
    """Frames of a side-by-side video (left half | right half)."""

    def __init__(self, path: Path, limit: int | None = None) -> None:
        self.path = path
        self._cap = cv2.VideoCapture(str(path))
        if not self._cap.isOpened():
            raise SourceError(f"cannot open video {path}")
        n = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        if n <= 0:  # some containers do not say: count once
            n = 0
            while self._cap.grab():
                n += 1
            self._reopen()
        self.count = n if limit is None else min(n, limit)
        self.fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self._next = 0  # index the capture reads next

    def _reopen(self) -> None:
        self._cap.release()
        self._cap = cv2.VideoCapture(str(self.path))
        self._next = 0

    def load(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        if i != self._next:
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, i)
            self._next = i
        ok, frame = self._cap.read()
        if not ok:  # a container that does not seek: read up to the frame
            self._reopen()
            for _ in range(i):
                self._cap.grab()
            ok, frame = self._cap.read()
            if not ok:
                raise SourceError(f"cannot read frame {i} of video {self.path}")
        self._next = i + 1
        h, w = frame.shape[:2]
        if w % 2:
            raise SourceError(f"video {self.path} is {w} px wide: a side-by-side stereo video "
                              "needs an even width")
        half = w // 2
        return np.ascontiguousarray(frame[:, :half]), np.ascontiguousarray(frame[:, half:])

    def close(self) -> None:
        self._cap.release()


_Store = _ImageStore | _VideoStore


@dataclass(frozen=True)
class _Frames:
    """What a recording, folder or video opened to: its frames, its name, the recorded times
    (None: none recorded), its frame rate, the size a recording's header says, and what
    opening tolerated."""

    store: _Store
    name: str
    times: list[tuple[float, float]] | None = None
    default_fps: float = PLAIN_FOLDER_FPS
    recorded_size: tuple[int, int] | None = None
    warnings: tuple[str, ...] = ()


def _open_frames(path: Path) -> _Frames:
    """Open a recording folder, a plain folder of pairs or a side-by-side video file."""
    if path.is_dir():
        if is_recording(path):
            return _open_recording(path)
        found = discover_pairs(path)
        return _Frames(_ImageStore([(p.left, p.right) for p in found.pairs]),
                       f"Pairs in {path.name}")
    if path.is_file():
        video = _VideoStore(path)
        return _Frames(video, f"Video {path.name}",
                       default_fps=video.fps if video.fps > 0 else 30.0)
    raise SourceError(f"{path}: no such recording, folder or video")


def _open_recording(path: Path) -> _Frames:
    """A recording's frames: its images, else its side-by-side video, with their times."""
    rec = open_recording(path)
    if not rec.frames:
        raise SourceError(f"recording {path} holds no frames")
    times = [(f.t_left, f.t_right) for f in rec.frames]
    store: _Store
    if rec.has_images:
        store = _ImageStore(_image_pairs(rec))
    elif rec.video is not None:
        store = _VideoStore(rec.video, limit=len(rec.frames))
        times = times[: store.count]
    else:
        raise SourceError(f"recording {path} holds neither images nor a video")
    return _Frames(store, f"Playback of {path.name}", times, rec.fps, rec.size,
                   tuple(rec.warnings))


def _image_pairs(rec: Recording) -> list[tuple[Path, Path]]:
    """The image files of a recording that has images, frame by frame."""
    pairs = []
    for f in rec.frames:
        if f.left is None or f.right is None:
            raise SourceError(f"recording {rec.folder}: frame {f.index} has only one image")
        pairs.append((f.left, f.right))
    return pairs


def _pacing(times: list[tuple[float, float]], fixed_rate: bool, fps: float
            ) -> tuple[np.ndarray, float]:
    """(the schedule paced playback follows, s from the first frame; the typical interval
    between frames, s): the recorded times of the left frames when they can be followed
    (no `fixed_rate`, finite, in order), else a frame every 1/`fps` s."""
    n = len(times)
    rec_t = np.array([t[0] for t in times], float)
    if not fixed_rate and n > 1 and np.all(np.isfinite(rec_t)) and np.all(np.diff(rec_t) >= 0):
        schedule = rec_t - rec_t[0]
    else:
        schedule = np.arange(n, dtype=float) / fps
    interval = (float(np.median(np.diff(schedule))) if n > 1 else 1.0 / fps) or 1.0 / fps
    return schedule, interval


# ---- the source -----------------------------------------------------------------------------
class PlaybackSource(FrameSource):
    """A recording, a folder of pairs or a side-by-side video as a FrameSource (see module doc).

    `fps` overrides the recorded timing (frames per second); `paced=False` returns frames as fast
    as they load (benchmarks, tests).
    """

    def __init__(self, path: str | os.PathLike[str], fps: float | None = None, loop: bool = True,
                 paced: bool = True, at_end: str = "hold") -> None:
        if fps is not None and not (fps > 0 and math.isfinite(fps)):
            raise SourceError(f"playback frame rate must be positive, not {fps}")
        if at_end not in ("hold", "raise"):
            raise SourceError(f"at_end must be 'hold' or 'raise', not {at_end!r}")
        self.path = Path(path)
        self.paced = bool(paced)
        self.at_end = at_end
        opened = _open_frames(self.path)
        self._store: _Store = opened.store
        self.name = opened.name
        self.warnings: tuple[str, ...] = opened.warnings  # what opening tolerated (a torn frame)
        if self._store.count == 0:
            self._store.close()
            raise SourceError(f"{self.path} holds no frames")
        if opened.recorded_size is not None and opened.recorded_size != (0, 0):
            self._check_recorded_size(opened.recorded_size)
        self.nominal_fps = float(fps) if fps is not None else float(opened.default_fps)
        n = self._store.count
        times = opened.times
        if times is None:
            times = [(i / self.nominal_fps, i / self.nominal_fps) for i in range(n)]
        self._times = times  # what StereoFrame carries: the recorded capture times, s
        # the schedule (s from the first frame) that pacing follows
        self._schedule, self._frame_interval = _pacing(times, fps is not None, self.nominal_fps)

        self._cond = threading.Condition()
        self._store_lock = threading.Lock()
        # playback state, guarded by self._cond
        self._loop = bool(loop)
        self._pos = 0  # the frame the next read() delivers
        self._last: int | None = None  # the frame the last read() delivered
        self._paused = False
        self._speed = 1.0
        self._finished = False
        self._ended = False  # at_end="raise": the next read raises
        self._changed = False  # a pause/step/seek since the last delivery: deliver at once
        self._anchor: tuple[int, float] | None = None  # (frame, monotonic time it was due)
        self._closed = False
        self._cache: tuple[int, np.ndarray, np.ndarray] | None = None

    def _check_recorded_size(self, size: tuple[int, int]) -> None:
        """Say where a recording's header names another picture size than its first frame has
        (the pictures are what is shown and measured; the header's size is only said)."""
        try:
            left, _ = self._store.load(0)
        except SourceError:
            return  # said when the frame is played
        h, w = left.shape[:2]
        if (w, h) != tuple(size):
            text = (f"{self.path}: the header says {size[0]}x{size[1]} px but the pictures are "
                    f"{w}x{h} px; the pictures' size is used")
            log.warning("%s", text)
            self.warnings = (*self.warnings, text)

    # ---- information --------------------------------------------------------------------
    @property
    def frame_count(self) -> int:
        return self._store.count

    @property
    def position(self) -> int:
        """Index of the frame shown: the one delivered last (or the one about to be, after a
        step or seek)."""
        with self._cond:
            if self._paused or self._last is None:
                return self._pos
            return self._last

    @property
    def paused(self) -> bool:
        with self._cond:
            return self._paused

    @property
    def finished(self) -> bool:
        """True when playback without loop reached the last frame."""
        with self._cond:
            return self._finished

    @property
    def loop(self) -> bool:
        with self._cond:
            return self._loop

    @property
    def duration_s(self) -> float:
        return float(self._schedule[-1]) + self._frame_interval

    def timestamps(self, i: int) -> tuple[float, float]:
        """Recorded (t_left, t_right) of frame i, s."""
        return self._times[i]

    def time_s(self, i: int) -> float:
        """When frame i was recorded, s after the first frame (its place in the playback)."""
        return float(self._schedule[min(max(int(i), 0), self.frame_count - 1)])

    @property
    def speed(self) -> float:
        """Playback speed: 1 plays at the recorded pace, 2 twice as fast, 0.5 at half speed."""
        with self._cond:
            return self._speed

    def set_speed(self, speed: float) -> None:
        """Play at `speed` times the recorded pace from the next frame on (SourceError if it is
        not a positive number)."""
        if not (speed > 0 and math.isfinite(speed)):
            raise SourceError(f"playback speed must be positive, not {speed}")
        with self._cond:
            self._speed = float(speed)
            self._anchor = None  # the next frame is due at once, the ones after at the new pace
            self._cond.notify_all()

    # ---- control (any thread) -----------------------------------------------------------
    def set_loop(self, loop: bool) -> None:
        with self._cond:
            self._loop = bool(loop)
            self._cond.notify_all()

    def pause(self) -> None:
        """Hold the frame shown now; read() delivers it again until resume/step/seek."""
        with self._cond:
            if not self._paused:
                self._paused = True
                if self._last is not None:
                    self._pos = self._last
                self._changed = True
                self._cond.notify_all()

    def resume(self) -> None:
        """Play on from the frame after the one shown (from the start after the end)."""
        with self._cond:
            if not self._paused:
                return
            self._paused = False
            if self._last is not None and self._pos == self._last:
                self._pos = self._pos + 1
                if self._pos >= self.frame_count:
                    self._pos = 0
            self._finished = False
            self._ended = False
            self._anchor = None
            self._changed = True
            self._cond.notify_all()

    def step(self, n: int = 1) -> int:
        """Pause (if playing) and move `n` frames (negative: back); return the new position.

        Wraps around with loop on, stops at the first/last frame with loop off.
        """
        with self._cond:
            if not self._paused:
                self._paused = True
                if self._last is not None:
                    self._pos = self._last
            self._pos = self._wrap(self._pos + int(n))
            self._finished = False
            self._changed = True
            self._cond.notify_all()
            return self._pos

    def seek(self, i: int) -> int:
        """Make frame `i` (clamped to the recording) the next one delivered; return it."""
        with self._cond:
            self._pos = min(max(int(i), 0), self.frame_count - 1)
            self._anchor = None
            self._finished = False
            self._ended = False
            self._changed = True
            self._cond.notify_all()
            return self._pos

    def _wrap(self, i: int) -> int:
        n = self.frame_count
        return i % n if self._loop else min(max(i, 0), n - 1)

    # ---- FrameSource --------------------------------------------------------------------
    def playback(self) -> PlaybackSource:
        return self

    def read(self) -> StereoFrame:
        with self._cond:
            i = self._next_index()
        left, right = self._load(i)
        t_left, t_right = self._times[i]
        return StereoFrame(left, right, t_left, t_right, i)

    def _next_index(self) -> int:
        """Wait (interruptibly) until a frame is due; return its index and advance. Holds _cond."""
        while True:
            if self._closed:
                raise SourceError(f"{self.name} was closed")
            if self._ended:
                raise SourceError(f"{self.name}: end of the recording")
            i = self._pos
            if self._paused:
                if self._changed or self._last is None or not self.paced:
                    break
                # still frame: deliver again after a while, or at once on a change
                deadline = time.monotonic() + 1.0 / min(STILL_FPS, self.nominal_fps)
                while not (self._changed or self._closed or not self._paused):
                    left_s = deadline - time.monotonic()
                    if left_s <= 0:
                        break
                    self._cond.wait(left_s)
                if self._changed or self._closed or not self._paused:
                    continue
                break
            if not self.paced:
                break
            now = time.monotonic()
            sequential = self._last is not None and i == self._last + 1 and not self._changed
            wrapped = self._last is not None and i == 0 and self._last == self.frame_count - 1 \
                and not self._changed
            if self._anchor is None or not (sequential or wrapped):
                self._anchor = (i, now)
            elif wrapped and self._last is not None:
                prev_due = self._due(self._anchor, self._last)
                self._anchor = (0, prev_due + self._frame_interval / self._speed)
            due = self._due(self._anchor, i)
            if due - now > 0:
                self._changed = False
                self._cond.wait(due - now)
                if self._changed or self._closed or self._paused or self._pos != i:
                    continue  # something changed while waiting: decide again
                # the wait may also end early on a spurious wake-up: check the time
                if time.monotonic() < due:
                    continue
            elif now - due > _BEHIND_S:
                self._anchor = (i, now)  # far behind (slow consumer): do not rush to catch up
            break
        self._changed = False
        self._last = i
        if not self._paused:
            nxt = i + 1
            if nxt < self.frame_count:
                self._pos = nxt
            elif self._loop:
                self._pos = 0
            elif self.at_end == "raise":
                self._ended = True
            else:
                self._paused = True
                self._finished = True
        return i

    def _due(self, anchor: tuple[int, float], i: int) -> float:
        """When frame `i` is due (time.monotonic() s), paced from `anchor` (frame, when)."""
        a, t0 = anchor
        return t0 + float(self._schedule[i] - self._schedule[a]) / self._speed

    def _load(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        with self._store_lock:
            if self._closed:
                raise SourceError(f"{self.name} was closed")
            if self._cache is None or self._cache[0] != i:
                left, right = self._store.load(i)
                self._cache = (i, left, right)
            # copies: a consumer that draws on its frame must not change the held one
            return self._cache[1].copy(), self._cache[2].copy()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        with self._store_lock:
            self._store.close()
            self._cache = None
