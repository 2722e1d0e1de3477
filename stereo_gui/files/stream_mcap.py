"""The depth stream's MCAP recordings (`stereo-gui serve --mcap`, pipeline.stream) read back as
processed frames (files.ros2_bag.BagFrame): the depth image, the rectified left picture (its
JPEG decoded), both cameras' rectified calibration and the point cloud of each frame, stamped
with the frame's capture time.

The messages are foxglove's protobuf schemas, decoded with the schemas the file itself holds
(the `mcap-protobuf-support` package). Every message of one frame carries the same log time, so
a frame is what the file holds at one log time; a frame without its depth or either camera's
calibration (a recording stopped in the middle of a frame) is left out, with a warning.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from mcap.reader import make_reader

from stereo_gui.core.errors import InputError
from stereo_gui.files.ros2_bag import BagFrame, RectifiedCamera

log = logging.getLogger(__name__)

# a protobuf message as the reader decodes it with the file's own schema: its class is made at
# run time, so its fields are read unchecked (and checked here as they are read)
Decoded = Any

MCAP_MAGIC = b"\x89MCAP0\r\n"
# the topics of pipeline.stream.TOPICS this reader takes (a test checks that they agree)
STREAM_TOPICS = {
    "depth": "/stereo/depth",
    "left": "/stereo/left/image",
    "left_info": "/stereo/left/camera_info",
    "right_info": "/stereo/right/camera_info",
    "points": "/stereo/points",
}
SCHEMAS = {
    "depth": "foxglove.RawImage",
    "left": "foxglove.CompressedImage",
    "left_info": "foxglove.CameraCalibration",
    "right_info": "foxglove.CameraCalibration",
    "points": "foxglove.PointCloud",
}
_REQUIRED = ("depth", "left_info", "right_info")
# foxglove.PackedElementField.NumericType -> numpy
_NUMERIC = {1: "u1", 2: "i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4", 7: "<f4", 8: "<f8"}


def is_mcap(path: str | os.PathLike[str]) -> bool:
    """True when `path` is a file that starts as an MCAP file does, or is named .mcap."""
    path = Path(path)
    if path.suffix.lower() == ".mcap":
        return True
    try:
        with open(path, "rb") as f:
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


class StreamRecording:
    """An MCAP file of the depth stream, checked when opened (InputError: missing, not MCAP,
    cut short, or without the stream's depth and camera topics); `frames()` reads it."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: no such MCAP file")
        try:
            with open(self.path, "rb") as f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise InputError(f"{self.path} is not an MCAP file")
                f.seek(0)
                summary = make_reader(f).get_summary()
        except InputError:
            raise
        except OSError as exc:
            raise InputError(f"cannot read {self.path}: {exc.strerror or exc}") from exc
        except Exception as exc:  # the mcap reader's own errors for a cut or corrupt file
            raise InputError(f"{self.path} does not read as MCAP ({exc}): is it whole?") from exc
        if summary is None:
            raise InputError(f"{self.path} has no MCAP summary: the recording was not closed "
                             "whole")
        found: dict[str, tuple[int, str]] = {}
        for cid, ch in summary.channels.items():
            schema = summary.schemas.get(ch.schema_id)
            found[ch.topic] = (cid, schema.name if schema is not None else "")
        for key in _REQUIRED:
            topic = STREAM_TOPICS[key]
            if topic not in found:
                raise InputError(f"{self.path} is not a depth recording of stereo-gui serve: "
                                 f"it has no {topic} topic")
            if found[topic][1] != SCHEMAS[key]:
                raise InputError(f"{self.path}: {topic} holds {found[topic][1] or 'no schema'}, "
                                 f"not {SCHEMAS[key]}: not a depth recording of stereo-gui serve")
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        self.frame_count = int(counts.get(found[STREAM_TOPICS["depth"]][0], 0))
        self._topics = [t for t in STREAM_TOPICS.values() if t in found]

    def frames(self, limit: int | None = None) -> Iterator[BagFrame]:
        """The recording's frames in time order (at most `limit`)."""
        try:  # guarded: without the package the error says what to install
            from mcap_protobuf.decoder import DecoderFactory
        except ImportError as exc:
            raise InputError("reading a depth recording (MCAP) needs the package "
                             "mcap-protobuf-support: pip install mcap-protobuf-support") from exc
        by_topic = {t: k for k, t in STREAM_TOPICS.items()}
        done = skipped = 0
        group: dict[str, Decoded] = {}
        group_time: int | None = None
        try:
            with open(self.path, "rb") as f:
                reader = make_reader(f, decoder_factories=[DecoderFactory()])
                for _schema, channel, message, decoded in reader.iter_decoded_messages(
                        topics=self._topics, log_time_order=True):
                    if group_time is not None and message.log_time != group_time:
                        frame = self._frame(group, group_time)
                        if frame is None:
                            skipped += 1
                        else:
                            yield frame
                            done += 1
                            if limit is not None and done >= limit:
                                return
                        group = {}
                    group_time = message.log_time
                    group[by_topic[channel.topic]] = decoded
                if group and group_time is not None:
                    frame = self._frame(group, group_time)
                    if frame is None:
                        skipped += 1
                    else:
                        yield frame
        except InputError:
            raise
        except OSError as exc:
            raise InputError(f"cannot read {self.path}: {exc.strerror or exc}") from exc
        except Exception as exc:  # a damaged chunk or message: the reader's and protobuf's errors
            raise InputError(f"{self.path}: a message does not decode ({exc})") from exc
        finally:
            if skipped:
                log.warning("%s: %d frame(s) without their depth or camera calibration were "
                            "left out", self.path.name, skipped)

    def _frame(self, group: dict[str, Decoded], log_time: int) -> BagFrame | None:
        if any(k not in group for k in _REQUIRED):
            return None
        depth_msg = group["depth"]
        stamp = depth_msg.timestamp.ToNanoseconds() if depth_msg.HasField("timestamp") \
            else log_time
        depth = _depth(depth_msg, self.path)
        left = _jpeg(group["left"], self.path) if "left" in group else None
        points, rgb = _points(group["points"], self.path) if "points" in group else (None, None)
        return BagFrame(stamp, depth, _camera(group["left_info"]), _camera(group["right_info"]),
                        left, points, rgb)


def _depth(msg: Decoded, path: Path) -> np.ndarray:
    if msg.encoding != "16UC1":
        raise InputError(f"{path}: a depth image is {msg.encoding!r}, not 16UC1")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = bytes(msg.data)
    if step < 2 * w or len(data) < step * h:
        raise InputError(f"{path}: a depth image holds {len(data)} bytes, not {h} rows of "
                         f"{step}")
    rows = np.frombuffer(data, np.uint8, count=step * h).reshape(h, step)[:, : 2 * w]
    return np.ascontiguousarray(rows).view("<u2").astype(np.uint16)


def _jpeg(msg: Decoded, path: Path) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"{path}: a left picture ({msg.format or 'no format'}) does not decode")
    return img


