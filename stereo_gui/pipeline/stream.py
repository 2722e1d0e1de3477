"""The depth for the robot's programs, without Qt: each processed frame published on Foxglove
topics (the Foxglove SDK: one API for a live WebSocket server and for MCAP files), live to
clients (`DepthStream.serve`), recorded (`DepthStream.record`), or both.

Topics, every message of one frame stamped with the frame's capture time:
- `/stereo/depth`: foxglove.RawImage `16UC1`, millimetres of Z in the rectified left camera,
  0 where there is no value (the depth-camera convention ROS tools read): the final map the
  double-click reads (`core.measure.reading_map`);
- `/stereo/left/image`: the rectified left picture, foxglove.CompressedImage (JPEG);
- `/stereo/left/camera_info`, `/stereo/right/camera_info`: foxglove.CameraCalibration of the
  rectified cameras as ROS's stereo drivers give them (K = P's 3x3, R identity, D zero, the
  right camera's P holding Tx = -fx * baseline in metres);
- `/stereo/points`: foxglove.PointCloud in metres (x right, y down, z ahead), at most
  MAX_CLOUD_POINTS, coloured from the left picture, at most every CLOUD_EVERY_S;
- `/stereo/region`: the watched region's nearest and median distance and its alarm (JSON);
- `/stereo/readings`: each reading a person takes (a click, a ruler) with its +- (JSON);
- `/stereo/health`: the calibration-health figure and the frame rate (JSON);
- `/tf`: foxglove.FrameTransforms placing the cameras' optical frames on the rig's.

The JPEG and the point cloud are made only while something takes them (a subscribed client or
a recording). A client that reads slowly or not at all never slows the pipeline: the server keeps
at most CLIENT_BACKLOG messages per client and drops the oldest (the newest frame wins).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import cv2
import foxglove
import numpy as np
from foxglove import channels as ch
from foxglove import messages as m
from foxglove.websocket import ChannelView, Client, ServerListener, WebSocketServer

from stereo_gui.core.click_map import reading_map
from stereo_gui.core.errors import InputError
from stereo_gui.core.health import CalibrationHealth
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.depth_export import depth_mm, depth_to_png16
from stereo_gui.files.mcap_file import McapRecording
from stereo_gui.files.measurement_record import RULER_METHOD, MeasurementRecord
from stereo_gui.pipeline.cloud import reproject_every
from stereo_gui.pipeline.region import RegionStats

log = logging.getLogger(__name__)

# a JSON message of the topics below (and a CameraCalibration's fields): the SDK's JsonMessage
Message = dict[str, Any]

RIG_FRAME = "stereo_rig"
LEFT_FRAME = "stereo_left_optical"
RIGHT_FRAME = "stereo_right_optical"
TOPICS = {
    "depth": "/stereo/depth",
    "left": "/stereo/left/image",
    "left_info": "/stereo/left/camera_info",
    "right_info": "/stereo/right/camera_info",
    "points": "/stereo/points",
    "region": "/stereo/region",
    "readings": "/stereo/readings",
    "health": "/stereo/health",
    "tf": "/tf",
}
MAX_CLOUD_POINTS = 50_000
# the point cloud goes out at most this often (seconds; with its frame's time): it repeats the
# depth and the camera info, and at every frame it would be half of what a client receives
CLOUD_EVERY_S = 0.1
JPEG_QUALITY = 85
# messages the server holds for one client before it drops the oldest: about two frames' worth,
# so that a stalled client costs two frames of memory, not the SDK's default 1024 messages
CLIENT_BACKLOG = 16
RATE_WINDOW_S = 2.0
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765

_NUMBER = {"type": "number"}
_MAYBE_NUMBER = {"type": ["number", "null"]}
REGION_SCHEMA = {
    "type": "object", "title": "stereo_gui.Region",
    "properties": {
        "x": {"type": "integer"}, "y": {"type": "integer"},
        "width": {"type": "integer"}, "height": {"type": "integer"},
        "nearest_m": _MAYBE_NUMBER, "median_m": _MAYBE_NUMBER,
        "valid_share": _NUMBER, "alarm": {"type": "boolean"}, "alarm_m": _MAYBE_NUMBER,
        "note": {"type": "string"},
    },
}
READING_SCHEMA = {
    "type": "object", "title": "stereo_gui.Reading",
    "properties": {
        "kind": {"type": "string"}, "x": _NUMBER, "y": _NUMBER,
        "valid": {"type": "boolean"}, "z_m": _MAYBE_NUMBER, "range_m": _MAYBE_NUMBER,
        "pm_m": _MAYBE_NUMBER, "reason": {"type": ["string", "null"]},
    },
}
HEALTH_SCHEMA = {
    "type": "object", "title": "stereo_gui.Health",
    "properties": {
        "fps": _MAYBE_NUMBER, "vertical_px": _MAYBE_NUMBER, "matches": {"type": "integer"},
        "drifted": {"type": "boolean"}, "text": {"type": "string"},
    },
}


def _metres(mm: float | None) -> float | None:
    return None if mm is None or not math.isfinite(mm) else round(float(mm) / 1000.0, 6)


def _calibration_of(result: PipelineResult) -> StereoCalibration:
    """The calibration the frame was rectified with (InputError: none)."""
    if result.calibration is None:
        raise InputError("depth in millimetres needs the frame's calibration")
    return result.calibration


def depth_image_mm(result: PipelineResult) -> np.ndarray:
    """(H, W) uint16 Z in whole millimetres of the map the double-click reads; 0 = no value
    (or beyond 65.535 m): the depth PNG export's."""
    return depth_to_png16(depth_mm(reading_map(result), _calibration_of(result)))


