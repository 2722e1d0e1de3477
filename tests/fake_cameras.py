"""A fake cv2.VideoCapture for the camera sources' tests (tests/sources) and the window's
(tests/qt): importable as `fake_cameras` from any test (tests/ is on sys.path)."""

from __future__ import annotations

import time

import cv2
import numpy as np


class FakeCapture:
    """Stands in for cv2.VideoCapture(index): devices and their behaviour live in `devices`."""

    devices: dict = {}
    log: list = []

    def __init__(self, index, *args):
        self.index = index
        self.dev = FakeCapture.devices.get(index)
        self.props = {}
        self.grabs = 0
        self.released = False

    def isOpened(self):
        return self.dev is not None

    def set(self, prop, value):
        controls = self.dev.get("controls") if self.dev else None
        if controls is not None and prop in CONTROL_PROPS:
            return controls.set(prop, value)
        self.props[prop] = value
        return True

    def get(self, prop):
        controls = self.dev.get("controls") if self.dev else None
        if controls is not None and prop in CONTROL_PROPS:
            return controls.get(prop)
        return 25.0 if prop == cv2.CAP_PROP_FPS else 0.0

    def grab(self):
        FakeCapture.log.append(("grab", self.index))
        if self.dev.get("period_s"):  # the camera's own frame clock
            time.sleep(self.dev["period_s"])
        self.grabs += 1
        if self.dev.get("gone"):  # unplugged: grabs fail (a new capture does not open)
            return False
        dead_after = self.dev.get("dead_after")
        if dead_after is not None and self.grabs > dead_after:
            return False
        return self.grabs not in self.dev.get("drop", ())

    def retrieve(self):
        FakeCapture.log.append(("retrieve", self.index))
        if self.grabs in self.dev.get("undecodable", ()):
            return False, None
        w, h = self.dev.get("size", (64, 48))
        shape = (h, w) if self.dev.get("gray") else (h, w, 3)
        return True, np.full(shape, self.dev["value"] + self.grabs, np.uint8)

    def read(self):
        return (self.grab() and self.retrieve()) or (False, None)

    def release(self):
        FakeCapture.log.append(("release", self.index))
        self.released = True


class PresentCapture:
    """A minimal fake cv2.VideoCapture: indices in `present` open and deliver frames of their
    index's grey level; `backends` records every (index, *args) it was opened with."""

    present: set = set()
    backends: list = []

    def __init__(self, index, *args):
        self.index = index
        PresentCapture.backends.append((index, *args))

    def isOpened(self):
        return self.index in PresentCapture.present

    def set(self, *args):
        return True

    def get(self, prop):
        return 30.0

    def grab(self):
        return True

    def retrieve(self):
        return True, np.full((48, 64, 3), self.index, np.uint8)

    def read(self):
        return self.retrieve()

    def release(self):
        pass


def unplug(devices: dict, index: int) -> None:
    """Make camera `index` vanish: its open captures fail, a new one does not open."""
    devices.pop(index)["gone"] = True


# ---- camera controls -------------------------------------------------------------------------
# The capture properties of the controls a fake device may answer for
CONTROL_PROPS = (cv2.CAP_PROP_AUTOFOCUS, cv2.CAP_PROP_FOCUS, cv2.CAP_PROP_AUTO_EXPOSURE,
                 cv2.CAP_PROP_EXPOSURE, cv2.CAP_PROP_GAIN, cv2.CAP_PROP_AUTO_WB,
                 cv2.CAP_PROP_WB_TEMPERATURE, cv2.CAP_PROP_TEMPERATURE,
                 cv2.CAP_PROP_WHITE_BALANCE_BLUE_U, cv2.CAP_PROP_BRIGHTNESS)


