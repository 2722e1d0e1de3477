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
import threading
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

    async with websockets.connect(address, subprotocols=SUBPROTOCOLS, max_size=None,
                                  max_queue=16 if reads else 1, close_timeout=0.5) as ws:
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


def _publisher(seconds: float, report_every: float, label: str, during=None):
    """Publish live frames of the demo pair for `seconds` with a stream that serves; call
    `during(address)` in a thread meanwhile; print fps and RSS every `report_every` s."""
    rig = SimRig(seed=0)
    calib = rig.true_calibration()
    left, right = rig.render_scene(Scene.demo())
    proc = live_processor(calib, load_preset("live"))
    from stereo_gui.sources.base import StereoFrame

    frame = StereoFrame(left, right, 0.0, 0.0, 0)
    with DepthStream() as stream:
        address = stream.serve(port=0)
        proc.set_stream(stream)
        worker = None
        if during is not None:
            worker = threading.Thread(target=during, args=(address,), daemon=True)
            worker.start()
        t0 = last = time.monotonic()
        n = n_last = 0
        rss0 = rss_mb()
        print(f"{label}: RSS at start {rss0:.0f} MiB", flush=True)
        while time.monotonic() - t0 < seconds:
            proc(frame)
            n += 1
            now = time.monotonic()
            if now - last >= report_every:
                print(f"  {now - t0:6.0f} s: {(n - n_last) / (now - last):5.1f} fps, RSS "
                      f"{rss_mb():.0f} MiB, clients {stream.stats().clients}", flush=True)
                last, n_last = now, n
        if worker is not None:
            worker.join(600)
    proc.close()


def load(cycles: int, clients: int) -> None:
    def churn(address: str) -> None:
        for c in range(cycles):
            group = [Client(address) for _ in range(clients)]
            time.sleep(0.05)
            for cl in group:
                cl.close()
        print(f"  {cycles} x {clients} clients joined and left", flush=True)

    _publisher(cycles * 0.6 + 10, 5.0, f"{clients} clients joining and leaving {cycles} times",
               churn)


def stall(seconds: float) -> None:
    holder = {}

    def stalled(address: str) -> None:
        holder["client"] = Client(address, reads=False)

    _publisher(seconds, max(5.0, seconds / 12), f"a client that never reads, {seconds:.0f} s",
               stalled)
    if "client" in holder:
        holder["client"].close()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--load", action="store_true", help="10 clients joining and leaving 100 times")
    p.add_argument("--stall", type=float, metavar="S", help="a client that never reads, S seconds")
    p.add_argument("--client", metavar="ADDRESS", help=argparse.SUPPRESS)  # (a client's process)
    p.add_argument("--no-read", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--topic", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.client:
        asyncio.run(_client(args.client, not args.no_read, args.topic))
        return 0
    speed(args.rounds, args.frames)
    if args.load:
        load(100, 10)
    if args.stall:
        stall(args.stall)
    return 0


if __name__ == "__main__":
    sys.exit(main())