def camera_infos(calibration: StereoCalibration) -> tuple[Message, Message]:
    """The rectified cameras' CameraCalibration fields (left, right), as ROS's stereo drivers
    give them: K the rectified projection's 3x3, R identity (the pictures are rectified), D
    zero, P with the right camera's Tx = -fx * baseline in metres (OpenCV's P2 holds mm)."""
    w, h = (int(v) for v in calibration.image_size)
    out = []
    for P, frame in ((calibration.P1, LEFT_FRAME), (calibration.P2, RIGHT_FRAME)):
        P = np.asarray(P, np.float64).copy()
        P[:, 3] /= 1000.0
        out.append({"frame_id": frame, "width": w, "height": h, "distortion_model": "plumb_bob",
                        "D": [0.0] * 5, "K": [float(v) for v in P[:, :3].reshape(-1)],
                        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                        "P": [float(v) for v in P.reshape(-1)]})
    return out[0], out[1]


def cloud_packed(result: PipelineResult, max_points: int = MAX_CLOUD_POINTS
                 ) -> tuple[bytes, int]:
    """The frame's points as foxglove.PointCloud data: x, y, z float32 metres in the left
    optical frame, then red, green, blue, alpha uint8 (16 bytes a point); every n-th pixel so
    that at most `max_points` pixels are looked at. Returns (data, points)."""
    disp = reading_map(result)
    h, w = disp.shape[:2]
    step = max(1, math.ceil(math.sqrt(h * w / max_points)))
    _d, xyz, good = reproject_every(disp, _calibration_of(result), step)
    img = result.rectified_left[::step, ::step]
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    bgr = img.reshape(-1, 3)
    n = int(good.sum())
    packed = np.empty(n, dtype=[("xyz", "<f4", 3), ("rgba", "u1", 4)])
    packed["xyz"] = xyz[good] / 1000.0
    packed["rgba"][:, :3] = bgr[good][:, ::-1]
    packed["rgba"][:, 3] = 255
    return packed.tobytes(), n


