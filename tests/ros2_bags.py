"""Reading a ROS 2 bag back in tests as a ROS 2 user's program would: rosbags' reader and its
CDR deserializer (no ROS install)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Bag:
    """A bag read whole: topic -> message type, topic -> [(bag time ns, message)], and the
    counts its metadata lists."""

    types: dict[str, str] = field(default_factory=dict)
    messages: dict[str, list] = field(default_factory=dict)
    listed: dict[str, int] = field(default_factory=dict)

    def count(self, topic: str) -> int:
        return len(self.messages.get(topic, []))

    def msgs(self, topic: str) -> list:
        return [m for _, m in self.messages.get(topic, [])]


def read_bag(path) -> Bag:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    bag = Bag()
    with Reader(Path(path)) as reader:
        for c in reader.connections:
            bag.types[c.topic] = c.msgtype
            bag.listed[c.topic] = c.msgcount
        for c, t, raw in reader.messages():
            bag.messages.setdefault(c.topic, []).append((t, ts.deserialize_cdr(raw, c.msgtype)))
    return bag


def stamp_ns(msg) -> int:
    s = msg.header.stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def image(msg) -> np.ndarray:
    """A sensor_msgs/Image as an array: (H, W) uint16 for 16UC1, (H, W, 3) uint8 for bgr8."""
    assert not msg.is_bigendian
    if msg.encoding == "16UC1":
        rows = np.asarray(msg.data, np.uint8).reshape(msg.height, msg.step)[:, : 2 * msg.width]
        return np.ascontiguousarray(rows).view("<u2")
    assert msg.encoding == "bgr8", msg.encoding
    rows = np.asarray(msg.data, np.uint8).reshape(msg.height, msg.step)[:, : 3 * msg.width]
    return rows.reshape(msg.height, msg.width, 3)


def cloud(msg) -> tuple[np.ndarray, np.ndarray]:
    """A PointCloud2 of x, y, z, rgb float32 as (N, 3) float32 and (N, 3) uint8 red, green,
    blue (rgb's bits 0x00RRGGBB)."""
    fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    assert fields == [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1)], fields
    pts = np.frombuffer(np.asarray(msg.data, np.uint8).tobytes(),
                        dtype=[("xyz", "<f4", 3), ("rgb", "<u4")])
    bits = pts["rgb"]
    rgb = np.stack([(bits >> 16) & 255, (bits >> 8) & 255, bits & 255], axis=1).astype(np.uint8)
    return pts["xyz"], rgb
