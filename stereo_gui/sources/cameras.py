"""Real frame sources: two USB cameras, one side-by-side stereo camera, a side-by-side video file.

All use cv2.VideoCapture, with the backend cv2-enumerate-cameras lists a camera under (it names
cameras, with USB vendor and product ids, on Windows, Linux and macOS). Devices fail in the field (unplugged, claimed by another program, a USB
bus without bandwidth for two streams); every such failure becomes a SourceError whose message
names the device and says what to try.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn, Protocol

import cv2
import cv2_enumerate_cameras
import numpy as np

from stereo_gui.core.camera_settings import CameraSettings
from stereo_gui.core.errors import SourceError, SourceUnavailable
from stereo_gui.sources.base import FramePacer, FrameSource, StereoFrame
from stereo_gui.sources.camera_controls import CameraControls, PairControls

log = logging.getLogger(__name__)

SYSFS_VIDEO = Path("/sys/class/video4linux")
# consecutive failed grabs before a camera counts as gone (a single dropped frame is normal)
MAX_FAILED_GRABS = 5
# the backends cv2-enumerate-cameras lists a camera under, best first: each camera is shown once,
# under the first (V4L2 before GStreamer on Linux, Media Foundation before DirectShow on Windows)
_BACKEND_ORDER = (cv2.CAP_V4L2, cv2.CAP_MSMF, cv2.CAP_DSHOW, cv2.CAP_AVFOUNDATION,
                  cv2.CAP_GSTREAMER)
BACKEND_NAMES = {cv2.CAP_V4L2: "V4L2", cv2.CAP_MSMF: "MSMF", cv2.CAP_DSHOW: "DirectShow",
                 cv2.CAP_AVFOUNDATION: "AVFoundation", cv2.CAP_GSTREAMER: "GStreamer"}
# a grab waits at most this long where the backend honours CAP_PROP_READ_TIMEOUT_MSEC, so that
# a camera that stops answering fails the read instead of blocking the reader for ever
READ_TIMEOUT_MS = 1500
RECONNECT_INTERVAL_S = 3.0  # a camera that vanished is looked for again this often
UNAVAILABLE_WAIT_S = 0.25  # while it is missing, a read returns (SourceUnavailable) this soon


class ListedCamera(Protocol):
    """A camera as cv2-enumerate-cameras lists it (or a stand-in with the same fields)."""

    index: int
    name: str
    path: str | None
    vid: int | None
    pid: int | None


EnumerateFn = Callable[[int], Iterable[ListedCamera]]  # the cameras a backend lists


class EndOfSource(SourceError):
    """A finite source (a video file without looping) has no more frames."""


@dataclass(frozen=True)
class CameraInfo:
    """A video device: OpenCV index, the name the system gives it, its device path if any, the
    OpenCV backend (cv2.CAP_*) to open it with (None: OpenCV chooses) and its USB vendor and
    product ids when known."""

    index: int
    name: str
    path: str | None = None
    backend: int | None = None
    vid: int | None = None
    pid: int | None = None

    @property
    def usb_id(self) -> str:
        """'046d:0825', or '' when the ids are not known."""
        return f"{self.vid:04x}:{self.pid:04x}" if self.vid is not None and self.pid is not None \
            else ""

    @property
    def identity(self) -> str:
        """What a camera is remembered by besides its index: its name and USB ids, so that a
        webcam plugged in again under another index is found again."""
        return f"{self.name} [{self.usb_id}]" if self.usb_id else self.name

    def label(self) -> str:
        return f"{self.index}: {self.identity}"


def _metadata_node(path: str | None) -> bool:
    """True for a Linux webcam's second, metadata-only node (/dev/video1 beside /dev/video0),
    which sysfs marks with an "index" other than 0. cv2-enumerate-cameras tells them apart only
    when it may open the device (ioctl); without that permission it lists both."""
    if not path or not path.startswith("/dev/video"):
        return False
    try:
        return int((SYSFS_VIDEO / Path(path).name / "index").read_text().strip() or 0) != 0
    except (OSError, ValueError):
        return False


def _enumerate(enumerate_fn: EnumerateFn | None = None, backends: Iterable[int] | None = None
               ) -> list[CameraInfo]:
    """Cameras from cv2-enumerate-cameras (or `enumerate_fn(backend)`, a stand-in with the same
    results), each once, under the best backend that lists it."""
    if enumerate_fn is None:
        enumerate_fn = cv2_enumerate_cameras.enumerate_cameras
        backends = cv2_enumerate_cameras.supported_backends
    order = {b: i for i, b in enumerate(_BACKEND_ORDER)}
    cams: list[CameraInfo] = []
    seen: set[str | tuple[str, int | None, int | None, int]] = set()
    for backend in sorted(backends or (), key=lambda b: order.get(b, len(order))):
        for c in enumerate_fn(backend):
            key = c.path or (c.name, c.vid, c.pid, c.index)
            if key in seen or _metadata_node(c.path):
                continue
            seen.add(key)
            cams.append(CameraInfo(int(c.index), str(c.name or f"Camera {c.index}"), c.path,
                                   int(backend), c.vid, c.pid))
    return cams


def _probe(max_index: int) -> list[CameraInfo]:
    cams = []
    for i in range(max_index):
        with quiet_opencv():
            cap = cv2.VideoCapture(i)
        try:
            if cap.isOpened():
                cams.append(CameraInfo(i, f"Camera {i}", None))
        finally:
            cap.release()
    return cams


def list_cameras(max_probe: int = 4, enumerate_fn: EnumerateFn | None = None,
                 backends: Iterable[int] | None = None) -> list[CameraInfo]:
    """The video devices present, with names, backends and USB ids from cv2-enumerate-cameras
    (Windows, Linux, macOS; no device is opened); never raises (an empty list when none).

    `enumerate_fn(backend)` and `backends` replace the library (tests). Should the library fail,
    the first `max_probe` indices are tried with cv2.VideoCapture ("Camera N", no ids).
    """
    try:
        return _enumerate(enumerate_fn, backends)
    except Exception as exc:  # noqa: BLE001 - listing devices must never stop the application
        log.warning("listing cameras failed (%s); trying indices 0-%d", exc, max_probe - 1)
    try:
        return _probe(max_probe)
    except Exception as exc:  # noqa: BLE001
        log.warning("probing cameras failed: %s", exc)
        return []


def find_camera(index: int, cameras: list[CameraInfo]) -> CameraInfo | None:
    """The listed camera with OpenCV index `index` (the first backend's), or None."""
    return next((c for c in cameras if c.index == index), None)


def find_cameras_again(indices: tuple[int, ...], remembered: tuple[str, ...],
                       cameras: list[CameraInfo]) -> tuple[tuple[int, ...], list[str]]:
    """The indices of the remembered cameras now: a camera whose `identity` (name and USB ids)
    is no longer at its remembered index but at another listed one moved there (unplugged and
    plugged in again, another USB port). Returns the indices and a note per camera that moved.

    Cameras that are at their index, or that are not listed at all, keep their index.
    """
    if len(remembered) != len(indices) or not cameras:
        return tuple(indices), []
    out = list(indices)
    taken = {i for i, ident in zip(indices, remembered, strict=True)
             if (c := find_camera(i, cameras)) is not None and c.identity == ident}
    notes = []
    for slot, (index, ident) in enumerate(zip(indices, remembered, strict=True)):
        if not ident or index in taken:
            continue
        moved = next((c for c in cameras if c.identity == ident and c.index not in taken), None)
        if moved is not None:
            out[slot] = moved.index
            taken.add(moved.index)
            notes.append(f"camera {ident} is now at index {moved.index} (was {index})")
    return tuple(out), notes


_log_lock = threading.Lock()


@contextlib.contextmanager
def quiet_opencv() -> Iterator[None]:
    """Keep OpenCV's own lines (`[ WARN:0@1.1] ... can't open camera by index`, "OpenCV should be
    configured with libavdevice") off the terminal while a camera is opened: our SourceError
    says what happened and what to do."""
    with _log_lock:
        previous = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        try:
            yield
        finally:
            cv2.utils.logging.setLogLevel(previous)


def _as_bgr(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return img


def _open_camera(index: int, size: tuple[int, int], role: str, backend: int | None = None
                 ) -> cv2.VideoCapture:
    """Open camera `index` (with OpenCV backend `backend`, as the listing reports it) at `size`
    (width, height) px or raise SourceError."""
    with quiet_opencv():
        cap = (cv2.VideoCapture(int(index)) if backend is None
               else cv2.VideoCapture(int(index), int(backend)))
        opened = cap is not None and cap.isOpened()
    if not opened:
        if cap is not None:
            cap.release()
        raise SourceError(f"cannot open {role} camera {index}: no such device, or another "
                          "program is using it; check the cable, close other camera programs, "
                          "or choose other cameras (File > Choose source, or --source cams:L,R)")
    # MJPG lets two cameras share one USB bus at 640x480 and 30 fps (raw YUYV often cannot)
    cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*"MJPG"))
    cap.set(cv2.CAP_PROP_FRAME_WIDTH, int(size[0]))
    cap.set(cv2.CAP_PROP_FRAME_HEIGHT, int(size[1]))
    cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # keep the newest frame, not a backlog
    # only some backends take a read timeout (set() says whether); it cannot be given to the
    # constructor: a backend that does not know a parameter of open() refuses to open at all
    if not cap.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, READ_TIMEOUT_MS):
        log.debug("%s camera %s: the backend has no read timeout", role, index)
    return cap