class _ClientNoise(logging.Filter):
    """The SDK's lines about clients (one that vanished without closing, sent what the protocol
    does not know, failed its handshake) are about them, not the depth: shown only where the
    log shows INFO (-v), never as "stereo-gui: error:" on a robot's terminal. The client itself
    is told (the server answers a bad message with a status)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return (not record.name.startswith("foxglove.websocket")
                or logging.getLogger().isEnabledFor(logging.INFO))


def _quiet_client_noise() -> None:
    for handler in logging.getLogger().handlers:
        if not any(isinstance(f, _ClientNoise) for f in handler.filters):
            handler.addFilter(_ClientNoise())


@dataclass(frozen=True)
class _Channels:
    """The stream's channels, one a topic (TOPICS)."""

    depth: ch.RawImageChannel
    left: ch.CompressedImageChannel
    left_info: ch.CameraCalibrationChannel
    right_info: ch.CameraCalibrationChannel
    points: ch.PointCloudChannel
    tf: ch.FrameTransformsChannel
    region: foxglove.Channel
    readings: foxglove.Channel
    health: foxglove.Channel


@dataclass(frozen=True)
class StreamStats:
    """What the stream has done: frames published, its rate over the last RATE_WINDOW_S
    (frames per second, None before two frames), clients subscribed now, the server's address
    and the recording's path (None: none)."""

    frames: int
    fps: float | None
    clients: int
    address: str | None
    recording: str | None


