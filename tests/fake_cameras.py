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
        self.props[prop] = value
        return True

    def get(self, prop):
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
