"""What a camera's controls were set to (focus, exposure, gain, white balance, brightness), as
plain data: remembered with a capture session and a calibration, and compared when the cameras
are opened again. How the values are read from and written to a device is
`stereo_gui.sources.camera_controls`; this module knows no device.

Values are in the units of the backend that read them (`backend`): a V4L2 exposure is in 100 us
steps, a DirectShow or Media Foundation one is log2 of seconds. Two settings are compared only
when they come from the same backend.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

# the controls, in the order they are shown and written (a switch before the value it frees)
SWITCHES = ("focus_auto", "exposure_auto", "wb_auto")
VALUES = ("focus", "exposure", "gain", "wb_temperature", "brightness")
CONTROL_NAMES = ("focus_auto", "focus", "exposure_auto", "exposure", "gain", "wb_auto",
                 "wb_temperature", "brightness")
# the value a switch frees: the value is the camera's own while its switch is on
FREED_BY = {"focus": "focus_auto", "exposure": "exposure_auto", "wb_temperature": "wb_auto"}
LABELS = {"focus_auto": "Autofocus", "focus": "Focus", "exposure_auto": "Auto exposure",
          "exposure": "Exposure", "gain": "Gain", "wb_auto": "Auto white balance",
          "wb_temperature": "White balance", "brightness": "Brightness"}
# focus values closer than this (in the device's steps) count as the same focus: webcams take
# focus in steps of 1 to 5 and read back the step they settled on
FOCUS_TOLERANCE = 2.5


@dataclass(frozen=True)
class CameraSettings:
    """One camera's controls: each None when the camera does not have it (or it is unknown).

    Switches are True (automatic) or False (held by hand); values are in `backend`'s units.
    """

    backend: str = ""
    focus_auto: bool | None = None
    focus: float | None = None
    exposure_auto: bool | None = None
    exposure: float | None = None
    gain: float | None = None
    wb_auto: bool | None = None
    wb_temperature: float | None = None
    brightness: float | None = None

    def get(self, name: str) -> float | bool | None:
        if name not in CONTROL_NAMES:
            raise KeyError(name)
        value: float | bool | None = getattr(self, name)
        return value

    def with_values(self, **changes: Any) -> CameraSettings:
        return replace(self, **changes)

    @property
    def known(self) -> dict[str, float | bool]:
        """{control: value} of the controls that have a value."""
        return {n: getattr(self, n) for n in CONTROL_NAMES if getattr(self, n) is not None}

    def to_json(self) -> dict[str, object]:
        return {"backend": self.backend, **self.known}

    @staticmethod
    def from_json(data: object, where: str = "camera controls") -> CameraSettings:
        """The settings `to_json` wrote; ValueError naming the field that is wrong. Unknown
        fields are ignored (a later version may know more controls)."""
        if not isinstance(data, dict):
            raise ValueError(f"{where} should be an object")
        backend = data.get("backend", "")
        if not isinstance(backend, str) or len(backend) > 64:
            raise ValueError(f"{where}: backend should be a short text")
        out: dict[str, Any] = {}  # (checked: a bool for a switch, a float for the rest)
        for name in CONTROL_NAMES:
            v = data.get(name)
            if v is None:
                continue
            if name in SWITCHES:
                if not isinstance(v, bool):
                    raise ValueError(f"{where}: {name} should be true or false")
                out[name] = v
            else:
                # (abs first: an integer such as 10**400 has no float, and isfinite would fail)
                if isinstance(v, bool) or not isinstance(v, int | float) or abs(v) > 1e7 \
                        or not math.isfinite(v):
                    raise ValueError(f"{where}: {name} should be a finite number")
                out[name] = float(v)
        return CameraSettings(backend, **out)


@dataclass(frozen=True)
class PairSettings:
    """Both cameras' controls, left and right (as the calibration names the cameras)."""

    left: CameraSettings = CameraSettings()
    right: CameraSettings = CameraSettings()

    def side(self, side: str) -> CameraSettings:
        if side not in ("left", "right"):
            raise KeyError(side)
        return self.left if side == "left" else self.right

    @property
    def empty(self) -> bool:
        return not (self.left.known or self.right.known)

    def swapped(self) -> PairSettings:
        """Left and right exchanged (for a calibration made with the images exchanged)."""
        return PairSettings(self.right, self.left)

    def to_json(self) -> dict[str, object]:
        return {"left": self.left.to_json(), "right": self.right.to_json()}

    @staticmethod
    def from_json(data: object, where: str = "camera controls") -> PairSettings:
        if not isinstance(data, dict):
            raise ValueError(f"{where} should be an object with left and right")
        return PairSettings(CameraSettings.from_json(data.get("left", {}), f"{where} left"),
                            CameraSettings.from_json(data.get("right", {}), f"{where} right"))


@dataclass(frozen=True)
class SettingsMismatch:
    """Why the cameras now are not as they were when a calibration was made: `what` is "focus",
    "autofocus" or "resolution", `side` "left", "right" or "" (both), `message` the sentence
    shown to the technician, `restorable` whether writing the calibration's controls back can
    mend it (a resolution cannot be written to a camera that is open)."""

    what: str
    side: str
    message: str
    restorable: bool


def _fmt(v: float) -> str:
    return f"{v:g}" if abs(v - round(v)) > 1e-9 else f"{int(round(v))}"


def compare_with_calibration(calibrated: PairSettings | None, now: PairSettings,
                             calibrated_size: tuple[int, int] | None = None,
                             size_now: tuple[int, int] | None = None) -> list[SettingsMismatch]:
    """What differs between the controls a calibration was made with and those read now, where
    it matters for the calibration's validity: the focus (it moves the focal length and the
    distortion), autofocus left on, and the resolution. Exposure, gain and white balance change
    the images' look, not their geometry, and are not reported here."""
    out: list[SettingsMismatch] = []
    if calibrated_size is not None and size_now is not None and \
            tuple(calibrated_size) != tuple(size_now):
        cw, ch = calibrated_size
        w, h = size_now
        out.append(SettingsMismatch(
            "resolution", "", f"the calibration was made at {cw}x{ch} px; the cameras deliver "
            f"{w}x{h} px: choose {cw}x{ch} (File > Choose source…) or calibrate again", False))
    if calibrated is None:
        return out
    for side in ("left", "right"):
        cal, cur = calibrated.side(side), now.side(side)
        if cal.backend and cur.backend and cal.backend != cur.backend:
            continue  # other units: a focus of 30 under V4L2 is not one under DirectShow
        if cur.focus_auto and cal.focus_auto is False:
            at = f" at focus {_fmt(cal.focus)}" if cal.focus is not None else ""
            out.append(SettingsMismatch(
                "autofocus", side, f"the calibration was made with the {side} camera's focus "
                f"locked{at}; autofocus is on now: distances will be wrong whenever it refocuses",
                True))
        elif cal.focus is not None and cur.focus is not None and \
                abs(cal.focus - cur.focus) > FOCUS_TOLERANCE:
            out.append(SettingsMismatch(
                "focus", side, f"the calibration was made at focus {_fmt(cal.focus)}; the {side} "
                f"camera is at {_fmt(cur.focus)}: distances will be wrong", True))
    return out

