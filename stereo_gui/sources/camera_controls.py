"""A camera's controls (focus, exposure, gain, white balance, brightness) read from and written
to the device through OpenCV's capture properties, with each backend's own conventions.

OpenCV passes most values through untouched, so their meaning is the backend's (checked against
OpenCV's videoio sources, cap_v4l.cpp, cap_dshow.cpp, cap_msmf.cpp, cap_avfoundation_mac.mm):

- V4L2 (Linux): CAP_PROP_AUTO_EXPOSURE is V4L2's exposure_auto: 1 manual, 3 aperture priority
  (automatic); CAP_PROP_EXPOSURE is exposure_absolute in steps of 100 us; autofocus and
  automatic white balance are 0/1; the white balance is a temperature in kelvin. A control the
  device lacks reads -1 and refuses writes.
- DirectShow (Windows): the auto-exposure switch is written 0.25 (manual) / 0.75 (automatic);
  OpenCV's own DirectShow backend does not handle that property (it reads -1 and refuses it),
  so on most builds the switch shows as unavailable and a manual exposure is simply written.
  Autofocus reads back DirectShow's flags (1 automatic, 2 manual). Exposure is log2 of seconds
  (-6 = 1/64 s). The white balance temperature goes through CAP_PROP_WHITE_BALANCE_BLUE_U;
  there is no automatic white balance switch.
- Media Foundation (Windows): auto exposure and autofocus are 0 (manual) / 1 (automatic): any
  value but 0 means automatic, so DirectShow's 0.25 would switch it ON here. Exposure is log2
  of seconds; the white balance temperature is CAP_PROP_TEMPERATURE; no automatic white balance
  switch.
- AVFoundation (macOS): OpenCV's camera backend handles only the image size and frame rate;
  every control reads 0 and refuses writes, and is shown as unavailable.

Every write is read back: a control that refuses a write, or accepts it and keeps its old
value, is reported (WriteResult) and from then on shown as unavailable, never as a slider that
does nothing. Only the frame worker's reader thread calls these (it owns the devices).
"""

from __future__ import annotations

import logging
import math
import sys
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Protocol

import cv2

from stereo_gui.core.camera_settings import (
    CONTROL_NAMES,
    FREED_BY,
    LABELS,
    SWITCHES,
    CameraSettings,
    PairSettings,
)

log = logging.getLogger(__name__)


class Device(Protocol):
    """What controls are read from and written to: a cv2.VideoCapture, or the simulated rig's
    camera (sim/controls.py)."""

    def get(self, prop: int, /) -> float: ...

    def set(self, prop: int, value: float, /) -> bool: ...

MISSING = -1.0  # what V4L2, DirectShow and Media Foundation read for a control a device lacks


@dataclass(frozen=True)
class ControlSpec:
    """How one control is reached on one backend: the capture property, for a switch the device
    values written for off (held by hand) and on (automatic) and those read back as on, for a
    value the range offered on the slider (typical of webcams: OpenCV does not report a
    device's range; the device clamps and the value read back is shown) and its unit."""

    name: str
    prop: int
    off: float = 0.0
    on: float = 1.0
    read_on: tuple[float, ...] = (1.0,)
    lo: float = 0.0
    hi: float = 255.0
    step: float = 1.0
    unit: str = ""

    @property
    def switch(self) -> bool:
        return self.name in SWITCHES


@dataclass(frozen=True)
class Convention:
    """A backend's controls (those it does not offer are absent) and what it reads for a
    control a device lacks (None: every control is unavailable)."""

    backend: str
    specs: dict[str, ControlSpec]
    note: str = ""


def _specs(*specs: ControlSpec) -> dict[str, ControlSpec]:
    return {s.name: s for s in specs}


_V4L2 = Convention("V4L2", _specs(
    ControlSpec("focus_auto", cv2.CAP_PROP_AUTOFOCUS),
    ControlSpec("focus", cv2.CAP_PROP_FOCUS, lo=0, hi=255, step=1),
    # V4L2_EXPOSURE_MANUAL = 1; automatic is 3 (aperture priority), which is what UVC webcams
    # offer; 0 (full auto) is read as automatic too
    ControlSpec("exposure_auto", cv2.CAP_PROP_AUTO_EXPOSURE, off=1.0, on=3.0, read_on=(0.0, 3.0)),
    ControlSpec("exposure", cv2.CAP_PROP_EXPOSURE, lo=1, hi=2047, step=1, unit="x100 us"),
    ControlSpec("gain", cv2.CAP_PROP_GAIN, lo=0, hi=255, step=1),
    ControlSpec("wb_auto", cv2.CAP_PROP_AUTO_WB),
    ControlSpec("wb_temperature", cv2.CAP_PROP_WB_TEMPERATURE, lo=2000, hi=7500, step=10,
                unit="K"),
    ControlSpec("brightness", cv2.CAP_PROP_BRIGHTNESS, lo=0, hi=255, step=1),
))

