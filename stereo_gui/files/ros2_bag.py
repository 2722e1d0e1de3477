"""Processed stereo frames as a ROS 2 bag (the `rosbags` library: pure Python, no ROS install).

A bag is a folder: `metadata.yaml` (what `ros2 bag info` reads) and one MCAP file of CDR
messages (the ROS 2 `mcap` storage, the default since Iron), its chunks zstd-compressed inside
the MCAP (readers decompress them; the metadata says no file or message compression). Bag
format version 8 (Jazzy's), with the message definitions of ROS 2 Jazzy (those of the three
sensor_msgs types used are the same in Humble, Iron, Jazzy and Kilted).

Topics, every message of one frame stamped with the frame's capture time:
- `/stereo/depth`: sensor_msgs/msg/Image `16UC1`, millimetres of Z in the rectified left camera,
  0 where there is no value (the depth-camera convention of ROS's depth_image_proc);
- `/stereo/left/image_rect`: sensor_msgs/msg/Image `bgr8`, the rectified left picture;
- `/stereo/left/camera_info`, `/stereo/right/camera_info`: sensor_msgs/msg/CameraInfo of the
  rectified cameras (K, R identity, D zero `plumb_bob`, P with the right camera's
  Tx = -fx * baseline in metres), as ROS's stereo drivers give them;
- `/stereo/points`: sensor_msgs/msg/PointCloud2, x, y, z float32 metres (x right, y down,
  z ahead, the left optical frame) and `rgb`: 0x00RRGGBB in a float32 field, as
  depth_image_proc packs it (RViz reads its low 24 bits); only points with a value (is_dense).

The bag is written into a temporary folder beside the target (`.NAME.XXXXXXXX.partial`: only
a killed process leaves one behind), read back whole by `rosbags` (every message counted per
topic against what was written) and only then renamed into place; a full disk or any other
failure leaves no temporary folder, and an earlier bag as it was.
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

import numpy as np
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.errors import ReaderError, WriterError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

if TYPE_CHECKING:  # rosbags declares its message protocol for type checkers only
    from rosbags.typesys.store import MsgType

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import os_error_text, syscalls

log = logging.getLogger(__name__)

BAG_VERSION: Final = 8  # rosbag2's metadata version of Jazzy (rosbags also writes 9, Kilted's)
TOPICS = {
    "depth": "/stereo/depth",
    "left": "/stereo/left/image_rect",
    "left_info": "/stereo/left/camera_info",
    "right_info": "/stereo/right/camera_info",
    "points": "/stereo/points",
}
MSG_TYPES = {
    "depth": "sensor_msgs/msg/Image",
    "left": "sensor_msgs/msg/Image",
    "left_info": "sensor_msgs/msg/CameraInfo",
    "right_info": "sensor_msgs/msg/CameraInfo",
    "points": "sensor_msgs/msg/PointCloud2",
}
IDENTITY_3X3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
POINT_STEP = 16  # bytes a point: x, y, z, rgb (4 x float32)


@dataclass(frozen=True)
class RectifiedCamera:
    """A rectified camera as sensor_msgs/msg/CameraInfo holds it: image `width` x `height` px,
    K (3x3) and P (3x4) row-major in pixels, P's Tx = -fx * baseline in metres for the right
    camera; R, D as rectified pictures have them unless given."""

    frame_id: str
    width: int
    height: int
    K: tuple[float, ...]  # 9 values
    P: tuple[float, ...]  # 12 values
    R: tuple[float, ...] = IDENTITY_3X3
    D: tuple[float, ...] = (0.0,) * 5
    distortion_model: str = "plumb_bob"

    def __post_init__(self) -> None:
        if (len(self.K), len(self.P), len(self.R)) != (9, 12, 9):
            raise InputError(f"camera {self.frame_id!r}: K, R and P need 9, 9 and 12 values, "
                             f"not {len(self.K)}, {len(self.R)} and {len(self.P)}")


@dataclass(frozen=True, eq=False)
class BagFrame:
    """One processed frame for the bag; every message of it carries `stamp_ns` (nanoseconds
    since the epoch). Depth, picture and points are in the rectified left camera
    (`left_camera.frame_id`); the picture and the points may be missing (None)."""

    stamp_ns: int
    depth_mm: np.ndarray  # (H, W) uint16 Z in mm, 0 = no value
    left_camera: RectifiedCamera
    right_camera: RectifiedCamera
    left_bgr: np.ndarray | None = None  # (H, W, 3) uint8
    points_m: np.ndarray | None = None  # (N, 3) float32 metres
    points_rgb: np.ndarray | None = None  # (N, 3) uint8 red, green, blue


@dataclass(frozen=True)
class BagSummary:
    """What a written bag holds: frames, messages by topic, its size on disk (bytes)."""

    path: Path
    frames: int
    messages: dict[str, int] = field(default_factory=dict)
    size_bytes: int = 0
    storage: str = "mcap"


def pack_points(points_m: np.ndarray, rgb: np.ndarray | None) -> bytes:
    """PointCloud2 data of (N, 3) points in metres and their (N, 3) uint8 colours: x, y, z
    float32 then rgb, the uint32 0x00RRGGBB stored in a float32 field (little-endian)."""
    xyz = np.asarray(points_m, np.float32).reshape(-1, 3)
    packed = np.zeros(len(xyz), dtype=[("xyz", "<f4", 3), ("rgb", "<u4")])
    packed["xyz"] = xyz
    if rgb is not None:
        c = np.asarray(rgb, np.uint32).reshape(-1, 3)
        packed["rgb"] = (c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2]
    return packed.tobytes()


def unpack_rgb(rgb_field: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 red, green, blue of a PointCloud2 `rgb` float32 field's values."""
    bits = np.ascontiguousarray(rgb_field, "<f4").view("<u4")
    return np.stack([(bits >> 16) & 255, (bits >> 8) & 255, bits & 255], axis=1).astype(np.uint8)


