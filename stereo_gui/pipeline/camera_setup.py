"""Setting up two webcams for a calibration and for measuring, below Qt: the controls a
calibration was made with written back and what still differs said (restore-and-warn), focus
locked where autofocus is on, and the right camera's exposure and gain set so that its image
matches the left's (exposure matching). Everything here runs in the frame worker's reader
thread, as tasks handed to it (FrameWorker.run_on_source): only that thread touches devices.

A calibration names its cameras as its pairs were calibrated: when the cameras were found
swapped (`StereoCalibration.swapped_inputs`), its left camera is the source's right one.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.camera_settings import (
    PairSettings,
    SettingsMismatch,
    compare_with_calibration,
)
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.util import to_gray
from stereo_gui.sources.camera_controls import (
    CameraState,
    ControlReading,
    PairControls,
    WriteResult,
)

log = logging.getLogger(__name__)

# the share of the width, at each image's outer side, that only one camera sees (the left
# image's left edge, the right image's right edge): left out of the brightness compared
OVERLAP_MARGIN = 0.15
MATCH_TOLERANCE = 0.02  # brightness ratio within 2 %: matched
MATCH_MAX_STEPS = 8  # steps before matching gives up and says how close it came
MATCH_SETTLE_FRAMES = 3  # frames a webcam takes to show a new exposure: waited between steps
GAIN_STEPS_PER_DOUBLING = 64.0  # a first guess at the gain scale; each step corrects it


@dataclass(frozen=True)
class ControlsReport:
    """The cameras' controls read back (source order: `left` is the source's left camera),
    what the last writes did, and what differs from the calibration in use."""

    left: CameraState
    right: CameraState
    results: tuple[WriteResult, ...] = ()
    mismatches: tuple[SettingsMismatch, ...] = ()

    @property
    def settings(self) -> PairSettings:
        return PairSettings(self.left.settings(), self.right.settings())

    @property
    def failures(self) -> tuple[WriteResult, ...]:
        return tuple(r for r in self.results if not r.ok)

    def autofocus_on(self) -> tuple[str, ...]:
        """The sides ("left", "right") whose autofocus is on."""
        return tuple(s.side for s in (self.left, self.right) if s.value("focus_auto") is True)


def calibration_controls_in_source_order(calib: StereoCalibration | None) -> PairSettings | None:
    """The controls a calibration was made with, as the source names its cameras."""
    if calib is None or calib.camera_controls is None or calib.camera_controls.empty:
        return None
    c = calib.camera_controls
    return c.swapped() if calib.swapped_inputs else c


def _mismatches(pair: PairControls, calib: StereoCalibration | None,
                size_now: tuple[int, int] | None) -> tuple[SettingsMismatch, ...]:
    if calib is None:
        return ()
    now = pair.settings()
    if calib.swapped_inputs:
        now = now.swapped()
    return tuple(compare_with_calibration(calib.camera_controls, now, calib.image_size,
                                          size_now))


def read_controls(pair: PairControls, calib: StereoCalibration | None = None,
                  size_now: tuple[int, int] | None = None) -> ControlsReport:
    """The cameras' controls now, and what differs from `calib`'s (None: nothing to compare)."""
    left, right = pair.read()
    return ControlsReport(left, right, (), _mismatches(pair, calib, size_now))


def write_control(pair: PairControls, name: str, value: bool | float,
                  sides: Sequence[str] = ("left", "right"),
                  calib: StereoCalibration | None = None,
                  size_now: tuple[int, int] | None = None) -> ControlsReport:
    """Write one control to the `sides` cameras (both: "same for both cameras")."""
    results = tuple(pair.write(name, value, sides))
    left, right = pair.read()
    return ControlsReport(left, right, results, _mismatches(pair, calib, size_now))


def restore_calibration_controls(pair: PairControls, calib: StereoCalibration | None,
                                 size_now: tuple[int, int] | None = None) -> ControlsReport:
    """Write back the controls `calib` was made with (those these cameras have, under the same
    backend), read them back, and say what still differs (a focus the camera would not take,
    another resolution)."""
    want = calibration_controls_in_source_order(calib)
    results = tuple(pair.apply(want)) if want is not None else ()
    for r in results:
        if not r.ok:
            log.warning("restoring the calibration's controls: %s", r.message)
    left, right = pair.read()
    return ControlsReport(left, right, results, _mismatches(pair, calib, size_now))


def lock_focus(pair: PairControls, sides: Sequence[str] = ("left", "right"),
               calib: StereoCalibration | None = None,
               size_now: tuple[int, int] | None = None) -> ControlsReport:
    """Turn autofocus off on the `sides` cameras, holding the focus where it is now."""
    results = []
    for side in sides:
        c = pair.side(side)
        if c.read_one("focus_auto").value is True:
            results.extend(c.lock("focus"))
    left, right = pair.read()
    return ControlsReport(left, right, tuple(results), _mismatches(pair, calib, size_now))


# ---- exposure matching --------------------------------------------------------------------------
def overlap_brightness(left: np.ndarray, right: np.ndarray,
                       margin: float = OVERLAP_MARGIN) -> tuple[float, float]:
    """Mean grey level of each image over the part both cameras see: the left image without
    its left `margin` of the width, the right image without its right one."""
    gl, gr = to_gray(left), to_gray(right)
    w = gl.shape[1]
    m = int(round(w * margin))
    return float(gl[:, m:].mean()), float(gr[:, :w - m].mean())


@dataclass(frozen=True)
class MatchStep:
    """One step of exposure matching: `ratio` is the left image's brightness over the right's
    on the overlap (measured before this step), `done` True when within MATCH_TOLERANCE or when
    nothing more can be done (`message` says which), `results` what was written."""

    ratio: float
    done: bool
    message: str
    results: tuple[WriteResult, ...] = ()
    report: ControlsReport | None = None


def _log_units(r: ControlReading) -> bool:
    return r.unit.startswith("log2")


def exposure_limit(reading: ControlReading, fps: float) -> float | None:
    """The longest exposure (in `reading`'s units) that keeps `fps` frames per second: a
    longer one would lower the frame rate and widen the cameras' skew."""
    if not fps or fps <= 0 or not math.isfinite(fps):
        return None
    if _log_units(reading):
        return float(math.floor(math.log2(1.0 / fps)))
    if reading.unit.startswith("x100"):
        return float(math.floor(1e4 / fps))
    return None


def begin_exposure_matching(pair: PairControls) -> list[WriteResult]:
    """Hold both cameras' exposure where it is (automatic exposure off): the left is the
    reference, the right is then set to match it; neither drifts afterwards."""
    out = []
    for c in (pair.left, pair.right):
        if c.read_one("exposure_auto").value is True:
            out.extend(c.lock("exposure"))
    return out


def exposure_match_step(pair: PairControls, left_img: np.ndarray, right_img: np.ndarray,
                        max_exposure: float | None = None,
                        tolerance: float = MATCH_TOLERANCE) -> MatchStep:
    """Measure the brightness of both images on their overlap and set the right camera's
    exposure (first) and gain (for what the exposure cannot do) so that the right image
    matches the left. `max_exposure` caps the exposure (in the camera's units) so that the
    frame rate is kept. Brightness is taken to follow the exposure time; the gain's scale is
    not known (GAIN_STEPS_PER_DOUBLING is a first guess): each step measures again, so a few
    steps correct it."""
    lm, rm = overlap_brightness(left_img, right_img)
    if rm < 1.0 or lm < 1.0:
        return MatchStep(float("nan"), True, "an image is black: nothing to match")
    ratio = lm / rm
    if abs(ratio - 1.0) <= tolerance:
        return MatchStep(ratio, True, f"matched: the right image is within "
                                      f"{abs(ratio - 1) * 100:.1f} % of the left's brightness")
    right = pair.right.read()
    exp, gain = right.reading("exposure"), right.reading("gain")
    remaining = ratio
    results: list[WriteResult] = []
    if exp.available and right.freed("exposure") and exp.value is not None:
        e = float(exp.value)
        hi = exp.hi if max_exposure is None else min(exp.hi, max_exposure)
        if _log_units(exp):
            want = min(max(round(e + math.log2(ratio)), exp.lo), hi)
            remaining = ratio / 2.0 ** (want - e)
        else:
            want = min(max(round(e * ratio / exp.step) * exp.step, exp.lo), hi)
            remaining = ratio * e / want if want > 0 else ratio
        if want != e:
            results.append(pair.right.write("exposure", want))
    if abs(remaining - 1.0) > tolerance / 2 and gain.available and gain.value is not None:
        g = float(gain.value)
        want_g = min(max(round(g + GAIN_STEPS_PER_DOUBLING * math.log2(remaining)), gain.lo),
                     gain.hi)
        if want_g != g:
            results.append(pair.right.write("gain", want_g))
    if not results:
        return MatchStep(ratio, True, f"the right camera cannot be brought closer: its exposure "
                                      f"and gain are at their limits or unavailable (the right "
                                      f"image is {(1 / ratio - 1) * 100:+.0f} % of the left's)")
    left_state, right_state = pair.read()
    return MatchStep(ratio, False, f"right image {(1 / ratio - 1) * 100:+.1f} % of the left's: "
                                   "adjusting", tuple(results),
                     ControlsReport(left_state, right_state, tuple(results)))