def _fps(cap: cv2.VideoCapture, default: float = 30.0) -> float:
    try:
        fps = float(cap.get(cv2.CAP_PROP_FPS))
    except Exception:  # noqa: BLE001 - some backends do not report it
        return default
    return fps if 1.0 <= fps <= 240.0 else default


class _Camera:
    """One device of a camera source: its capture while it is there (`cap`, None after it
    vanished), and what it takes to open it again at the same size: its index, backend and
    identity (name and USB ids, `CameraInfo.identity`, "" when not known)."""

    def __init__(self, role: str, index: int, size: tuple[int, int], backend: int | None = None,
                 identity: str = "") -> None:
        self.role, self.index, self.size = role, int(index), size
        self.backend, self.identity = backend, identity
        # its capture while it is there (None after it vanished)
        self.cap: cv2.VideoCapture | None = _open_camera(self.index, size, role, backend)
        self._controls: CameraControls | None = None  # of `cap`, made when first asked for

    @property
    def present(self) -> bool:
        return self.cap is not None

    @property
    def device(self) -> cv2.VideoCapture:
        """The capture of a camera that is present (the sources' read() makes sure first)."""
        if self.cap is None:
            raise SourceError(f"{self.describe()} is not connected")
        return self.cap

    def describe(self) -> str:
        """'right camera 2 (HD Webcam C270 [046d:0825])', for messages."""
        return f"{self.role} camera {self.index}" + (f" ({self.identity})" if self.identity else "")

    @property
    def controls(self) -> CameraControls | None:
        """The device's CameraControls (None while it is missing)."""
        if self.cap is None:
            return None
        if self._controls is None or self._controls.cap is not self.cap:
            self._controls = CameraControls(self.cap, self.backend, self.role)
        return self._controls

    def reopen(self, index: int, backend: int | None) -> None:
        """Open the device again (at `index` now) at the size it had; SourceError if it fails.
        The controls written before it vanished are written again: a webcam plugged in again
        starts in its automatic modes."""
        wanted: dict[str, bool | float] = (dict(self._controls.wanted)
                                           if self._controls is not None else {})
        self.cap = _open_camera(int(index), self.size, self.role, backend)
        self.index, self.backend = int(index), backend
        controls = self.controls if wanted else None  # (None only if nothing was written)
        if controls is not None:
            results = controls.apply(CameraSettings(controls.backend).with_values(**wanted))
            log.info("%s: controls restored after reconnecting: %s", self.describe(),
                     ", ".join(f"{r.name} {r.outcome}" for r in results))

    def release(self) -> None:
        cap, self.cap = self.cap, None
        if cap is not None:
            try:
                cap.release()
            except Exception:  # noqa: BLE001 - releasing a vanished device may fail; nothing to do
                pass


