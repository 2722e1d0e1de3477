"""Open a frame source from its command-line spec: auto | sim[:MODE] | cams:L,R | sbs:N | DIR |
VIDEO."""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from stereo_gui.core.errors import InputError, SourceError
from stereo_gui.sources import cameras
from stereo_gui.sources.base import FrameSource, StereoFrame
from stereo_gui.sources.camera_controls import PairControls
from stereo_gui.sources.cameras import SideBySideSource, TwoCameraSource
from stereo_gui.sources.playback import PlaybackSource
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource
from stereo_gui.sources.sim.conditions import condition_named

log = logging.getLogger(__name__)

SPEC_HELP = ("auto, sim (sim:board, sim:scene, or sim:wall:CONDITION:METRES for a painted wall "
             "under a condition of `bench --accuracy`), cams:L,R (two camera indices), sbs:N (one "
             "side-by-side camera), a folder of recorded pairs, or a side-by-side video file")

_CAMS = re.compile(r"^cams:\s*(\d+)\s*,\s*(\d+)\s*$")
_SBS = re.compile(r"^sbs:\s*(\d+)\s*$")
_SIM = re.compile(r"^sim(?::(mixed|board|scene))?$")
_SIM_WALL = re.compile(r"^sim:wall(?::([^:]*))?(?::(.*))?$")


@dataclass(frozen=True)
class OpenedSource:
    """An opened source; `fell_back_to_sim` when automatic selection found no usable cameras
    (the window then shows a banner), `message` says why or what was chosen.

    `spec` is the spec to remember for this source ("" when the one asked for): a folder or
    video as an absolute path, cameras under the indices they were found at. `cameras` are the
    identities (name and USB ids, `CameraInfo.identity`) of the cameras opened, in the order of
    the spec's indices, to find them again under other indices.
    """

    source: FrameSource
    fell_back_to_sim: bool = False
    message: str = ""
    spec: str = ""
    cameras: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()  # what opening tolerated, for the person (not the terminal)


@dataclass(frozen=True)
class SourceSpec:
    """A parsed spec: kind is auto, sim, cams, sbs, folder or video."""

    kind: str
    indices: tuple[int, ...] = ()
    path: Path | None = None
    mode: str = "mixed"  # for sim
    condition: str = "rig"  # for sim:wall: how the wall is rendered (sim/conditions.py)
    wall_mm: float = 1000.0  # ... and how far away it is


def parse_source_spec(spec: str | None) -> SourceSpec:
    """Parse a source spec without opening anything; raise InputError if it is not one."""
    text = (spec or "auto").strip()
    low = text.lower()
    if low in ("", "auto"):
        return SourceSpec("auto")
    m = _SIM.match(low)
    if m:
        return SourceSpec("sim", mode=m.group(1) or "mixed")
    m = _SIM_WALL.match(low)
    if m:
        return _sim_wall_spec(text, m.group(1) or "rig", m.group(2))
    if low.startswith("cams:"):
        m = _CAMS.match(low)
        if not m:
            raise InputError(f"source {text!r}: give two camera indices as cams:L,R, for example cams:0,1")
        left, right = int(m.group(1)), int(m.group(2))
        if left == right:
            raise InputError(f"source {text!r}: left and right must be two different cameras")
        return SourceSpec("cams", indices=(left, right))
    if low.startswith("sbs:"):
        m = _SBS.match(low)
        if not m:
            raise InputError(f"source {text!r}: give one camera index as sbs:N, for example sbs:0")
        return SourceSpec("sbs", indices=(int(m.group(1)),))
    path = Path(text).expanduser()
    if path.is_dir():
        return SourceSpec("folder", path=path.resolve())
    if path.is_file():
        return SourceSpec("video", path=path.resolve())
    raise InputError(f"source {text!r} is neither an existing folder or video file nor one of: "
                     f"{SPEC_HELP}")