_DSHOW = Convention("DirectShow", _specs(
    # written 1 / 0; DirectShow reads back its flags: 1 automatic, 2 manual (3: both set)
    ControlSpec("focus_auto", cv2.CAP_PROP_AUTOFOCUS, off=0.0, on=1.0, read_on=(1.0, 3.0)),
    ControlSpec("focus", cv2.CAP_PROP_FOCUS, lo=0, hi=255, step=1),
    ControlSpec("exposure_auto", cv2.CAP_PROP_AUTO_EXPOSURE, off=0.25, on=0.75, read_on=(0.75,)),
    ControlSpec("exposure", cv2.CAP_PROP_EXPOSURE, lo=-13, hi=-1, step=1, unit="log2 s"),
    ControlSpec("gain", cv2.CAP_PROP_GAIN, lo=0, hi=255, step=1),
    ControlSpec("wb_temperature", cv2.CAP_PROP_WHITE_BALANCE_BLUE_U, lo=2800, hi=6500, step=10,
                unit="K"),
    ControlSpec("brightness", cv2.CAP_PROP_BRIGHTNESS, lo=-64, hi=64, step=1),
), note="DirectShow has no automatic white balance switch in OpenCV")

_MSMF = Convention("MSMF", _specs(
    ControlSpec("focus_auto", cv2.CAP_PROP_AUTOFOCUS),
    ControlSpec("focus", cv2.CAP_PROP_FOCUS, lo=0, hi=255, step=1),
    ControlSpec("exposure_auto", cv2.CAP_PROP_AUTO_EXPOSURE, off=0.0, on=1.0, read_on=(1.0,)),
    ControlSpec("exposure", cv2.CAP_PROP_EXPOSURE, lo=-13, hi=-1, step=1, unit="log2 s"),
    ControlSpec("gain", cv2.CAP_PROP_GAIN, lo=0, hi=255, step=1),
    ControlSpec("wb_temperature", cv2.CAP_PROP_TEMPERATURE, lo=2800, hi=6500, step=10, unit="K"),
    ControlSpec("brightness", cv2.CAP_PROP_BRIGHTNESS, lo=-64, hi=64, step=1),
), note="Media Foundation has no automatic white balance switch in OpenCV")

_AVFOUNDATION = Convention("AVFoundation", {}, note=(
    "OpenCV's macOS camera backend offers no focus, exposure or white balance controls: lock "
    "them with the camera maker's tool (or uvc-util) before calibrating"))

CONVENTIONS = {cv2.CAP_V4L2: _V4L2, cv2.CAP_DSHOW: _DSHOW, cv2.CAP_MSMF: _MSMF,
               cv2.CAP_AVFOUNDATION: _AVFOUNDATION}


def convention_for(backend: int | None, platform: str | None = None) -> Convention:
    """The conventions of OpenCV backend `backend` (cv2.CAP_*); None (OpenCV chose) means the
    platform's default camera backend: V4L2 on Linux, Media Foundation on Windows,
    AVFoundation on macOS. Another backend (GStreamer...) offers no controls here."""
    if backend is None:
        platform = platform or sys.platform
        backend = (cv2.CAP_MSMF if platform.startswith("win") else cv2.CAP_AVFOUNDATION
                   if platform == "darwin" else cv2.CAP_V4L2)
    conv = CONVENTIONS.get(int(backend))
    if conv is None:
        return Convention(f"backend {backend}", {}, note="this OpenCV backend's controls are "
                                                         "not known here")
    return conv


@dataclass(frozen=True)
class ControlReading:
    """One control as read from a device: `available` False when it cannot be set (the device
    lacks it, or refused or ignored a write: `note` says which); `value` a bool for a switch, a
    number for a value (None when the device does not report one; a control that ignores
    writes still reports what it is); `lo`, `hi`, `step`, `unit` for its slider."""

    name: str
    available: bool
    value: bool | float | None = None
    lo: float = 0.0
    hi: float = 255.0
    step: float = 1.0
    unit: str = ""
    note: str = ""

    @property
    def label(self) -> str:
        return LABELS[self.name]


@dataclass(frozen=True)
class CameraState:
    """All controls of one camera (`side` "left" or "right") as read back, in CONTROL_NAMES
    order, and its backend's name."""

    side: str
    backend: str
    readings: tuple[ControlReading, ...]
    note: str = ""

    def reading(self, name: str) -> ControlReading:
        for r in self.readings:
            if r.name == name:
                return r
        raise KeyError(name)

    def value(self, name: str) -> bool | float | None:
        """What control `name` reads now (None when the camera does not report it)."""
        return self.reading(name).value

    def settings(self) -> CameraSettings:
        return CameraSettings(self.backend).with_values(
            **{r.name: r.value for r in self.readings if r.value is not None})

    def freed(self, name: str) -> bool:
        """Whether value `name` is held by hand now (its automatic switch is off or missing),
        so that writing it means something."""
        switch = FREED_BY.get(name)
        return switch is None or self.value(switch) is not True