class _CameraSource(FrameSource):
    """What the camera sources share: bad frames skipped and counted, and cameras that come back.

    A frame that cannot be decoded is skipped (`skipped_frames` counts them) and the next one
    read. A camera that fails MAX_FAILED_GRABS times in a row is released and looked for again
    every `reconnect_interval_s` (by its identity in the camera listing, `find_cameras_again`, so
    that it is found under another index too) and opened at the size it had. Meanwhile read()
    raises SourceUnavailable ("Reconnecting to right camera 2…") after waiting at most
    UNAVAILABLE_WAIT_S, and frames go on by themselves once it is back. A camera that comes back
    delivering another image size raises SourceError: the calibration would not fit it.
    """

    _cams: list[_Camera]
    name: str
    reconnect_interval_s: float = 0.0

    def _init_faults(self) -> None:
        self.skipped_frames = 0  # frames that could not be decoded and were left out
        self.reconnects = 0  # times a vanished camera was opened again
        self.reconnect_interval_s = RECONNECT_INTERVAL_S
        self._lost_reason = ""
        self._next_attempt = 0.0  # time.monotonic() of the next look for a vanished camera
        self._shape: tuple[int, ...] | None = None  # of the first frame delivered
        self._wake = threading.Event()  # set by close(): a waiting read returns at once
        self._closed = False

    @property
    def _caps(self) -> list[cv2.VideoCapture]:
        return [c.cap for c in self._cams if c.cap is not None]

    def _reconnecting_text(self) -> str:
        lost = " and ".join(c.describe() for c in self._cams if not c.present)
        return (f"Reconnecting to {lost}… it {self._lost_reason}; trying again every "
                f"{self.reconnect_interval_s:g} s")

    def _lose(self, cams: list[_Camera], why: str) -> NoReturn:
        """Release `cams` (they stopped delivering frames) and raise SourceUnavailable."""
        for c in cams:
            c.release()
        self._lost_reason = why
        self._next_attempt = time.monotonic() + self.reconnect_interval_s
        text = self._reconnecting_text()
        log.warning("%s: %s", self.name, text)
        raise SourceUnavailable(text)

    def _ensure_present(self) -> None:
        """Open vanished cameras again when it is time to look; SourceUnavailable while one
        is still missing (after waiting at most UNAVAILABLE_WAIT_S)."""
        if all(c.present for c in self._cams):
            return
        now = time.monotonic()
        if now < self._next_attempt:
            self._wake.wait(min(self._next_attempt - now, UNAVAILABLE_WAIT_S))
            if self._closed:
                raise SourceError(f"{self.name}: the source was closed")
            if time.monotonic() < self._next_attempt:
                raise SourceUnavailable(self._reconnecting_text())
        self._next_attempt = time.monotonic() + self.reconnect_interval_s
        listed = list_cameras()
        # all the source's cameras take part, so that a twin still at its index is not taken
        indices, _notes = find_cameras_again(tuple(c.index for c in self._cams),
                                             tuple(c.identity for c in self._cams), listed)
        for cam, index in zip(self._cams, indices, strict=True):
            if cam.present:
                continue
            info = find_camera(index, listed)
            if cam.identity and (info is None or info.identity != cam.identity):
                continue  # not listed again yet, or another device is at its index now
            try:
                cam.reopen(index, info.backend if info is not None else cam.backend)
            except SourceError as exc:
                log.info("%s: %s", self.name, exc)
        if not all(c.present for c in self._cams):
            raise SourceUnavailable(self._reconnecting_text())
        self.reconnects += 1
        self._renamed()
        log.warning("%s: the camera is back; frames go on", self.name)

    def _renamed(self) -> None:
        """Update `name` after a camera came back under another index."""

    def _check_shape(self, image: np.ndarray) -> None:
        if self._shape is None:
            self._shape = image.shape
        elif image.shape != self._shape:
            h, w = image.shape[:2]
            h0, w0 = self._shape[:2]
            raise SourceError(f"{self.name} delivers {w}x{h} px images now, not {w0}x{h0} as "
                              "before: the calibration does not fit them; choose the source "
                              "again")

    def close(self) -> None:
        self._closed = True
        self._wake.set()
        for cam in self._cams:
            cam.release()