class _Clients(ServerListener):
    """The server's listener: which clients hold a subscription (what the window and `serve`
    count as connected). The SDK calls it from its own threads."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._subs: dict[int, set[int]] = {}

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            self._subs.setdefault(client.id, set()).add(channel.id)
        log.info("stream: client %d subscribed to %s", client.id, channel.topic)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            subs = self._subs.get(client.id)
            if subs is not None:
                subs.discard(channel.id)
                if not subs:
                    del self._subs[client.id]

    @property
    def count(self) -> int:
        with self._lock:
            return len(self._subs)


class DepthStream:
    """Publishes processed frames on the topics above, to a live server and/or an MCAP file.

    Any thread may publish (the frame worker's lanes, the `serve` loop, a reading from the UI
    thread); frames are published one at a time. `close` stops the server and closes the
    recording (renamed into place only when written whole)."""

    def __init__(self) -> None:
        self._context = foxglove.Context()
        ctx = self._context
        self._ch = _Channels(
            depth=ch.RawImageChannel(TOPICS["depth"], context=ctx),
            left=ch.CompressedImageChannel(TOPICS["left"], context=ctx),
            left_info=ch.CameraCalibrationChannel(TOPICS["left_info"], context=ctx),
            right_info=ch.CameraCalibrationChannel(TOPICS["right_info"], context=ctx),
            points=ch.PointCloudChannel(TOPICS["points"], context=ctx),
            tf=ch.FrameTransformsChannel(TOPICS["tf"], context=ctx),
            region=foxglove.Channel(TOPICS["region"], schema=REGION_SCHEMA, context=ctx),
            readings=foxglove.Channel(TOPICS["readings"], schema=READING_SCHEMA, context=ctx),
            health=foxglove.Channel(TOPICS["health"], schema=HEALTH_SCHEMA, context=ctx),
        )
        self._lock = threading.Lock()
        self._server: WebSocketServer | None = None
        self._host = ""
        self._clients = _Clients()
        self._recording: McapRecording | None = None  # the MCAP file being written
        self._frames = 0
        self._published: list[float] = []  # monotonic times of the last RATE_WINDOW_S's frames
        self._cloud_at = -math.inf  # monotonic time the last point cloud went out
        self._infos: tuple[StereoCalibration, tuple[Message, Message]] | None = None
        # capture times are monotonic seconds; the topics carry wall-clock nanoseconds
        self._epoch_offset_s = time.time() - time.monotonic()

    # ---- sinks ---------------------------------------------------------------------------
    def serve(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> str:
        """Start the live server (InputError: the port is taken or the host unknown); its
        address "ws://host:port"."""
        if self._server is not None:
            return self._address(self._server)
        _quiet_client_noise()
        try:
            self._server = server = foxglove.start_server(
                name="stereo-gui", host=host, port=port, context=self._context,
                server_listener=self._clients, message_backlog_size=CLIENT_BACKLOG)
        except Exception as exc:  # the SDK raises its own RuntimeError kinds for a bind failure
            raise InputError(f"cannot serve on {host}:{port}: {_bind_words(exc)}") from exc
        self._host = host
        if host not in ("127.0.0.1", "localhost", "::1"):
            log.warning("the depth stream listens on %s: other machines can read it", host)
        return self._address(server)

    def _address(self, server: WebSocketServer) -> str:
        return f"ws://{self._host}:{server.port}"

    @property
    def address(self) -> str | None:
        if self._server is None:
            return None
        return self._address(self._server)

    def record(self, path: str | Path) -> Path:
        """Record every topic to the MCAP file `path` (written under a temporary name, renamed
        when closed whole; InputError when it cannot be made: its folder, its name, the disk)."""
        if self._recording is not None:
            raise InputError(f"already recording to {self._recording.path}")
        recording = McapRecording(Path(path), self._context)
        self._recording = recording
        return recording.path

    def stop_recording(self) -> Path | None:
        """Close the recording (atomic rename); its path, None when none was running."""
        with self._lock:  # (not while a frame is being written to it)
            rec, self._recording = self._recording, None
        return rec.close() if rec is not None else None

    def stats(self) -> StreamStats:
        rec = self._recording
        with self._lock:
            frames, fps = self._frames, self._rate()
        return StreamStats(frames, fps, self._clients.count if self._server else 0,
                           self.address, str(rec.path) if rec is not None else None)

    def _rate(self) -> float | None:
        t = self._published
        if len(t) < 2 or t[-1] <= t[0]:
            return None
        return (len(t) - 1) / (t[-1] - t[0])

    def stop_server(self) -> None:
        """Stop serving (a recording goes on)."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()

    def close(self) -> Path | None:
        """Stop the server and close the recording; the recording's path (None: none)."""
        self.stop_server()
        return self.stop_recording()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- messages ------------------------------------------------------------------------
    def _stamp(self, t_s: float) -> tuple[m.Timestamp, int]:
        """(Timestamp, nanoseconds) of a capture time: monotonic seconds (a live source's)
        are put on the wall clock; a time that is one already (after 2001) is kept."""
        wall = t_s if t_s > 1e9 else t_s + self._epoch_offset_s
        ns = round(wall * 1e9)
        return m.Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000), ns

    def publish(self, result: PipelineResult, t_capture_s: float,
                region: RegionStats | None = None,
                health: CalibrationHealth | None = None) -> None:
        """Publish one processed frame (its capture time, monotonic or wall-clock seconds),
        with the region's statistics (pipeline.region.RegionStats) and the newest
        calibration-health figure where there are any."""
        calib = result.calibration
        if calib is None or not calib.metric:
            raise InputError("the depth stream needs a calibration with a metric scale")
        with self._lock:
            now = time.monotonic()
            self._published = [t for t in self._published if now - t <= RATE_WINDOW_S] + [now]
            self._publish(result, calib, t_capture_s, region, health, self._rate())
            self._frames += 1

    def _publish(self, result: PipelineResult, calib: StereoCalibration, t_capture_s: float,
                 region: RegionStats | None, health: CalibrationHealth | None,
                 fps: float | None) -> None:
        stamp, ns = self._stamp(t_capture_s)
        c = self._ch
        if c.depth.has_sinks():  # (each picture is made only when something takes it)
            depth = depth_image_mm(result)
            h, w = depth.shape
            c.depth.log(m.RawImage(timestamp=stamp, frame_id=LEFT_FRAME, width=w, height=h,
                                      encoding="16UC1", step=2 * w, data=depth.tobytes()),
                           log_time=ns)
        if self._infos is None or self._infos[0] is not calib:
            self._infos = (calib, camera_infos(calib))
        for channel, info in zip((c.left_info, c.right_info), self._infos[1]):
            channel.log(m.CameraCalibration(timestamp=stamp, **info), log_time=ns)
        c.tf.log(self._transforms(stamp, calib), log_time=ns)
        if c.left.has_sinks():
            ok, jpeg = cv2.imencode(".jpg", result.rectified_left,
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if ok:
                c.left.log(m.CompressedImage(timestamp=stamp, frame_id=LEFT_FRAME,
                                                data=jpeg.tobytes(), format="jpeg"),
                              log_time=ns)
        now = time.monotonic()
        if c.points.has_sinks() and now - self._cloud_at >= CLOUD_EVERY_S:
            self._cloud_at = now
            data, _ = cloud_packed(result)
            f32, u8 = m.PackedElementFieldNumericType.Float32, m.PackedElementFieldNumericType.Uint8
            fields = [m.PackedElementField(name=n, offset=o, type=t) for n, o, t in (
                ("x", 0, f32), ("y", 4, f32), ("z", 8, f32), ("red", 12, u8),
                ("green", 13, u8), ("blue", 14, u8), ("alpha", 15, u8))]
            c.points.log(m.PointCloud(
                timestamp=stamp, frame_id=LEFT_FRAME,
                pose=m.Pose(position=m.Vector3(x=0.0, y=0.0, z=0.0),
                            orientation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                point_stride=16, fields=fields, data=data), log_time=ns)
        if region is not None:
            c.region.log(region_message(region), log_time=ns)
        c.health.log(health_message(health, fps), log_time=ns)

    def _transforms(self, stamp: m.Timestamp, calib: StereoCalibration) -> m.FrameTransforms:
        ident = m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        baseline_m = float(calib.rectified_baseline_mm) / 1000.0
        return m.FrameTransforms(transforms=[
            m.FrameTransform(timestamp=stamp, parent_frame_id=RIG_FRAME,
                             child_frame_id=LEFT_FRAME, translation=m.Vector3(x=0.0, y=0.0, z=0.0),
                             rotation=ident),
            m.FrameTransform(timestamp=stamp, parent_frame_id=LEFT_FRAME,
                             child_frame_id=RIGHT_FRAME,
                             translation=m.Vector3(x=baseline_m, y=0.0, z=0.0), rotation=ident),
        ])

    def publish_reading(self, reading: Message, t_s: float | None = None) -> None:
        """Publish one reading a person took (`reading_message`'s fields)."""
        _, ns = self._stamp(time.monotonic() if t_s is None else t_s)
        self._ch.readings.log(reading, log_time=ns)


def region_message(stats: RegionStats) -> Message:
    """A RegionStats as the `/stereo/region` message (metres)."""
    r = stats.region
    return {"x": int(r.x0), "y": int(r.y0), "width": int(r.x1 - r.x0),
            "height": int(r.y1 - r.y0), "nearest_m": _metres(stats.nearest_mm),
            "median_m": _metres(stats.median_mm), "valid_share": float(stats.valid_fraction),
            "alarm": bool(stats.alarm), "alarm_m": _metres(stats.alarm_mm), "note": stats.note}


def record_message(record: MeasurementRecord) -> Message:
    """A logged reading (files.measurement_record.MeasurementRecord: a click, or a ruler's A-B
    distance, whose range is the length) as the `/stereo/readings` message (metres)."""
    ok = bool(record.valid)
    return {"kind": "ruler" if record.method.startswith(RULER_METHOD) else "click",
            "x": float(record.x_px), "y": float(record.y_px), "valid": ok,
            "z_m": _metres(record.Z_mm) if ok else None,
            "range_m": _metres(record.range_mm) if ok else None,
            "pm_m": _metres(record.expected_error_mm) if ok else None,
            "reason": None if ok else (record.reason or None)}


def health_message(health: CalibrationHealth | None, fps: float | None) -> Message:
    """The calibration-health figure (core.health.CalibrationHealth, None: not measured yet)
    and the frame rate as the `/stereo/health` message."""
    out: Message = {"fps": None if fps is None or not math.isfinite(fps) else round(float(fps), 2),
           "vertical_px": None, "matches": 0, "drifted": False,
           "text": "Calibration health: not measured yet"}
    if health is not None:
        out.update(vertical_px=(float(health.vertical_px) if health.measured else None),
                   matches=int(health.matches), drifted=bool(health.drifted), text=health.text())
    return out


def _bind_words(exc: Exception) -> str:
    text = str(exc)
    low = text.lower()
    if "in use" in low or "addrinuse" in low or "98" in low:
        return "the port is in use (another stereo-gui serve? choose another with --port)"
    return text or type(exc).__name__