@dataclass(frozen=True)
class WriteResult:
    """What writing `asked` to control `name` of the `side` camera did: `outcome` is "took"
    (read back as asked), "adjusted" (the camera moved, to `read_back`: clamped or rounded to
    its steps), "refused" (the backend said no), "ignored" (accepted, but it reads back as
    before), "unavailable" (the camera lacks it; nothing was written) or "skipped" (settings of
    another backend, whose units differ); `message` says so for the technician."""

    side: str
    name: str
    asked: bool | float
    read_back: bool | float | None
    outcome: str
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.outcome in ("took", "adjusted")


def _fmt(v: bool | float | None) -> str:
    if isinstance(v, bool):
        return "on" if v else "off"
    if v is None:
        return "nothing"
    return f"{v:g}"


class CameraControls:
    """The controls of one opened camera: `cap` is its cv2.VideoCapture (or anything with
    get(prop) and set(prop, value)), `backend` the cv2.CAP_* it was opened with.

    Not thread-safe: used only by the thread that reads the camera's frames."""

    def __init__(self, cap: Device, backend: int | None, side: str,
                 convention: Convention | None = None) -> None:
        self.cap = cap
        self.side = side
        self.convention = convention or convention_for(backend)
        # controls found missing by a write: {name: why}; they stay unavailable
        self._lost: dict[str, str] = {}
        # what was written and taken, {name: value}: a camera opened again (unplugged and
        # plugged in, it starts in its automatic modes) gets it back
        self.wanted: dict[str, bool | float] = {}

    @property
    def backend(self) -> str:
        return self.convention.backend

    # ---- reading ---------------------------------------------------------------------------
    def _get(self, spec: ControlSpec) -> float | None:
        try:
            v = float(self.cap.get(spec.prop))
        except Exception as exc:  # noqa: BLE001 - a device that fails a read lacks the control
            log.debug("%s camera: reading %s failed: %s", self.side, spec.name, exc)
            return None
        return v if math.isfinite(v) else None

    def _decode(self, spec: ControlSpec, raw: float) -> bool | float:
        if spec.switch:
            return any(abs(raw - v) < 1e-3 for v in spec.read_on)
        return raw

    def read_one(self, name: str) -> ControlReading:
        spec = self.convention.specs.get(name)
        if spec is None:
            why = self.convention.note or f"{self.backend} offers no {LABELS[name].lower()}"
            return ControlReading(name, False, note=why)
        slider = ControlReading(name, False, lo=spec.lo, hi=spec.hi, step=spec.step,
                                unit=spec.unit)
        raw = self._get(spec)
        if name in self._lost:  # it cannot be set; what it reads is still what it is
            value = None if raw is None or raw == MISSING else self._decode(spec, raw)
            return replace(slider, value=value, note=self._lost[name])
        if raw is None or raw == MISSING:
            return replace(slider, note="this camera does not have it")
        if not spec.switch:
            # the device's own value may lie outside the typical range: widen the slider to it
            slider = replace(slider, lo=min(spec.lo, raw), hi=max(spec.hi, raw))
        return replace(slider, available=True, value=self._decode(spec, raw))

    def read(self) -> CameraState:
        """Every control, read from the device now."""
        return CameraState(self.side, self.backend,
                           tuple(self.read_one(n) for n in CONTROL_NAMES), self.convention.note)

    # ---- writing ---------------------------------------------------------------------------
    def write(self, name: str, value: bool | float) -> WriteResult:
        """Write one control and read it back (see WriteResult)."""
        spec = self.convention.specs.get(name)
        before = self.read_one(name)
        if spec is None or not before.available:
            return WriteResult(self.side, name, value, None, "unavailable",
                               f"{self.side} camera: {LABELS[name].lower()} is not available "
                               f"({before.note})")
        raw = (spec.on if value else spec.off) if spec.switch else float(value)
        try:
            accepted = bool(self.cap.set(spec.prop, raw))
        except Exception as exc:  # noqa: BLE001 - a failing device refuses the write
            log.debug("%s camera: writing %s failed: %s", self.side, name, exc)
            accepted = False
        after = self.read_one(name)
        got = after.value if after.available else None
        what = f"{self.side} camera: {LABELS[name].lower()}"
        asked: bool | float
        if spec.switch:
            asked = bool(value)
            if got is asked:
                self.wanted[name] = asked
                return WriteResult(self.side, name, asked, got, "took")
            outcome = "refused" if not accepted else "ignored"
        else:
            asked = float(value)
            if got is not None and abs(got - asked) <= max(spec.step / 2, 1e-6):
                self.wanted[name] = got
                return WriteResult(self.side, name, asked, got, "took")
            if got is not None and before.value is not None and abs(got - before.value) > 1e-6:
                self.wanted[name] = got
                return WriteResult(self.side, name, asked, got, "adjusted",
                                   f"{what} set to {_fmt(got)} (asked {_fmt(asked)}: the camera "
                                   "rounds or limits it)")
            if not self._held_by_hand(name):
                # a value its automatic switch sets is refused by design: it is not missing
                return WriteResult(self.side, name, asked, got, "refused",
                                   f"{what} is set by the camera while its automatic mode is on")
            outcome = "refused" if not accepted else "ignored"
            if before.value is not None and self._responds(spec, float(before.value)):
                # it moves for another value: this one lies beyond what the camera can do
                return WriteResult(self.side, name, asked, before.value, outcome,
                                   f"{what} stays at {_fmt(before.value)}: the camera does not "
                                   f"take {_fmt(asked)} (beyond its range?)")
        why = ("the camera refused it" if outcome == "refused"
               else "the camera accepted it but kept its value")
        self._lost[name] = f"{why} when {_fmt(asked)} was written"
        log.warning("%s: %s", what, self._lost[name])
        return WriteResult(self.side, name, asked, got, outcome,
                           f"{what} did not change ({why}); it is shown as unavailable")

    def _responds(self, spec: ControlSpec, before: float) -> bool:
        """Whether value control `spec` moves at all: a value between `before` and the middle
        of its typical range is written, read back, and `before` written again."""
        mid = (spec.lo + spec.hi) / 2
        probe = before + (mid - before) / 2 if abs(mid - before) > 2 * spec.step \
            else before + (spec.hi - spec.lo) / 4
        probe = spec.lo + round((probe - spec.lo) / spec.step) * spec.step
        try:
            self.cap.set(spec.prop, probe)
            moved = self._get(spec)
            self.cap.set(spec.prop, before)
        except Exception:  # noqa: BLE001 - a device that fails here does not respond
            return False
        return moved is not None and moved != MISSING and abs(moved - before) > 1e-6

    def apply(self, settings: CameraSettings) -> list[WriteResult]:
        """Write `settings` (those it knows and this camera has): switches that go off first,
        then the values they free, then switches that go on. Settings read under another
        backend are skipped (their units differ)."""
        if settings.backend and settings.backend != self.backend:
            return [WriteResult(self.side, "", False, None, "skipped",
                                f"{self.side} camera: the controls were saved under "
                                f"{settings.backend}, this camera is opened with {self.backend}; "
                                "they are not restored (other units)")]
        out = []
        known = settings.known
        for name in SWITCHES:
            if known.get(name) is False:
                out.append(self.write(name, False))
        for name, v in known.items():
            if name in SWITCHES:
                continue
            switch = FREED_BY.get(name)
            if switch is not None and known.get(switch) is True:
                continue  # the camera sets it itself
            out.append(self.write(name, v))
        for name in SWITCHES:
            if known.get(name) is True:
                out.append(self.write(name, True))
        return [r for r in out if r.outcome != "unavailable"]

    def _held_by_hand(self, name: str) -> bool:
        """Whether value `name` is free to be written: its automatic switch (if it has one) is
        off or missing."""
        switch = FREED_BY.get(name)
        return switch is None or self.read_one(switch).value is not True

    def lock(self, value_name: str) -> list[WriteResult]:
        """Hold `value_name` (focus, exposure, wb_temperature) at what it is now: its switch
        off, then the value read before written back (switching to manual may reset it)."""
        now = self.read_one(value_name)
        out = [self.write(FREED_BY[value_name], False)]
        if now.available and now.value is not None:
            out.append(self.write(value_name, now.value))
        return out


@dataclass
class PairControls:
    """Both cameras' controls, left and right (as the frames name them)."""

    left: CameraControls
    right: CameraControls

    def side(self, side: str) -> CameraControls:
        return self.left if side == "left" else self.right

    def read(self) -> tuple[CameraState, CameraState]:
        return self.left.read(), self.right.read()

    def settings(self) -> PairSettings:
        return PairSettings(self.left.read().settings(), self.right.read().settings())

    def write(self, name: str, value: bool | float, sides: Iterable[str] = ("left", "right")
              ) -> list[WriteResult]:
        return [self.side(s).write(name, value) for s in sides]

    def apply(self, settings: PairSettings) -> list[WriteResult]:
        return self.left.apply(settings.left) + self.right.apply(settings.right)
