"""`stereo-gui serve`: the live depth for the robot's programs, headless. Every processed frame
is published on the Foxglove WebSocket protocol (pipeline.stream: the topics and their units)
and, with --mcap, recorded to an MCAP file. Ctrl+C and SIGTERM stop it cleanly (the recording
closed and readable); --frames N stops after N frames."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time

from stereo_gui.commands import options
from stereo_gui.commands.disparity import CALIB_HELP
from stereo_gui.core.errors import InputError
from stereo_gui.pipeline.rig import Rig, open_rig
from stereo_gui.pipeline.stream import DEFAULT_HOST, DEFAULT_PORT, DepthStream
from stereo_gui.sources.open import SPEC_HELP

log = logging.getLogger(__name__)

MAX_FRAMES = 10_000_000
STATUS_EVERY_S = 10.0  # a line on the terminal this often while serving


def _region(text: str) -> tuple[int, int, int, int]:
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"a region is X,Y,W,H in whole pixels, not {text!r}")
    if x < 0 or y < 0 or w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"a region needs X, Y >= 0 and W, H > 0, not {text!r}")
    return x, y, w, h


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--source", default="auto", metavar="S", help=SPEC_HELP)
    parser.add_argument("--calib", metavar="C", help=CALIB_HELP + " (on the simulated rig: its "
                        "true calibration when not given)")
    parser.add_argument("--preset", default="live", metavar="P",
                        help="matcher preset: live (default), quality, seed, a user preset or a "
                        ".json file")
    parser.add_argument("--host", default=DEFAULT_HOST,
                        help=f"address to listen on (default {DEFAULT_HOST}: this machine only)")
    parser.add_argument("--port", type=options.whole(0, 65535), default=DEFAULT_PORT,
                        help=f"port to listen on (default {DEFAULT_PORT}; 0: any free port)")
    parser.add_argument("--no-server", action="store_true",
                        help="do not listen at all (with --mcap: only record)")
    parser.add_argument("--mcap", metavar="FILE.mcap",
                        help="also record every topic to this MCAP file")
    parser.add_argument("--frames", type=options.whole(1, MAX_FRAMES), metavar="N",
                        help="stop after N processed frames (default: until Ctrl+C)")
    parser.add_argument("--region", type=_region, metavar="X,Y,W,H",
                        help="watch this box of the rectified left image (/stereo/region)")
    parser.add_argument("--alarm-m", type=options.number(0.01, 100.0, "m"), metavar="D",
                        help="with --region: an alarm when anything in it is nearer than D metres")


def run(args: argparse.Namespace) -> int:
    if args.no_server and not args.mcap:
        raise InputError("--no-server without --mcap would do nothing: give --mcap FILE.mcap")
    if args.alarm_m is not None and args.region is None:
        raise InputError("--alarm-m needs --region X,Y,W,H (the box the alarm watches)")
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT,
                                                                     signal.SIGTERM)}
    try:
        with open_rig(args.source, args.calib, args.preset) as rig, DepthStream() as stream:
            if args.region is not None:
                rig.watch(args.region, None if args.alarm_m is None else args.alarm_m * 1000.0)
            address = None if args.no_server else stream.serve(args.host, args.port)
            if args.mcap:
                stream.record(args.mcap)
            print(f"serving {rig.description}" + (f" on {address}" if address else "")
                  + (f", recording to {args.mcap}" if args.mcap else "")
                  + ("" if args.frames else " (Ctrl+C stops)"), flush=True)
            frames, t_start = _serve(rig, stream, args.frames, stop)
            recorded = stream.close()
        took = time.monotonic() - t_start
        print(f"{frames} frames in {took:.1f} s ({frames / took if took > 0 else 0:.1f} fps), "
              f"{rig.dropped_frames} skipped for newer ones"
              + (f"; recorded {recorded}" if recorded else ""), flush=True)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 0


def _serve(rig: Rig, stream: DepthStream, limit: int | None, stop: threading.Event
           ) -> tuple[int, float]:
    """Publish frames until `limit` or `stop`; (frames, start time)."""
    t_start = time.monotonic()
    last_status = t_start
    frames = 0
    for frame in rig.frames(limit):
        out = frame.output
        stream.publish(frame.result, frame.t_capture, region=out.region, health=out.health)
        frames += 1
        now = time.monotonic()
        if now - last_status >= STATUS_EVERY_S:
            last_status = now
            st = stream.stats()
            sys.stderr.write(f"stereo-gui: {frames} frames, {st.fps or 0:.1f} fps, "
                             f"{st.clients} client(s)\n")
        if stop.is_set():
            break
    return frames, t_start