def _camera(msg: Decoded) -> RectifiedCamera:
    return RectifiedCamera(frame_id=msg.frame_id, width=int(msg.width), height=int(msg.height),
                           K=tuple(float(v) for v in msg.K), P=tuple(float(v) for v in msg.P),
                           R=tuple(float(v) for v in msg.R), D=tuple(float(v) for v in msg.D),
                           distortion_model=msg.distortion_model or "plumb_bob")


def _points(msg: Decoded, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(N, 3) float32 metres and (N, 3) uint8 colours (None: uncoloured) of a PointCloud."""
    stride = int(msg.point_stride)
    fields = {f.name: f for f in msg.fields}
    if stride <= 0 or any(a not in fields for a in "xyz"):
        raise InputError(f"{path}: a point cloud has no x, y, z fields")
    names, formats, offsets = [], [], []
    for f in fields.values():
        kind = _NUMERIC.get(int(f.type))
        if kind is None:
            continue
        names.append(f.name)
        formats.append(kind)
        offsets.append(int(f.offset))
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                      "itemsize": stride})
    data = bytes(msg.data)
    pts = np.frombuffer(data, dtype, count=len(data) // stride)
    xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float32)
    rgb = None
    if all(c in fields for c in ("red", "green", "blue")):
        rgb = np.stack([pts["red"], pts["green"], pts["blue"]], axis=1).astype(np.uint8)
    return xyz, rgb