class _SwappedSource(FrameSource):
    """Wraps a source so that its left and right images trade places (other attributes, e.g.
    a playback source's pause/step, pass through)."""

    def __init__(self, inner: FrameSource):
        self._inner = inner
        self.name = f"{inner.name} (swapped)"
        self.nominal_fps = inner.nominal_fps

    def read(self) -> StereoFrame:
        f = self._inner.read()
        return StereoFrame(f.right, f.left, f.t_right, f.t_left, f.index, f.truth)

    def close(self) -> None:
        self._inner.close()

    # (the capabilities are forwarded explicitly: FrameSource's defaults would hide them)
    @property
    def skipped_frames(self) -> int:
        return self._inner.skipped_frames

    @skipped_frames.setter
    def skipped_frames(self, count: int) -> None:
        self._inner.skipped_frames = count

    def playback(self) -> PlaybackSource | None:
        return self._inner.playback()

    def simulated_rig(self) -> SimRig | None:
        return self._inner.simulated_rig()

    def camera_controls(self) -> PairControls | None:
        """The inner source's camera controls with left and right exchanged (None if none)."""
        pair = self._inner.camera_controls()
        if pair is None:
            return None
        pair.left.side, pair.right.side = "right", "left"
        return PairControls(pair.right, pair.left)

    def __getattr__(self, name: str) -> object:
        return getattr(self._inner, name)


def _sim_wall_spec(text: str, condition: str, metres: str | None) -> SourceSpec:
    """sim:wall[:CONDITION[:METRES]], checked: a known condition, a distance the rig can show."""
    try:
        condition_named(condition)
    except InputError as exc:
        raise InputError(f"source {text!r}: {exc}") from None
    lo, hi = (v / 1000.0 for v in SimSource.WALL_MM)
    try:
        z = 1.0 if metres is None else float(metres)
    except ValueError:
        z = math.nan
    if not (math.isfinite(z) and lo <= z <= hi):
        raise InputError(f"source {text!r}: give the wall's distance in metres, from {lo:g} to "
                         f"{hi:g}, for example sim:wall:{condition}:1.5")
    return SourceSpec("sim", mode="wall", condition=condition, wall_mm=z * 1000.0)


def _sim(spec: SourceSpec, size: tuple[int, int], swap: bool) -> FrameSource:
    # live, 2x2 anti-aliasing is plenty and halves the rendering time, leaving the CPU to the
    # pipeline (the ground-truth sets of `simulate` and the tests keep 3x3)
    config = replace(RigConfig.for_size(size), supersample=2)
    source = SimSource(SimRig(config), mode=spec.mode, condition=spec.condition,
                       wall_mm=spec.wall_mm)
    return _SwappedSource(source) if swap else source


def _auto(size: tuple[int, int], swap: bool) -> OpenedSource:
    cams = cameras.list_cameras()
    if len(cams) >= 2:
        try:
            src = TwoCameraSource(cams[0].index, cams[1].index, size=size, swap=swap,
                                  backends=(cams[0].backend, cams[1].backend),
                                  identities=(cams[0].identity, cams[1].identity))
            return OpenedSource(src, False, f"using cameras {cams[0].label()} and {cams[1].label()}",
                                cameras=(cams[0].identity, cams[1].identity))
        except SourceError as exc:
            why = f"two cameras were found but could not be opened ({exc})"
    elif len(cams) == 1:
        why = f"only one camera was found ({cams[0].label()})"
    else:
        why = "no cameras were found"
    # said on the terminal too (not only in the window's banner), without -v
    log.warning("%s; showing the simulated rig (choose cameras with File > Choose source, or "
                "--source cams:L,R)", why)
    return OpenedSource(_sim(SourceSpec("sim"), size, swap), True, f"{why}; showing the simulated rig")


