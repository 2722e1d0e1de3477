"""What the Live tab says about a pixel, without Qt: the reading under the pointer (the same
`core.measure.measure_point` a double-click runs, computed on the job thread), the true distance
on the simulated rig, and distances formatted for labels.

One rule for units everywhere in the live views: a distance is in metres to the millimetre
("0.812 m", "3.014 m"), an uncertainty or an error in millimetres ("± 4.1 mm").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.click_map import reading_map
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.measure import Measurement, measure_point
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration

# views sharing the left image's pixel frame: a reading there is a reading of the left image
MEASURABLE_VIEWS = ("left", "raw", "closed", "depth", "wls")
TRUTH_LABEL = "TRUE (simulated scene)"


def format_distance(mm: float) -> str:
    """A distance for a label: always metres with millimetre resolution ("0.812 m")."""
    if not math.isfinite(mm):
        return "–"
    return f"{mm / 1000:.3f} m"


def format_error(mm: float) -> str:
    """An uncertainty or an error for a label: always millimetres ("± 4.1 mm")."""
    if math.isnan(mm):
        return "± –"
    if math.isinf(mm):
        return "± ∞"
    return f"± {mm:.1f} mm" if abs(mm) < 1000 else f"± {mm:.0f} mm"


def disparity_of_view(result: PipelineResult | None, key: str) -> np.ndarray | None:
    """The disparity (px, NaN invalid) view `key` shows: raw, closed, or the final one."""
    if result is None:
        return None
    if key == "raw":
        return result.disparity_px
    if key == "closed":
        return result.closed_px
    return result.final_px


def true_point(truth: object | None, calibration: StereoCalibration | None, x: float, y: float
               ) -> np.ndarray | None:
    """The true (X, Y, Z) mm seen at rectified pixel (x, y) when the frame carries ground truth
    that can say so (`StereoFrame.truth` of the simulated rig), else None."""
    locate = getattr(truth, "point_rectified", None)
    if locate is None or calibration is None:
        return None
    p = locate(calibration, x, y)
    return None if p is None else np.asarray(p, np.float64)


@dataclass(frozen=True)
class PointerReading:
    """What the readout line shows for the pointer at (x, y) px of view `key`.

    `measurement` is what a double-click at that pixel of the same frame gives (None when the
    pointer is outside the image or over the right image); `true_z_mm` is the rendered scene's
    depth there on the simulated rig (None elsewhere); `note` says why there is no measurement.
    `map_px` is the depth map's own disparity at that pixel (NaN where it has none): the line
    says it where the reading differs from it by more than the reading's bound.
    """

    key: str
    x: float
    y: float
    measurement: Measurement | None = None
    true_z_mm: float | None = None
    note: str = ""
    map_px: float = float("nan")


def read_pointer(result: PipelineResult | None, key: str, x: float, y: float,
                 patch: int, fit: FitResult | None = None, truth: object | None = None
                 ) -> PointerReading:
    """The reading for the pointer at (x, y) px of view `key` of `result` (None: no frame yet):
    `measure_point` with the click's patch and fit, so hover and double-click agree. Runs the
    matcher's refinement and scans: call it off the UI thread."""
    if result is None:
        return PointerReading(key, x, y, note="no frame yet")
    h, w = result.disparity_px.shape[:2]
    if not (0 <= round(x) < w and 0 <= round(y) < h):
        return PointerReading(key, x, y, note="outside the image")
    if key not in MEASURABLE_VIEWS:
        return PointerReading(key, x, y, note="right image: measure on the left or a disparity "
                                              "view")
    m = measure_point(result, x, y, patch=patch, fit=fit)
    t = true_point(truth, result.calibration, x, y)
    shown = float(reading_map(result)[round(y), round(x)])
    return PointerReading(key, x, y, m, None if t is None else float(t[2]), map_px=shown)


def readout_line(r: PointerReading) -> str:
    """The readout line of a pointer reading."""
    where = f"x {round(r.x):4d}  y {round(r.y):4d}   "
    m = r.measurement
    if m is None:
        return where + r.note
    truth = ("" if r.true_z_mm is None else
             f"   |  {TRUTH_LABEL}: Z {format_distance(r.true_z_mm)}")
    if not m.valid:
        # the depth view may show a colour here: say that the click does not take it
        shown = (_map_says(r.map_px, "the click does not take it")
                 if math.isfinite(r.map_px) else "")
        return where + f"no distance: {m.reason or 'invalid'}{shown}{truth}"
    how = "" if m.method == "triangulation" else f" ({m.method} fit)"
    return (where + f"Z {format_distance(m.Z_mm)} {format_error(m.expected_error_mm)}{how}   "
                    f"disparity {m.disparity_px:.2f} px   as a double-click reads it"
                    f"{_beside_map(r)}{truth}")


def _beside_map(r: PointerReading) -> str:
    """Why the reading and the depth map's value at its pixel differ, where they do by more than
    the reading's 95 % bound: one number for one pixel, or the reason there are two."""
    m = r.measurement
    if m is None or not m.valid:
        return ""
    if not math.isfinite(r.map_px):
        return "   (the map has no value at this pixel: read from its patch)"
    bound = m.disparity_bound_px if math.isfinite(m.disparity_bound_px) else 0.0
    if abs(m.disparity_px - r.map_px) <= max(bound, 1.0 / 16.0):
        return ""
    return _map_says(r.map_px, "the reading is of its "
                     + ("patch, aligned with the right image" if m.refined else "patch"))


def _map_says(map_px: float, why: str) -> str:
    """The readout's note of the depth map's own value at the pixel, and why the line's differs."""
    return f"   (the map says {map_px:.2f} px at this pixel: {why})"