# ---- the target folder ------------------------------------------------------------------------
def check_bag_target(target: str | os.PathLike[str], replace: bool = False) -> bool:
    """Raise InputError unless a bag may be written to `target`: its folder exists, and the
    target does not (or, with `replace`, is a bag folder or an empty one: never another folder
    or a file). True when there is one to replace."""
    target = Path(target)
    if target.name in ("", ".", ".."):
        raise InputError(f"{target} cannot be a bag: name a new folder for it")
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write {target}: folder {parent} does not exist")
    if not target.exists() and not target.is_symlink():
        return False
    if not replace:
        raise InputError(f"{target} exists already: give --force to replace it")
    if target.is_symlink() or not target.is_dir():
        raise InputError(f"{target} exists and is not a folder (a file or a link): a bag "
                         "never replaces one")
    if not (target / "metadata.yaml").is_file() and any(target.iterdir()):
        raise InputError(f"{target} is a folder but not a ROS 2 bag (it has no metadata.yaml): "
                         "it is not replaced, even with --force")
    return True


@contextlib.contextmanager
def atomic_folder(target: str | os.PathLike[str], verify: Callable[[Path], None] | None = None,
                  replace: bool = False) -> Iterator[Path]:
    """Yield a path with the target's name inside a new temporary folder beside `target` (the
    path itself is not created: the caller's writer makes it, and may name its files after
    it); when the block is done, sync every file, check it with `verify` and rename it to
    `target`. An earlier `target` (with `replace`, see `check_bag_target`) is moved aside first
    and removed only once the new one is in place; should that rename fail, it is put back. On
    any error the temporary folder is removed and InputError names the target."""
    target = Path(target)
    existed = check_bag_target(target, replace)
    kept = f"{target} was left as it was" if existed else "nothing was written"
    folder = target.parent if str(target.parent) else Path(".")
    work = _free_name(folder, f".{target.name}.{{}}.partial")
    try:
        work.mkdir()
    except OSError as exc:
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; {kept}") from exc
    tmp = work / target.name
    try:
        yield tmp
        if not tmp.is_dir():
            raise InputError(f"cannot write {target}: nothing reached the disk; {kept}")
        _sync_tree(tmp)
        if verify is not None:
            try:
                verify(tmp)
            except InputError:
                raise
            except Exception as exc:  # the reader's own errors for a cut or corrupt file
                detail = os_error_text(exc) if isinstance(exc, OSError) else str(exc)
                raise InputError(f"cannot write {target}: the bag written does not read back "
                                 f"({detail}); the disk may be full; {kept}") from exc
        _move_into_place(tmp, target, folder, existed)
    except OSError as exc:
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; {kept}") from exc
    finally:
        _remove(work)


def _free_name(folder: Path, pattern: str) -> Path:
    for _ in range(100):
        path = folder / pattern.format(secrets.token_hex(4))
        if not path.exists():
            return path
    raise InputError(f"no free temporary name in {folder}")