def expected_frame_size(spec: str | None, size: tuple[int, int] = (640, 480)
                        ) -> tuple[int, int] | None:
    """The (width, height) px of one image the source `spec` will deliver, before it is opened:
    `size` for cameras and the simulated rig (what they are asked for), the first frame's for a
    recording, folder or video; None when that cannot be read."""
    try:
        s = parse_source_spec(spec)
    except InputError:
        return None
    if s.kind in ("auto", "sim", "cams", "sbs") or s.path is None:
        return int(size[0]), int(size[1])
    try:
        src = PlaybackSource(s.path, paced=False)
    except (SourceError, OSError) as exc:
        log.info("cannot read the frame size of %s: %s", s.path, exc)
        return None
    try:
        frame = src.read()
        return int(frame.left.shape[1]), int(frame.left.shape[0])
    except (SourceError, OSError) as exc:
        log.info("cannot read the frame size of %s: %s", s.path, exc)
        return None
    finally:
        src.close()


def _cameras(indices: tuple[int, ...], remembered: tuple[str, ...]
             ) -> tuple[tuple[int, ...], tuple[int | None, ...], tuple[str, ...], list[str]]:
    """(indices, backends, identities, notes) of the cameras a spec names, found again by their
    remembered identities when they moved to other indices."""
    listed = cameras.list_cameras()
    indices, notes = cameras.find_cameras_again(tuple(indices), tuple(remembered), listed)
    infos = [cameras.find_camera(i, listed) for i in indices]
    backends = tuple(c.backend if c is not None else None for c in infos)
    idents = tuple(c.identity if c is not None else "" for c in infos)
    for n in notes:
        log.info("%s", n)
    return indices, backends, idents if all(idents) else (), notes


def open_source(spec: str | None, size: tuple[int, int] = (640, 480), swap: bool = False,
                remembered_cameras: tuple[str, ...] = ()) -> OpenedSource:
    """Open the source a spec names (see SPEC_HELP); `size` is one image's (width, height) px.

    `remembered_cameras` are the identities saved with a cams:/sbs: spec (OpenedSource.cameras):
    a camera found under another index now is opened there. Cameras open with the backend the
    listing reports. Bad specs raise InputError; devices or files that cannot be opened raise
    SourceError. Only "auto" falls back to the simulated rig (and says so in the result).
    """
    size = (int(size[0]), int(size[1]))
    if size[0] <= 0 or size[1] <= 0:
        raise InputError(f"image size must be positive, not {size[0]}x{size[1]}")
    s = parse_source_spec(spec)
    if s.kind == "auto":
        return _auto(size, swap)
    if s.kind == "sim":
        return OpenedSource(_sim(s, size, swap), False, "simulated rig")
    if s.kind == "cams":
        (left, right), (b_left, b_right), idents, notes = _cameras(s.indices,
                                                                    remembered_cameras)
        pair = TwoCameraSource(left, right, size=size, swap=swap, backends=(b_left, b_right),
                               identities=idents)
        return OpenedSource(pair, False, "; ".join([pair.name, *notes]),
                            spec=f"cams:{left},{right}", cameras=idents)
    if s.kind == "sbs":
        (index,), (backend,), idents, notes = _cameras(s.indices, remembered_cameras)
        one = SideBySideSource(index, size=(2 * size[0], size[1]), swap=swap, backend=backend,
                               identity=idents[0] if idents else "")
        return OpenedSource(one, False, "; ".join([one.name, *notes]), spec=f"sbs:{index}",
                            cameras=idents)
    # a folder of pairs, a recording, or a side-by-side video: all play back like a recording
    # (pause, step, seek and loop); remembered by absolute path, so that it opens from anywhere
    if s.path is None:  # (parse_source_spec gives the other kinds a path)
        raise InputError(f"source {spec!r}: no folder or video file")
    played = PlaybackSource(s.path)
    src: FrameSource = _SwappedSource(played) if swap else played
    return OpenedSource(src, False, src.name, spec=str(s.path), warnings=played.warnings)