class TwoCameraSource(_CameraSource):
    """Two cameras, left and right. Both are grabbed first and then decoded, so that the two
    exposures are as close in time as the devices allow. A bad frame is skipped, a camera that
    vanishes is reconnected (see _CameraSource); `identities` (in the order of the indices given,
    as `OpenedSource.cameras`) let it be found under another index."""

    def __init__(self, left_index: int, right_index: int, size: tuple[int, int] = (640, 480),
                 swap: bool = False, backends: tuple[int | None, int | None] = (None, None),
                 identities: tuple[str, ...] = ()):
        if left_index == right_index:
            raise SourceError(f"left and right camera are the same device ({left_index}): "
                              "choose two different cameras")
        idents = tuple(identities) if len(identities) == 2 else ("", "")
        if swap:
            left_index, right_index = right_index, left_index
            backends = (backends[1], backends[0])
            idents = (idents[1], idents[0])
        self.size = (int(size[0]), int(size[1]))
        self._init_faults()
        self._cams: list[_Camera] = []
        self._index = 0
        try:
            for role, i, backend, ident in (("left", left_index, backends[0], idents[0]),
                                            ("right", right_index, backends[1], idents[1])):
                self._cams.append(_Camera(role, i, self.size, backend, ident))
        except BaseException:
            self.close()
            raise
        self._renamed()
        self.nominal_fps = min(_fps(c.device) for c in self._cams)

    def camera_controls(self) -> PairControls | None:
        """The two cameras' controls (sources.camera_controls.PairControls), or None while one
        of them is missing. Only the thread that reads frames may use them."""
        left, right = (c.controls for c in self._cams)
        return PairControls(left, right) if left is not None and right is not None else None

    @property
    def left_index(self) -> int:
        return self._cams[0].index

    @property
    def right_index(self) -> int:
        return self._cams[1].index

    def _renamed(self) -> None:
        self.name = f"Cameras {self.left_index}, {self.right_index}"

    def _grab_both(self) -> tuple[float, float]:
        failures = 0
        left, right = self._cams
        while True:
            ok_l = left.device.grab()
            t_l = time.monotonic()
            ok_r = right.device.grab()
            t_r = time.monotonic()
            if ok_l and ok_r:
                return t_l, t_r
            failures += 1
            if failures >= MAX_FAILED_GRABS:
                self._lose([c for c, ok in ((left, ok_l), (right, ok_r)) if not ok],
                           "stopped delivering frames (unplugged, or the USB bus is "
                           "overloaded?)")

    def read(self) -> StereoFrame:
        if self._closed:
            raise SourceError(f"{self.name}: the source was closed")
        self._ensure_present()
        for _ in range(MAX_FAILED_GRABS):
            t_l, t_r = self._grab_both()
            ok_l, left = self._cams[0].device.retrieve()
            ok_r, right = self._cams[1].device.retrieve()
            bad = [c for c, ok, img in ((self._cams[0], ok_l, left), (self._cams[1], ok_r, right))
                   if not ok or img is None]
            if not bad:
                break
            self.skipped_frames += 1  # one undecodable frame: skip it, read the next pair
            log.debug("%s: %s delivered a frame that could not be decoded", self.name,
                      bad[0].describe())
        else:
            self._lose(bad, "delivers frames that cannot be decoded")
        left, right = _as_bgr(left), _as_bgr(right)
        if left.shape != right.shape:
            raise SourceError(
                f"the cameras deliver different image sizes ({left.shape[1]}x{left.shape[0]} and "
                f"{right.shape[1]}x{right.shape[0]}): choose a resolution both support")
        self._check_shape(left)
        frame = StereoFrame(left, right, t_l, t_r, self._index)
        self._index += 1
        return frame


