#!/usr/bin/env python3
"""What streaming the depth costs and whether clients can hurt it (a script, not a test).

    python scripts/bench_stream.py                 # live fps: no stream / serving / clients / + MCAP
    python scripts/bench_stream.py --load          # + 10 clients joining and leaving 100 times
    python scripts/bench_stream.py --stall 600     # + a client that never reads, for 600 s

The live preset on the simulated rig's 640x480 demo pair, as the Live tab runs it (its lanes,
its default views, `stereo-gui bench`'s timing), with the stream attached to the processor as
the window attaches it. Each case is timed in interleaved rounds; the median is reported with
its ratio to the case without a stream. RSS is the process's resident memory.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from stereo_gui.commands.bench import bench_preset, live_processor, rss_mb
from stereo_gui.files.presets import load_preset
from stereo_gui.pipeline.stream import DepthStream
from stereo_gui.sources.sim import Scene, SimRig

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


class Client:
    """A Foxglove client in a process of its own (as a robot's program is): subscribes to every
    topic, then reads everything (`reads=True`) or nothing."""

    def __init__(self, address: str, reads: bool = True, topic: str | None = None) -> None:
        import subprocess

        self._proc = subprocess.Popen(
            [sys.executable, __file__, "--client", address] + ([] if reads else ["--no-read"])
            + ([] if topic is None else ["--topic", topic]), stdout=subprocess.PIPE, text=True)
        line = self._proc.stdout.readline()
        if not line.startswith("subscribed"):
            raise RuntimeError(f"the client did not subscribe: {line!r}")

    def close(self) -> None:
        self._proc.terminate()
        self._proc.wait(10)


async def _client(address: str, reads: bool, topic: str | None = None) -> None:
    import websockets

    # (a client that never reads must not time out its own keep-alive pings and leave: it stays,
    # its socket's buffers full, as a hung program's would)
    async with websockets.connect(address, subprotocols=SUBPROTOCOLS, max_size=None,
                                  max_queue=16 if reads else 1, close_timeout=0.5,
                                  ping_interval=None if not reads else 20) as ws:
        channels: dict = {}
        while True:  # every channel advertised within a moment of the first
            try:
                msg = await asyncio.wait_for(ws.recv(), 0.5 if channels else 30)
            except TimeoutError:
                break
            if isinstance(msg, str):
                m = json.loads(msg)
                if m["op"] == "advertise":
                    channels.update({c["id"]: c for c in m["channels"]})
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": cid} for i, cid in enumerate(channels)
            if topic is None or channels[cid]["topic"] == topic]}))
        print("subscribed", flush=True)
        while True:
            if reads:
                await ws.recv()
            else:
                await asyncio.sleep(1.0)


def speed(rounds: int, frames: int) -> None:
    rig = SimRig(seed=0)
    calib = rig.true_calibration()
    left, right = rig.render_scene(Scene.demo())
    params = load_preset("live")
    proc = live_processor(calib, params)
    cases = ("no stream", "serving, no client", "a client of the depth", "a client of all",
             "all + MCAP")
    fps: dict[str, list[float]] = {c: [] for c in cases}
    tmp = Path(tempfile.mkdtemp())
    try:
        for r in range(rounds):
            for case in cases:
                stream = client = None
                if case != "no stream":
                    stream = DepthStream()
                    address = stream.serve(port=0)
                    if case == "a client of the depth":
                        client = Client(address, topic="/stereo/depth")
                    elif case != "serving, no client":
                        client = Client(address)
                    if case == "all + MCAP":
                        stream.record(tmp / f"run{r}.mcap")
                proc.set_stream(stream)
                res = bench_preset(calib, params, left, right, frames, processor=proc)
                proc.set_stream(None)
                fps[case].append(res["fps"])
                if client is not None:
                    client.close()
                if stream is not None:
                    stream.close()
                print(f"  round {r + 1} {case:>24}: {res['fps']:5.1f} fps, RSS "
                      f"{rss_mb():.0f} MiB", flush=True)
    finally:
        proc.close()
    base = statistics.median(fps["no stream"])
    print("\nmedian over the rounds (640x480, live preset):")
    for case in cases:
        m = statistics.median(fps[case])
        print(f"  {case:>24}: {m:5.1f} fps  ({m / base:.2f}x)")


def _publish_while(label: str, helper_argv: list[str] | None, seconds: float | None,
                   report_every: float = 10.0, baseline_s: float = 20.0) -> None:
    """Publish live frames of the demo pair (one lane, a served stream): first `baseline_s`
    alone, then while a helper process runs (`helper_argv` + the address; until it ends, or
    for `seconds`); fps and RSS every `report_every` s, and the two rates side by side."""
    import subprocess

    from stereo_gui.sources.base import StereoFrame

    rig = SimRig(seed=0)
    calib = rig.true_calibration()
    left, right = rig.render_scene(Scene.demo())
    proc = live_processor(calib, load_preset("live"))
    frame = StereoFrame(left, right, 0.0, 0.0, 0)
    with DepthStream() as stream:
        address = stream.serve(port=0)
        proc.set_stream(stream)

        def run_for(until, tag: str) -> float:
            t0 = last = time.monotonic()
            n = n_last = 0
            while not until(time.monotonic() - t0):
                proc(frame)
                n += 1
                now = time.monotonic()
                if now - last >= report_every:
                    print(f"  {tag} {now - t0:6.0f} s: {(n - n_last) / (now - last):5.1f} fps, "
                          f"RSS {rss_mb():.0f} MiB, clients {stream.stats().clients}",
                          flush=True)
                    last, n_last = now, n
            return n / (time.monotonic() - t0)

        print(f"{label}:", flush=True)
        alone = run_for(lambda t: t >= baseline_s, "alone")
        rss0 = rss_mb()
        helper = subprocess.Popen([sys.executable, __file__, *helper_argv, address])
        try:
            during = run_for(lambda t: helper.poll() is not None
                             or (seconds is not None and t >= seconds), "with it")
        finally:
            if helper.poll() is None:
                helper.terminate()
            helper.wait(30)
        after = run_for(lambda t: t >= baseline_s, "after")
    proc.close()
    print(f"  alone {alone:.1f} fps; meanwhile {during:.1f} fps ({during / alone:.2f}x); after "
          f"{after:.1f} fps; RSS {rss0:.0f} -> {rss_mb():.0f} MiB", flush=True)


async def _churn(address: str, cycles: int, clients: int) -> None:
    """`clients` clients connect at once, each subscribes to the depth and takes one message,
    and all leave; `cycles` times."""
    import websockets

    async def one() -> None:
        async with websockets.connect(address, subprotocols=SUBPROTOCOLS, max_size=None,
                                      close_timeout=0.5) as ws:
            channel = None
            while channel is None:
                m = json.loads(await ws.recv())
                if m["op"] == "advertise":
                    channel = next((c["id"] for c in m["channels"]
                                    if c["topic"] == "/stereo/depth"), None)
            await ws.send(json.dumps({"op": "subscribe",
                                      "subscriptions": [{"id": 1, "channelId": channel}]}))
            while not isinstance(await ws.recv(), bytes):
                pass

    for _ in range(cycles):
        await asyncio.gather(*(one() for _ in range(clients)))
    print(f"  {cycles} x {clients} clients joined, read a depth and left", flush=True)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--load", action="store_true", help="10 clients joining and leaving 100 times")
    p.add_argument("--stall", type=float, metavar="S", help="a client that never reads, S seconds")
    p.add_argument("--client", metavar="ADDRESS", help=argparse.SUPPRESS)  # (a client's process)
    p.add_argument("--no-read", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--topic", help=argparse.SUPPRESS)
    p.add_argument("--churn", metavar="ADDRESS", help=argparse.SUPPRESS)  # (the churn's process)
    args = p.parse_args()
    if args.client:
        asyncio.run(_client(args.client, not args.no_read, args.topic))
        return 0
    if args.churn:
        asyncio.run(_churn(args.churn, 100, 10))
        return 0
    speed(args.rounds, args.frames)
    if args.load:
        _publish_while("10 clients joining and leaving 100 times", ["--churn"], None)
    if args.stall:
        _publish_while(f"a client subscribed to everything that never reads, {args.stall:.0f} s",
                       ["--no-read", "--client"], args.stall, report_every=max(10.0,
                                                                              args.stall / 10))
    return 0


if __name__ == "__main__":
    sys.exit(main())
