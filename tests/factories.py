"""Objects the tests build again and again, made in one place.

`make_calibration` is the tests' one stereo calibration factory, `make_records` their
measurement log (tests/ is on the import path: `from factories import make_calibration`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.camera_settings import CameraSettings, PairSettings
from stereo_gui.core.stereo_calibration import PairError, StereoCalibration
from stereo_gui.files.measurement_record import MeasurementRecord

SIZE = (640, 480)  # the made-up calibration's image size (w, h), px
HELD_EXPOSURE = 150.0  # the exposure a calibration made at a held focus records
RECORD_F_PX, RECORD_B_MM = 750.0, 110.0  # the rig the made-up readings were triangulated with


def held_controls(focus: float) -> PairSettings:
    """Both cameras' controls held by hand: focus at `focus`, exposure at HELD_EXPOSURE."""
    held = CameraSettings("simulated", focus_auto=False, focus=focus, exposure_auto=False,
                          exposure=HELD_EXPOSURE)
    return PairSettings(held, held)


def make_calibration(alpha: float = 0.0, *, rig=None, focus: float | None = None,
                     **updates) -> StereoCalibration:
    """A stereo calibration for a test.

    Without `rig`: a realistic calibration built with OpenCV from made-up, awkward values
    (SIZE, a 9x6 board of 24.5 mm squares, figures with many digits, two pairs' errors), so
    that a file round trip has every digit to keep; `alpha` is stereoRectify's. With `rig` (a
    sources.sim SimRig): the rig's true calibration. `focus` records both cameras held at that
    focus (`held_controls`); `updates` go through `with_updates`.
    """
    if rig is not None:
        calib = rig.true_calibration()
    else:
        calib = _made_up(alpha)
    if focus is not None:
        updates = {"camera_controls": held_controls(focus), **updates}
    return calib.with_updates(**updates) if updates else calib


def _made_up(alpha: float) -> StereoCalibration:
    M1 = np.array([[752.123456789, 0.0, 323.6], [0.0, 748.5, 237.21], [0.0, 0.0, 1.0]])
    M2 = np.array([[745.3, 0.0, 316.1], [0.0, 742.8, 243.4], [0.0, 0.0, 1.0]])
    D1 = np.array([[-0.182, 0.061, 1.1e-3, -6.0e-4, -0.012]])
    D2 = np.array([[-0.214, 0.083, -7.5e-4, 1.25e-3, -0.021]])
    R, _ = cv2.Rodrigues(np.array([0.0061, -0.0118, 0.0042]))
    T = np.array([[-109.99], [0.715], [-0.935]])
    tx = np.array([[0, -T[2, 0], T[1, 0]], [T[2, 0], 0, -T[0, 0]], [-T[1, 0], T[0, 0], 0]])
    E = tx @ R
    F = np.linalg.inv(M2).T @ E @ np.linalg.inv(M1)
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(M1, D1, M2, D2, SIZE, R, T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
    opt1, _ = cv2.getOptimalNewCameraMatrix(M1, D1, SIZE, 1, SIZE)
    return StereoCalibration(SIZE, M1, D1, M2, D2, R, T, E, F, R1, R2, P1, P2, Q,
                             board=BoardSpec(9, 6, 24.5), rms_left=0.1 / 3, rms_right=0.2718281828,
                             rms_stereo=0.31415926535, epipolar_error_px=0.0123456789,
                             per_pair=(PairError("chessboard-1", 0.1, 0.2),
                                       PairError("07", 1 / 7, 2 / 7)),
                             alpha=alpha, optimal_M1=opt1, optimal_M2=None)


def make_record(i: int, valid: bool = True, true_mm: float | None = None) -> MeasurementRecord:
    """The i-th made-up reading (disparity 40 + 7.5 i px, Z = f B / d), or an invalid one."""
    d = 40.0 + 7.5 * i
    z = RECORD_F_PX * RECORD_B_MM / d
    if not valid:
        return MeasurementRecord(
            time=f"2026-11-22T10:00:{i:02d}+00:00", x_px=10.0 + i, y_px=20.0, disparity_px=math.nan,
            X_mm=math.nan, Y_mm=math.nan, Z_mm=math.nan, range_mm=math.nan, valid=False,
            reason="no valid pixels", valid_fraction=0.0, expected_error_mm=math.nan,
            calibration_file="/data/calib.yaml", calibration_rms_px=0.21)
    return MeasurementRecord(
        time=f"2026-11-22T10:00:{i:02d}+00:00", x_px=100.5 + i, y_px=200.25, disparity_px=d,
        X_mm=-12.5 * i, Y_mm=3.25, Z_mm=z, range_mm=math.hypot(z, 12.5 * i), valid=True,
        reason="", valid_fraction=0.875,
        expected_error_mm=z * z / (RECORD_F_PX * RECORD_B_MM) * 0.1,
        method="triangulation" if i % 2 else "cubic", true_mm=true_mm,
        calibration_file="/data/calib.yaml", calibration_rms_px=0.21)


def make_records(n: int = 6) -> list[MeasurementRecord]:
    """`n` valid readings, each with a true distance 3 mm off (alternating sign), then an
    invalid one."""
    out = [make_record(i, true_mm=RECORD_F_PX * RECORD_B_MM / (40.0 + 7.5 * i) + (-1) ** i * 3.0)
           for i in range(n)]
    out.append(make_record(n, valid=False))
    return out


def pole_before_wall(pole_mm: float, wall_mm: float = 2000.0, width_mm: float = 40.0,
                     contrast: float = 1.0):
    """A simulated scene: a vertical pole `width_mm` wide and 3 m tall, centred on the optical
    axis at `pole_mm`, before a textured wall at `wall_mm` (its texture at `contrast`)."""
    from stereo_gui.sources.sim import Scene
    from stereo_gui.sources.sim.scene import SceneObject

    wall = Scene.wall(wall_mm, seed=4).objects[0]
    pole = SceneObject("pole", np.array([0.0, 0.0, pole_mm]), np.array([1.0, 0.0, 0.0]),
                       np.array([0.0, 1.0, 0.0]), width_mm, 3000.0, seed=77, contrast=contrast)
    return Scene((wall, pole))