def _sync_tree(root: Path) -> None:
    """fsync every file of `root` and the folders themselves: the rename must not reach the
    disk before the data (rosbags closes its files without syncing them)."""
    for path in sorted(root.rglob("*")):
        if path.is_dir():
            _sync_folder(path)
            continue
        fd = syscalls.open(path, os.O_RDONLY | getattr(os, "O_BINARY", 0))
        try:
            syscalls.fsync(fd)
        finally:
            syscalls.close(fd)
    _sync_folder(root)


def _sync_folder(folder: Path) -> None:
    """Make a rename durable (best effort: not every system opens folders)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _move_into_place(tmp: Path, target: Path, folder: Path, existed: bool) -> None:
    if not existed:
        syscalls.replace(tmp, target)  # (nothing there: checked above)
        _sync_folder(folder)
        return
    # POSIX renames no folder over a non-empty one: the earlier bag goes aside first, for
    # the moment between the two renames (it is put back should the second one fail)
    earlier = _free_name(folder, f".{target.name}.{{}}.earlier")
    syscalls.replace(target, earlier)
    try:
        syscalls.replace(tmp, target)
    except BaseException:
        try:
            os.replace(earlier, target)
        except OSError:
            log.error("the earlier %s could not be put back; it is kept as %s", target, earlier)
        raise
    _sync_folder(folder)
    _remove(earlier)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


# ---- messages ---------------------------------------------------------------------------------
def _typestore() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


def _qos() -> list[Qos]:
    """What a camera driver offers: reliable, volatile (history unknown, as rosbag2 records
    it); the durations "infinite" as rosbags' own converter writes them."""
    forever = QosTime(2147483647, 4294967295)
    return [Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, QosDurability.VOLATILE,
                forever, forever, QosLiveliness.AUTOMATIC, forever, False)]


class _Messages:
    """Builds and serialises (CDR) the messages of one frame."""

    def __init__(self, typestore: Typestore) -> None:
        self.ts = typestore
        t = typestore.types
        self._Time = t["builtin_interfaces/msg/Time"]
        self._Header = t["std_msgs/msg/Header"]
        self._Image = t["sensor_msgs/msg/Image"]
        self._CameraInfo = t["sensor_msgs/msg/CameraInfo"]
        self._Roi = t["sensor_msgs/msg/RegionOfInterest"]
        self._PointCloud2 = t["sensor_msgs/msg/PointCloud2"]
        PointField = t["sensor_msgs/msg/PointField"]
        f32 = getattr(PointField, "FLOAT32")  # a constant of a message class made at run time
        self._fields = [PointField(name=n, offset=o, datatype=f32, count=1)
                        for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 12))]

    def _header(self, stamp_ns: int, frame_id: str) -> MsgType:
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        return self._Header(stamp=self._Time(sec=sec, nanosec=nsec), frame_id=frame_id)

    def _image(self, header: MsgType, img: np.ndarray, encoding: str) -> MsgType:
        h, w = img.shape[:2]
        data = np.ascontiguousarray(img)
        return self._Image(header=header, height=h, width=w, encoding=encoding, is_bigendian=0,
                           step=data.strides[0], data=data.reshape(-1).view(np.uint8))

    def _info(self, stamp_ns: int, cam: RectifiedCamera) -> MsgType:
        f64 = np.float64
        return self._CameraInfo(
            header=self._header(stamp_ns, cam.frame_id), height=int(cam.height),
            width=int(cam.width), distortion_model=cam.distortion_model,
            d=np.asarray(cam.D, f64), k=np.asarray(cam.K, f64), r=np.asarray(cam.R, f64),
            p=np.asarray(cam.P, f64), binning_x=0, binning_y=0,
            roi=self._Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))

    def of(self, frame: BagFrame) -> list[tuple[str, bytes]]:
        """(key of TOPICS, CDR bytes) of every message of `frame`."""
        depth = np.asarray(frame.depth_mm)
        if depth.dtype != np.uint16 or depth.ndim != 2:
            raise InputError(f"a depth image must be (H, W) uint16 mm, not {depth.dtype} "
                             f"{depth.shape}")
        depth = depth.astype("<u2", copy=False)
        h, w = depth.shape
        for cam in (frame.left_camera, frame.right_camera):
            if (cam.width, cam.height) != (w, h):
                raise InputError(f"camera {cam.frame_id!r} is {cam.width}x{cam.height} but the "
                                 f"depth image {w}x{h}")
        frame_id = frame.left_camera.frame_id
        header = self._header(frame.stamp_ns, frame_id)
        out = [("depth", self._image(header, depth, "16UC1"))]
        if frame.left_bgr is not None:
            left = np.asarray(frame.left_bgr)
            if left.dtype != np.uint8 or left.shape != (h, w, 3):
                raise InputError(f"the left picture must be ({h}, {w}, 3) uint8 BGR as the depth, "
                                 f"not {left.dtype} {left.shape}")
            out.append(("left", self._image(header, left, "bgr8")))
        out.append(("left_info", self._info(frame.stamp_ns, frame.left_camera)))
        out.append(("right_info", self._info(frame.stamp_ns, frame.right_camera)))
        if frame.points_m is not None:
            if frame.points_rgb is not None and len(frame.points_rgb) != len(frame.points_m):
                raise InputError(f"{len(frame.points_m)} points but {len(frame.points_rgb)} "
                                 "colours")
            data = np.frombuffer(pack_points(frame.points_m, frame.points_rgb), np.uint8)
            n = len(data) // POINT_STEP
            out.append(("points", self._PointCloud2(
                header=header, height=1, width=n, fields=self._fields, is_bigendian=False,
                point_step=POINT_STEP, row_step=POINT_STEP * n, data=data, is_dense=True)))
        return [(key, bytes(self.ts.serialize_cdr(msg, MSG_TYPES[key]))) for key, msg in out]