def split_side_by_side(frame: np.ndarray, swap: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Split a side-by-side frame into (left, right) contiguous halves (a last odd column is
    dropped); with `swap` the left half is the right image."""
    if frame.ndim < 2 or frame.shape[1] < 2:
        raise SourceError(f"a side-by-side frame must be at least 2 pixels wide, got shape {frame.shape}")
    half = frame.shape[1] // 2
    a = np.ascontiguousarray(frame[:, :half])
    b = np.ascontiguousarray(frame[:, half:2 * half])
    return (b, a) if swap else (a, b)


class _SideBySideCapture(FrameSource):
    """What the sources reading side-by-side frames from one cv2.VideoCapture share."""

    _cap: cv2.VideoCapture | None
    _index: int
    _closed: bool
    swap: bool

    def _stereo_frame(self, frame: np.ndarray, t: float) -> StereoFrame:
        """The next StereoFrame from one side-by-side frame captured at `t` seconds."""
        left, right = split_side_by_side(_as_bgr(frame), self.swap)
        out = StereoFrame(left, right, t, t, self._index)
        self._index += 1
        return out

    def close(self) -> None:
        self._closed = True
        if self._cap is not None:
            self._cap.release()


class SideBySideSource(_CameraSource, _SideBySideCapture):
    """One stereo camera that delivers both images side by side in one frame; a bad frame is
    skipped and a camera that vanishes is reconnected (see _CameraSource)."""

    def __init__(self, index: int, size: tuple[int, int] = (1280, 480), swap: bool = False,
                 backend: int | None = None, identity: str = ""):
        self.size = (int(size[0]), int(size[1]))  # the whole frame, both halves
        self.swap = bool(swap)
        self._init_faults()
        self._cams = [_Camera("side-by-side", index, self.size, backend, identity)]
        self._renamed()
        self.nominal_fps = _fps(self._cams[0].device)
        self._index = 0

    @property
    def index(self) -> int:
        return self._cams[0].index

    def _renamed(self) -> None:
        self.name = f"Side-by-side camera {self.index}"

    def read(self) -> StereoFrame:
        if self._closed:
            raise SourceError(f"{self.name}: the source was closed")
        self._ensure_present()
        cam = self._cams[0]
        for _ in range(MAX_FAILED_GRABS):
            if cam.device.grab():
                t = time.monotonic()
                ok, frame = cam.device.retrieve()
                if ok and frame is not None:
                    break
                self.skipped_frames += 1
        else:
            self._lose([cam], "stopped delivering frames (unplugged?)")
        self._check_shape(frame)
        return self._stereo_frame(frame, t)

    close = _CameraSource.close


class VideoFileSource(_SideBySideCapture):
    """A side-by-side stereo video file, played at its own frame rate (paced) or as fast as
    frames are read; with `loop` it starts again at the end, else read() raises EndOfSource.

    Timestamps are the video's own (seconds from its start, plus one duration per loop).
    """

    _cap: cv2.VideoCapture  # (opened in __init__, released by close)

    def __init__(self, path: str | os.PathLike[str], loop: bool = True, swap: bool = False,
                 paced: bool = True) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"video file {self.path} does not exist")
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            self._cap.release()
            raise SourceError(f"cannot open video file {self.path}: not a video OpenCV can read")
        self.loop = bool(loop)
        self.swap = bool(swap)
        self.paced = bool(paced)
        self.nominal_fps = _fps(self._cap)
        self.name = f"Video {self.path.name}"
        self._index = 0
        self._loops = 0
        self._frame_in_loop = 0
        self._frames_per_loop = 0
        self._pacer = FramePacer()
        self._closed = False

    def _next_frame(self) -> np.ndarray:
        ok, frame = self._cap.read()
        if ok and frame is not None:
            return frame
        if self._frame_in_loop == 0:
            raise SourceError(f"video file {self.path} holds no readable frames")
        if not self.loop:
            raise EndOfSource(f"end of video file {self.path.name}")
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
        self._loops += 1
        self._frames_per_loop = max(self._frames_per_loop, self._frame_in_loop)
        self._frame_in_loop = 0
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise SourceError(f"video file {self.path} cannot be rewound")
        return frame

    def read(self) -> StereoFrame:
        if self._closed:
            raise SourceError(f"{self.name}: the source was closed")
        if self.paced:
            self._pacer.wait(self.nominal_fps)
        frame = self._next_frame()
        t = (self._loops * self._frames_per_loop + self._frame_in_loop) / self.nominal_fps
        self._frame_in_loop += 1
        return self._stereo_frame(frame, t)
