"""`stereo-gui ros2-bag INPUT -o OUT_DIR`: the depth as a ROS 2 bag (files.ros2_bag: its topics
and units), for ROS 2 users' tools (`ros2 bag play`, rviz2, Foxglove).

INPUT is a depth recording of `stereo-gui serve --mcap` (its processed frames are copied, the
left picture's JPEG decoded), or anything `serve --source` takes that ends or is given --frames
(a recording folder, a folder of pairs, a side-by-side video, the simulated rig `sim`, cameras):
the window's pipeline then runs over it with --calib and --preset, as `serve` does. A recording
or video is converted frame by frame, none skipped, at whatever pace the pipeline has; cameras
and the simulated rig run at their own pace, and a frame the pipeline is too slow for is
skipped (said at the end).

Header stamps are the frames' capture times on the wall clock: the recording's own times for an
MCAP file; for a recording folder its frames' times counted from when it was made; for a video
or folder of pairs from now; for cameras and the simulated rig when they were captured.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_gui.commands import options
from stereo_gui.commands.disparity import CALIB_HELP
from stereo_gui.core.errors import InputError
from stereo_gui.files.recording import is_recording, open_recording
from stereo_gui.files.ros2_bag import (
    BagFrame,
    BagSummary,
    RectifiedCamera,
    check_bag_target,
    write_ros2_bag,
)
from stereo_gui.files.stream_mcap import StreamRecording, is_mcap
from stereo_gui.pipeline.rig import Frame, open_rig
from stereo_gui.pipeline.stream import camera_infos, cloud_packed
from stereo_gui.sources.open import SPEC_HELP, SourceSpec, parse_source_spec

log = logging.getLogger(__name__)

MAX_FRAMES = 10_000_000
STATUS_EVERY_S = 10.0  # a line on the terminal this often during a long conversion
ENDLESS_KINDS = ("auto", "sim", "cams", "sbs")  # sources that never end by themselves


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT",
                        help="an MCAP file of `stereo-gui serve --mcap`, a recording folder, a "
                        "folder of pairs, a side-by-side video, sim (sim:wall:CONDITION:METRES, "
                        "...) or cameras (cams:L,R, sbs:N; these and sim need --frames)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT_DIR",
                        help="the bag folder to write (it must not exist, unless --force)")
    parser.add_argument("--calib", metavar="C", help=CALIB_HELP + " (not for an MCAP file; on "
                        "the simulated rig: its true calibration when not given)")
    parser.add_argument("--preset", default=None, metavar="P",
                        help="matcher preset: live (default), quality, seed, a user preset or a "
                        ".json file (not for an MCAP file)")
    parser.add_argument("--frames", type=options.whole(1, MAX_FRAMES), metavar="N",
                        help="write at most N frames (default: every frame of the input)")
    parser.add_argument("--force", action="store_true",
                        help="replace OUT_DIR when it is a bag already (atomically)")


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    check_bag_target(out, args.force)  # before any work: a refusal costs nothing
    status = _Status()
    t_start = time.monotonic()
    given = Path(args.input).expanduser()
    # (SIGTERM is an interrupt here, as for every command: the temporary bag is removed)
    if (given.is_file() and is_mcap(given)) or given.suffix.lower() == ".mcap":
        if args.calib is not None or args.preset is not None:
            raise InputError("--calib and --preset apply to a pipeline run: the frames of "
                             f"an MCAP recording ({given.name}) were processed already")
        summary, what, skipped = _from_mcap(given, out, args, status)
    else:
        summary, what, skipped = _from_pipeline(args.input, out, args, status)
    took = time.monotonic() - t_start
    mb = summary.size_bytes / 1e6
    print(f"wrote {summary.frames} frames from {what} to {out} ({summary.storage.upper()} "
          f"storage, {mb:.1f} MB) in {took:.1f} s ({summary.frames / took if took > 0 else 0:.1f}"
          " frames/s)" + (f"; {skipped} skipped for newer ones" if skipped else ""), flush=True)
    return 0


class _Status:
    """A line on stderr every STATUS_EVERY_S while frames are written."""

    def __init__(self, total: int | None = None) -> None:
        self.total = total
        self._last = time.monotonic()

    def __call__(self, frames: int) -> None:
        now = time.monotonic()
        if now - self._last >= STATUS_EVERY_S:
            self._last = now
            of = f" of {self.total}" if self.total else ""
            sys.stderr.write(f"stereo-gui: {frames}{of} frames written\n")


def _from_mcap(path: Path, out: Path, args: argparse.Namespace, status: _Status
               ) -> tuple[BagSummary, str, int]:
    rec = StreamRecording(path)
    status.total = min(rec.frame_count, args.frames or rec.frame_count)
    summary = write_ros2_bag(out, rec.frames(args.frames), replace=args.force, progress=status)
    return summary, f"the recording {path.name}", 0


def _from_pipeline(spec: str, out: Path, args: argparse.Namespace, status: _Status
                   ) -> tuple[BagSummary, str, int]:
    s = _source_spec(spec, parse_source_spec)
    if s.kind in ENDLESS_KINDS and args.frames is None:
        raise InputError(f"{spec} never ends by itself: give --frames N")
    if s.kind in ("folder", "video") and args.calib is None:
        raise InputError(f"{spec} holds no calibration: give the rig's with --calib C (a file "
                         "of ours, OpenCV's, ROS's or Middlebury's)")
    with open_rig(spec, args.calib, args.preset or "live") as rig:
        playback = rig.source.playback()
        if playback is not None:
            status.total = min(playback.frame_count, args.frames or playback.frame_count)
        stamps = _Stamps(_anchor(s))
        # a recording: every frame once, in order; cameras and the simulated rig: the newest
        frames = (_bag_frame(f, stamps) for f in rig.frames(args.frames,
                                                            every=playback is not None))
        summary = write_ros2_bag(out, frames, replace=args.force, progress=status)
        skipped = rig.dropped_frames
    what = rig.description.split(";")[0]
    return summary, what[:1].lower() + what[1:], skipped


def _source_spec(spec: str, parse: Callable[[str], SourceSpec]) -> SourceSpec:
    try:
        return parse(spec)
    except InputError:
        if not Path(spec).expanduser().exists():
            raise InputError(f"{spec}: no such file or folder (INPUT is an MCAP file of "
                             f"`stereo-gui serve --mcap`, or a source: {SPEC_HELP})") from None
        raise


class _Stamps:
    """Capture times (seconds of the source's clock) as nanoseconds since the epoch. A time
    that is one on the wall clock already (after 2001) is kept; with an anchor (the wall-clock
    time of the first frame) the others keep their spacing from the first; else the times are
    the monotonic clock's (cameras, the simulated rig), put on the wall clock as the depth
    stream does. (Offsets are added in whole nanoseconds: a float of seconds since 1970 holds
    only a quarter of a microsecond.)"""

    def __init__(self, anchor_s: float | None) -> None:
        self._anchor_ns = None if anchor_s is None else round(anchor_s * 1e9)
        self._first: float | None = None
        self._offset_ns = time.time_ns() - time.monotonic_ns()

    def ns(self, t_s: float) -> int:
        if t_s > 1e9:
            return round(t_s * 1e9)
        if self._anchor_ns is not None:
            if self._first is None:
                self._first = t_s
            return self._anchor_ns + round((t_s - self._first) * 1e9)
        return round(t_s * 1e9) + self._offset_ns


def _anchor(spec: SourceSpec) -> float | None:
    """The wall-clock time of a played-back source's first frame: a recording's creation time,
    else (a video, a folder of pairs) now; None for live sources."""
    if spec.kind not in ("folder", "video"):
        return None
    if spec.kind == "folder" and spec.path is not None and is_recording(spec.path):
        try:
            created = _dt.datetime.fromisoformat(open_recording(spec.path).created)
            if created.tzinfo is None:
                created = created.replace(tzinfo=_dt.UTC)
            return created.timestamp()
        except (InputError, ValueError) as exc:
            log.info("the recording's creation time is not known (%s): stamps from now", exc)
    return time.time()


def _bag_frame(frame: Frame, stamps: _Stamps) -> BagFrame:
    """A processed Frame of the rig as the bag's BagFrame (its stamp from its capture time)."""
    result = frame.result
    left = result.rectified_left
    if left.ndim == 2:
        left = cv2.cvtColor(left, cv2.COLOR_GRAY2BGR)
    data, _n = cloud_packed(result)
    pts = np.frombuffer(data, dtype=[("xyz", "<f4", 3), ("rgba", "u1", 4)])
    left_info, right_info = camera_infos(frame.calibration)
    return BagFrame(stamps.ns(frame.t_capture), frame.depth_mm, _camera(left_info),
                    _camera(right_info), left, pts["xyz"], pts["rgba"][:, :3])


def _camera(info: dict[str, Any]) -> RectifiedCamera:
    """pipeline.stream.camera_infos' fields as a RectifiedCamera."""
    return RectifiedCamera(frame_id=info["frame_id"], width=info["width"],
                           height=info["height"], K=tuple(info["K"]), P=tuple(info["P"]),
                           R=tuple(info["R"]), D=tuple(info["D"]),
                           distortion_model=info["distortion_model"])