class FakeControlDevice:
    """A webcam's controls as one OpenCV backend shows them: `kind` is "V4L2", "DirectShow",
    "MSMF" or "AVFoundation". `values` {prop: value} are the controls the device has (in the
    backend's own units), `ranges` {prop: (lo, hi, step)} how it clamps and rounds them,
    `ignores` props it accepts and keeps unchanged (a driver that says yes and does nothing).
    `sets` records every set(prop, value, accepted) asked of it.

    How each backend answers is taken from OpenCV's sources (cap_v4l.cpp, cap_dshow.cpp,
    cap_msmf.cpp, cap_avfoundation_mac.mm):
    - V4L2: a control the device lacks reads -1 and refuses writes; the exposure (focus, white
      balance temperature) refuses writes while its automatic switch is on (V4L2 answers
      EACCES for an inactive control); auto exposure is a menu of 1 (manual) and 3 (aperture
      priority): other values are refused.
    - DirectShow: CAP_PROP_AUTO_EXPOSURE is not handled (reads -1, refuses writes); autofocus
      reads back DirectShow's flags, 1 automatic and 2 manual; a value written (focus,
      exposure) is taken as a manual value; white balance is CAP_PROP_WHITE_BALANCE_BLUE_U.
    - MSMF: auto exposure and autofocus read 0/1 and any non-zero write means automatic.
    - AVFoundation: every control reads 0 and refuses writes.
    """

    def __init__(self, kind: str, values: dict, ranges: dict | None = None,
                 ignores=()) -> None:
        self.kind = kind
        self.values = dict(values)
        self.ranges = dict(ranges or {})
        self.ignores = set(ignores)
        self.sets: list[tuple[int, float, bool]] = []

    # switches and the values they hold, per backend
    def _freed_by(self) -> dict:
        if self.kind == "V4L2":
            return {cv2.CAP_PROP_FOCUS: cv2.CAP_PROP_AUTOFOCUS,
                    cv2.CAP_PROP_EXPOSURE: cv2.CAP_PROP_AUTO_EXPOSURE,
                    cv2.CAP_PROP_WB_TEMPERATURE: cv2.CAP_PROP_AUTO_WB}
        return {}

    def _auto_on(self, switch: int) -> bool:
        v = self.values.get(switch)
        if switch == cv2.CAP_PROP_AUTO_EXPOSURE and self.kind == "V4L2":
            return v in (0.0, 3.0)
        return bool(v)

    def get(self, prop):
        if self.kind == "AVFoundation":
            return 0.0
        if prop == cv2.CAP_PROP_AUTO_EXPOSURE and self.kind == "DirectShow":
            return -1.0
        if prop not in self.values:
            return -1.0
        v = self.values[prop]
        if self.kind == "DirectShow" and prop == cv2.CAP_PROP_AUTOFOCUS:
            return 1.0 if v else 2.0
        return float(v)

    def _accept(self, prop, value) -> bool:
        if self.kind == "AVFoundation" or prop not in self.values:
            return False
        if self.kind == "DirectShow" and prop == cv2.CAP_PROP_AUTO_EXPOSURE:
            return False
        switch = self._freed_by().get(prop)
        if switch is not None and self._auto_on(switch):
            return False
        if self.kind == "V4L2" and prop == cv2.CAP_PROP_AUTO_EXPOSURE and \
                int(value) not in (1, 3):
            return False
        if prop in self.ignores:
            return True
        if self.kind == "MSMF" and prop in (cv2.CAP_PROP_AUTO_EXPOSURE, cv2.CAP_PROP_AUTOFOCUS):
            value = 1.0 if value != 0 else 0.0
        elif self.kind in ("V4L2", "DirectShow") and prop in (cv2.CAP_PROP_AUTOFOCUS,
                                                              cv2.CAP_PROP_AUTO_WB):
            value = 1.0 if round(value) == 1 else 0.0
        lo, hi, step = self.ranges.get(prop, (-1e9, 1e9, 0))
        value = min(max(float(value), lo), hi)
        if step:
            value = lo + round((value - lo) / step) * step
        self.values[prop] = value
        if self.kind == "DirectShow" and prop in (cv2.CAP_PROP_FOCUS,):
            self.values[cv2.CAP_PROP_AUTOFOCUS] = 0.0  # a value written is a manual value
        return True

    def set(self, prop, value):
        ok = self._accept(prop, value)
        self.sets.append((prop, float(value), ok))
        return ok

    # ---- the webcams the tests use ----------------------------------------------------------
    @staticmethod
    def v4l2(focus: bool = True, **changes) -> FakeControlDevice:
        """A UVC webcam under V4L2 (like a C920): all eight controls, focus in steps of 5;
        without `focus` a fixed-focus one (like a C270)."""
        values = {cv2.CAP_PROP_AUTOFOCUS: 1.0, cv2.CAP_PROP_FOCUS: 30.0,
                  cv2.CAP_PROP_AUTO_EXPOSURE: 3.0, cv2.CAP_PROP_EXPOSURE: 156.0,
                  cv2.CAP_PROP_GAIN: 0.0, cv2.CAP_PROP_AUTO_WB: 1.0,
                  cv2.CAP_PROP_WB_TEMPERATURE: 4600.0, cv2.CAP_PROP_BRIGHTNESS: 128.0}
        if not focus:
            del values[cv2.CAP_PROP_AUTOFOCUS], values[cv2.CAP_PROP_FOCUS]
        values.update(changes.pop("values", {}))
        ranges = {cv2.CAP_PROP_FOCUS: (0, 250, 5), cv2.CAP_PROP_EXPOSURE: (3, 2047, 1),
                  cv2.CAP_PROP_GAIN: (0, 255, 1), cv2.CAP_PROP_WB_TEMPERATURE: (2000, 6500, 1),
                  cv2.CAP_PROP_BRIGHTNESS: (0, 255, 1)}
        return FakeControlDevice("V4L2", values, ranges, **changes)

    @staticmethod
    def dshow(**changes) -> FakeControlDevice:
        """A webcam under DirectShow: focus, exposure (log2 s), gain, white balance, brightness."""
        values = {cv2.CAP_PROP_AUTOFOCUS: 1.0, cv2.CAP_PROP_FOCUS: 30.0,
                  cv2.CAP_PROP_EXPOSURE: -6.0, cv2.CAP_PROP_GAIN: 0.0,
                  cv2.CAP_PROP_WHITE_BALANCE_BLUE_U: 4600.0, cv2.CAP_PROP_BRIGHTNESS: 0.0}
        ranges = {cv2.CAP_PROP_FOCUS: (0, 250, 5), cv2.CAP_PROP_EXPOSURE: (-13, -1, 1),
                  cv2.CAP_PROP_BRIGHTNESS: (-64, 64, 1)}
        return FakeControlDevice("DirectShow", values, ranges, **changes)

    @staticmethod
    def msmf(**changes) -> FakeControlDevice:
        values = {cv2.CAP_PROP_AUTOFOCUS: 1.0, cv2.CAP_PROP_FOCUS: 30.0,
                  cv2.CAP_PROP_AUTO_EXPOSURE: 1.0, cv2.CAP_PROP_EXPOSURE: -6.0,
                  cv2.CAP_PROP_GAIN: 0.0, cv2.CAP_PROP_TEMPERATURE: 4600.0,
                  cv2.CAP_PROP_BRIGHTNESS: 0.0}
        return FakeControlDevice("MSMF", values, {cv2.CAP_PROP_EXPOSURE: (-13, -1, 1)},
                                 **changes)

    @staticmethod
    def avfoundation() -> FakeControlDevice:
        return FakeControlDevice("AVFoundation", {})
