"""`stereo-gui bench --window SECONDS`: what the window itself shows, not the pipeline alone.

The real window runs (offscreen without a display) on a live source, by default the simulated
rig with its true calibration, the Live tab showing the Depth and Left views; after a warm-up it
counts for SECONDS the frames the Live tab drew, the frames processed and read, the process's
CPU time and each drawn frame's latency from the reader's delivery to the views. The window is
`stereo_gui.qt.window_bench`; this module (no Qt, like every command) checks the options and
writes the result. `cli.py` joins the two: a command module never imports Qt.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any

from stereo_gui.commands.bench import rig_size
from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import Preset
from stereo_gui.files.presets import load_preset
from stereo_gui.sources.open import parse_source_spec

WINDOW_VIEWS = ("depth", "left")  # the Live tab's views the window bench shows
WARMUP_S = 2.0  # after the first frame drawn, before counting starts
DEFAULT_SOURCE = "sim"
SIZED_KINDS = ("auto", "sim", "cams", "sbs")  # sources that are asked for a frame size


@dataclass(frozen=True)
class WindowBench:
    """What `bench --window` runs: `seconds` counted after `warmup_s`, the `source` spec (as
    --source takes it), the `preset` by its name or path (`params` loaded from it), the frame
    `size` asked of a camera or the simulated rig (px; None: a recording's own), the
    calibration file `calib` (None: the simulated rig's true calibration)."""

    seconds: float
    source: str
    preset: str
    params: Preset
    size: tuple[int, int] | None
    calib: str | None
    views: tuple[str, ...] = WINDOW_VIEWS
    warmup_s: float = WARMUP_S


@dataclass(frozen=True)
class WindowBenchResult:
    """What `bench --window` measured over `seconds`: rates in frames per second (`shown_fps`
    drawn by the Live tab, `processing_fps` processed, `camera_fps` read from the source), the
    process's CPU as a percent of its `cores` (100: all busy), the latency from the reader's
    delivery to the views (ms; NaN when no frame was drawn) and in frame intervals of the
    source (`latency_intervals`: the median's), and what ran. `source_cpu_percent`: the part of
    the CPU that the reader thread spent inside the source's reads (the simulated rig's
    rendering, a recording's or a camera's decoding), of the same cores. On 2 CPUs OpenCV runs
    every call in the thread that makes it (`pipeline.concurrency`), so that is all of it; with
    more, OpenCV's own pool may help a read and is not counted."""

    shown_fps: float
    processing_fps: float
    camera_fps: float
    cpu_percent: float
    cores: int
    latency_median_ms: float
    latency_p95_ms: float
    latency_intervals: float
    latency_p95_intervals: float
    frames_shown: int
    frames_processed: int
    frames_read: int
    seconds: float
    warmup_s: float
    source: str
    size: tuple[int, int]
    preset: str
    views: tuple[str, ...]
    window_px: tuple[int, int]
    platform: str
    load_average: float
    errors: tuple[str, ...] = ()
    source_cpu_percent: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """The result as JSON takes it (NaN as null)."""
        out = dataclasses.asdict(self)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
            elif isinstance(value, tuple):
                out[key] = list(value)
        return out

    def line(self) -> str:
        """The one line `bench --window` prints."""
        w, h = self.size
        ww, wh = self.window_px
        return (f"window bench: shown {self.shown_fps:.1f} fps, processing "
                f"{self.processing_fps:.1f} fps, camera {self.camera_fps:.1f} fps, CPU "
                f"{_num(self.cpu_percent, '.0f')} % of {self.cores} cores (the source's "
                f"reads {_num(self.source_cpu_percent, '.0f')} %), latency "
                f"{_num(self.latency_median_ms, '.0f')} / {_num(self.latency_p95_ms, '.0f')} ms "
                f"(median / p95) = {_num(self.latency_intervals, '.2f')} / "
                f"{_num(self.latency_p95_intervals, '.2f')} frame intervals; {self.source} "
                f"{w}x{h}, preset {self.preset}, views {'+'.join(self.views)}, window {ww}x{wh} "
                f"({self.platform}), {self.seconds:.1f} s after {self.warmup_s:g} s of warm-up, "
                f"load average {_num(self.load_average, '.2f')}")


def _num(value: float, spec: str) -> str:
    return format(value, spec) if math.isfinite(value) else "-"


def window_request(args: argparse.Namespace) -> WindowBench:
    """The `bench --window` asked for by `args` (bench's options); InputError, one line, for
    options that do not go with it."""
    others = [name for name, given in (
        ("--scenes", args.scenes), ("--clicks", args.clicks), ("--accuracy", args.accuracy),
        ("images", args.left or args.right), ("--frames", args.frames is not None),
        ("--rounds", args.rounds != 1), ("--seed", args.seed is not None),
        ("--seeds", args.seeds is not None), ("--condition", bool(args.condition)))
        if given]
    if others:
        raise InputError(f"--window times the window on a live source for a number of seconds: "
                         f"it does not go with {', '.join(others)}")
    presets = args.preset or ["live"]
    if len(presets) > 1:
        raise InputError("--window runs one preset, the Live tab's: give --preset once")
    params = load_preset(presets[0])  # an unknown preset fails before the window opens
    source = args.source or DEFAULT_SOURCE
    kind = parse_source_spec(source).kind  # a spec that names no source fails here too
    if kind not in SIZED_KINDS and args.size:
        raise InputError(f"--size is for the simulated rig and cameras; {source} plays at its "
                         "own size")
    if kind != "sim" and not args.calib:
        raise InputError(f"--window on {source} needs --calib FILE (the true calibration is "
                         "the simulated rig's only)")
    size = rig_size(args.size) if kind in SIZED_KINDS else None
    return WindowBench(float(args.window), source, presets[0], params, size, args.calib)


def write_result(result: WindowBenchResult, as_json: bool) -> None:
    """The command's output: the one line, or the same as JSON."""
    print(json.dumps(result.to_dict(), indent=2) if as_json else result.line())