# ---- writing ----------------------------------------------------------------------------------
def write_ros2_bag(target: str | os.PathLike[str], frames: Iterable[BagFrame],
                   replace: bool = False,
                   progress: Callable[[int], None] | None = None) -> BagSummary:
    """Write `frames` (any iterable: each frame is written as it comes) as a ROS 2 bag folder
    at `target`, atomically (see the module doc); `replace` allows an earlier bag there to be
    replaced. `progress(frames written)` is called after each frame. InputError when nothing
    could be written, the disk is full, or the bag does not read back."""
    target = Path(target)
    typestore = _typestore()
    counts = {key: 0 for key in TOPICS}
    n_frames = 0

    def verify(path: Path) -> None:
        _verify_bag(path, {TOPICS[k]: v for k, v in counts.items()})

    with atomic_folder(target, verify, replace) as tmp:
        messages = _Messages(typestore)
        try:
            writer = Writer(tmp, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
            writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            with writer:
                qos = _qos()
                conns = {key: writer.add_connection(TOPICS[key], MSG_TYPES[key],
                                                    typestore=typestore, offered_qos_profiles=qos)
                         for key in TOPICS}
                for frame in frames:
                    for key, data in messages.of(frame):
                        writer.write(conns[key], int(frame.stamp_ns), data)
                        counts[key] += 1
                    n_frames += 1
                    if progress is not None:
                        progress(n_frames)
                if n_frames == 0:
                    raise InputError(f"no frame to write to {target}: nothing was written")
        except WriterError as exc:
            raise InputError(f"cannot write {target}: {exc}") from exc
    size = sum(p.stat().st_size for p in target.rglob("*") if p.is_file())
    log.info("wrote %d frames to %s (%d bytes)", n_frames, target, size)
    return BagSummary(target, n_frames, {TOPICS[k]: v for k, v in counts.items()}, size)


def _verify_bag(path: Path, expected: dict[str, int]) -> None:
    """Read the bag at `path` back with rosbags: its metadata and every message, counted by
    topic against `expected`; InputError on any difference."""
    got = {topic: 0 for topic in expected}
    with Reader(path) as reader:
        listed = {c.topic: c.msgcount for c in reader.connections}
        for conn, _t, _data in reader.messages():
            got[conn.topic] = got.get(conn.topic, 0) + 1
    if got != expected or listed != expected:
        raise InputError(f"the bag written at {path} holds {got} messages (its metadata "
                         f"{listed}), not {expected}")


def read_bag_counts(path: str | os.PathLike[str]) -> dict[str, int]:
    """How many messages each topic of a ROS 2 bag holds (from its metadata); InputError when
    `path` is not a bag rosbags reads."""
    try:
        with Reader(Path(path)) as reader:
            return {c.topic: c.msgcount for c in reader.connections}
    except (ReaderError, OSError) as exc:
        raise InputError(f"{path} is not a ROS 2 bag: {exc}") from exc

