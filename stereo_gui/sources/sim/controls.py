"""The simulated rig's camera controls: each simulated camera answers OpenCV's capture
properties as a V4L2 webcam does (auto exposure 1 manual / 3 automatic, exposure in 100 us
steps, a focus that refuses writes while autofocus is on, -1 for what it lacks), and what is set
acts on its images: exposure and gain scale the brightness, brightness adds to it, the white
balance temperature tints it, and the focus moves the focal length.

In their automatic modes the cameras behave as two webcams left to themselves do: each exposes
for its own brightness target (the two images differ, and change as the scene does), each picks
its own white balance, and autofocus follows the board's distance, changing the focal length by
FOCAL_CHANGE_PER_STEP per focus step. The defaults are the rig as built: everything held by
hand at the values its truth was made with (focus TRUE_FOCUS), so that frames are as before.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import cv2

from stereo_gui.sources.camera_controls import CameraControls, Convention, convention_for

TRUE_FOCUS = 30.0  # the focus the rig's truth (its calibration) holds at
FOCAL_CHANGE_PER_STEP = 0.001  # relative focal length change per focus step
REFERENCE_EXPOSURE = 150.0  # x100 us: the exposure at which the rig renders as built
NEUTRAL_WB_K = 5000.0  # the white balance at which the rig renders as built
MAX_AUTO_EXPOSURE = 330.0  # automatic exposure stays within a 30 fps frame (33 ms)
AUTO_TARGET = {0: 112.0, 1: 128.0}  # grey level each camera's auto exposure aims at
AUTO_WB_K = {0: 4700.0, 1: 5400.0}  # white balance each camera picks by itself
AUTOFOCUS_RATE = 3.0  # focus steps per frame while autofocus moves the lens

SIM_CONVENTION = Convention("simulated", dict(convention_for(cv2.CAP_V4L2).specs),
                            note="the simulated cameras answer as V4L2 webcams do")

_RANGES = {cv2.CAP_PROP_FOCUS: (0.0, 250.0), cv2.CAP_PROP_EXPOSURE: (1.0, 2047.0),
           cv2.CAP_PROP_GAIN: (0.0, 255.0), cv2.CAP_PROP_WB_TEMPERATURE: (2800.0, 6500.0),
           cv2.CAP_PROP_BRIGHTNESS: (0.0, 255.0)}
_FREED_BY = {cv2.CAP_PROP_FOCUS: cv2.CAP_PROP_AUTOFOCUS,
             cv2.CAP_PROP_EXPOSURE: cv2.CAP_PROP_AUTO_EXPOSURE,
             cv2.CAP_PROP_WB_TEMPERATURE: cv2.CAP_PROP_AUTO_WB}


@dataclass(frozen=True)
class CameraLook:
    """What one camera's controls do to its image: `gain` multiplies the brightness, `offset`
    adds grey levels, `channels` multiply blue, green and red, `focal_scale` scales the focal
    length (the image about the principal point)."""

    gain: float = 1.0
    offset: float = 0.0
    channels: tuple[float, float, float] = (1.0, 1.0, 1.0)
    focal_scale: float = 1.0

    @property
    def neutral(self) -> bool:
        return self == CameraLook()


class SimCameraDevice:
    """One simulated camera's controls, as get(prop) / set(prop, value) like cv2.VideoCapture.

    Thread-safe: the frame reader writes the automatic modes' values while a test may read.
    """

    def __init__(self, cam: int, auto_modes: bool = False) -> None:
        self.cam = cam
        self._lock = threading.Lock()
        on = 1.0 if auto_modes else 0.0
        self._v = {cv2.CAP_PROP_AUTOFOCUS: on, cv2.CAP_PROP_FOCUS: TRUE_FOCUS,
                   cv2.CAP_PROP_AUTO_EXPOSURE: 3.0 if auto_modes else 1.0,
                   cv2.CAP_PROP_EXPOSURE: REFERENCE_EXPOSURE, cv2.CAP_PROP_GAIN: 0.0,
                   cv2.CAP_PROP_AUTO_WB: on, cv2.CAP_PROP_WB_TEMPERATURE: NEUTRAL_WB_K,
                   cv2.CAP_PROP_BRIGHTNESS: 128.0}

    def _auto(self, switch: int) -> bool:
        v = self._v[switch]
        return v in (0.0, 3.0) if switch == cv2.CAP_PROP_AUTO_EXPOSURE else v == 1.0

    def get(self, prop: int) -> float:
        with self._lock:
            return float(self._v.get(int(prop), -1.0))

    def set(self, prop: int, value: float) -> bool:
        prop, value = int(prop), float(value)
        with self._lock:
            if prop not in self._v or not math.isfinite(value):
                return False
            switch = _FREED_BY.get(prop)
            if switch is not None and self._auto(switch):
                return False  # V4L2 refuses a control its automatic mode holds
            if prop == cv2.CAP_PROP_AUTO_EXPOSURE:
                if int(value) not in (1, 3):
                    return False
                value = float(int(value))
            elif prop in (cv2.CAP_PROP_AUTOFOCUS, cv2.CAP_PROP_AUTO_WB):
                value = 1.0 if round(value) == 1 else 0.0
            else:
                lo, hi = _RANGES[prop]
                value = float(round(min(max(value, lo), hi)))
            self._v[prop] = value
            return True

    # ---- what the automatic modes do, frame by frame ----------------------------------------
    def follow(self, mean_grey: float | None, board_distance_mm: float | None) -> None:
        """Let the automatic modes react to the frame just rendered: auto exposure towards its
        target brightness (`mean_grey` of the image), autofocus towards the board's distance
        (mm; None: the scene, about 1.5 m), auto white balance to this camera's own choice."""
        with self._lock:
            if self._auto(cv2.CAP_PROP_AUTO_EXPOSURE) and mean_grey:
                ratio = AUTO_TARGET[self.cam] / max(mean_grey, 1.0)
                e = self._v[cv2.CAP_PROP_EXPOSURE] * ratio ** 0.5
                self._v[cv2.CAP_PROP_EXPOSURE] = float(round(min(max(e, 1.0),
                                                                  MAX_AUTO_EXPOSURE)))
            if self._auto(cv2.CAP_PROP_AUTOFOCUS):
                d = 1500.0 if board_distance_mm is None else board_distance_mm
                target = TRUE_FOCUS + (d - 700.0) / 25.0
                f = self._v[cv2.CAP_PROP_FOCUS]
                step = max(-AUTOFOCUS_RATE, min(AUTOFOCUS_RATE, target - f))
                self._v[cv2.CAP_PROP_FOCUS] = float(min(max(round(f + step), 0.0), 250.0))
            if self._auto(cv2.CAP_PROP_AUTO_WB):
                self._v[cv2.CAP_PROP_WB_TEMPERATURE] = AUTO_WB_K[self.cam]

    def look(self) -> CameraLook:
        """What the controls set now do to this camera's image."""
        with self._lock:
            v = dict(self._v)
        gain = v[cv2.CAP_PROP_EXPOSURE] / REFERENCE_EXPOSURE * 2.0 ** (v[cv2.CAP_PROP_GAIN] / 64.0)
        tint = (v[cv2.CAP_PROP_WB_TEMPERATURE] / NEUTRAL_WB_K) ** 0.4
        return CameraLook(gain, (v[cv2.CAP_PROP_BRIGHTNESS] - 128.0) * 0.5,
                          (1.0 / tint, 1.0, tint),
                          1.0 + FOCAL_CHANGE_PER_STEP * (v[cv2.CAP_PROP_FOCUS] - TRUE_FOCUS))


def sim_controls(device: SimCameraDevice, side: str) -> CameraControls:
    """CameraControls of a simulated camera (V4L2 conventions, backend "simulated")."""
    return CameraControls(device, None, side, convention=SIM_CONVENTION)
