"""The Calibration tab's figures a person can check: RMS per camera and stereo, epipolar error,
baseline against the nominal one, rotation between the cameras, each camera's intrinsics, pairs
used, the lens shading; each value with its 1-sigma uncertainty beside it when the calibration has one."""

from __future__ import annotations

import math

from PySide6.QtWidgets import QFormLayout, QGroupBox, QSizePolicy, QWidget

from stereo_gui.core.calibrate import HARTLEY_NOTE
from stereo_gui.core.shading import shading_text
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.uncertainty import corner_sigma_px
from stereo_gui.qt.widgets.helpers import wrapping_label


def format_px(v: float) -> str:
    return f"{v:.3f} px" if v is not None and math.isfinite(v) else "—"


class CalibrationFigures(QGroupBox):
    """The "Result" group: one label per figure (see the module docstring)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Result", parent)
        form = QFormLayout(self)
        # every value wraps: at the default divider position the pane is narrower than the
        # longest line (the epipolar error's, the baseline's, the cameras'), which was cut off
        self.source_label = wrapping_label()
        self.rms_left_label = wrapping_label()
        self.rms_right_label = wrapping_label()
        self.rms_stereo_label = wrapping_label()
        self.epipolar_label = wrapping_label()
        self.baseline_label = wrapping_label()
        self.rotation_label = wrapping_label()
        self.model_label = wrapping_label()
        self.left_label = wrapping_label()
        self.right_label = wrapping_label()
        self.corners_label = wrapping_label()
        self.shading_label = wrapping_label()
        self.shading_label.setToolTip(
            "How much darker each camera's image gets towards its corners, measured on the "
            "white squares of the chessboard pairs. Undone before matching: two cameras see a "
            "point at different distances from their corners, and on a smooth wall that "
            "brightness difference would outweigh the wall's faint texture")
        self.corners_label.setToolTip("How uncertain each camera's lens model is at the image "
                                      "corners (1 sigma, px): large where the board never went")
        for lab in (self.left_label, self.right_label):
            lab.setToolTip("Focal lengths and principal point, px, each ± its 1-sigma uncertainty "
                           "(one standard deviation); 'corners' is how uncertain the lens model "
                           "is at the image corners")
        self.pairs_label = wrapping_label()
        form.addRow("Calibration:", self.source_label)
        form.addRow("RMS left camera:", self.rms_left_label)
        form.addRow("RMS right camera:", self.rms_right_label)
        form.addRow("RMS stereo:", self.rms_stereo_label)
        form.addRow("Epipolar error:", self.epipolar_label)
        form.addRow("Baseline:", self.baseline_label)
        form.addRow("Rotation between cameras:", self.rotation_label)
        form.addRow("Lens model:", self.model_label)
        form.addRow("Left camera:", self.left_label)
        form.addRow("Right camera:", self.right_label)
        form.addRow("Lens at the corners:", self.corners_label)
        form.addRow("Lens shading:", self.shading_label)
        form.addRow("Pairs:", self.pairs_label)
        self.note_label = wrapping_label()
        self.note_label.setStyleSheet("color: #b03a2e; font-weight: bold")
        form.addRow(self.note_label)
        # every row stays readable: the matrices below give way instead
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Minimum)

    def show_none(self) -> None:
        for lab in (self.rms_left_label, self.rms_right_label, self.rms_stereo_label,
                    self.epipolar_label, self.baseline_label, self.rotation_label,
                    self.model_label, self.left_label, self.right_label, self.corners_label,
                    self.shading_label, self.pairs_label):
            lab.setText("—")
        self.source_label.setText("none yet: calibrate, or load a calibration file")
        self.note_label.setText("")

    def show_calibration(self, c: StereoCalibration, source: str, nominal: float, pairs: str) -> None:
        """Show StereoCalibration `c`; `source` says where it came from, `nominal` is the nominal
        baseline (mm), `pairs` how many pairs it used."""
        self.source_label.setText(f"{source}; {c.image_size[0]}x{c.image_size[1]} px, "
                                  f"board {c.board.label() if c.board else 'unknown'}, "
                                  f"method {c.method}, alpha {c.alpha:g}, created {c.created}")
        self.rms_left_label.setText(format_px(c.rms_left))
        self.rms_right_label.setText(format_px(c.rms_right))
        self.rms_stereo_label.setText(format_px(c.rms_stereo) if math.isfinite(c.rms_stereo)
                                      else "— (no stereo solve in Hartley's method)")
        self.epipolar_label.setText(f"{format_px(c.epipolar_error_px)} mean |y left − y right| "
                                    f"of the corners after rectification")
        u = c.uncertainty
        if c.metric:
            b = c.baseline_mm
            diff = b - nominal + 0.0  # + 0.0: no "-0.00"
            if abs(diff) < 0.005:
                diff = 0.0
            pm = f" ± {u.baseline_sigma_mm(c.T):.2f}" if u is not None else ""
            self.baseline_label.setText(
                f"{b:.2f}{pm} mm (nominal {nominal:.1f} mm, difference {diff:+.2f} mm, "
                f"{100 * diff / nominal:+.2f} %)")
            self.note_label.setText("")
        else:
            self.baseline_label.setText("no metric scale (Hartley): distances are not in mm")
            self.note_label.setText(HARTLEY_NOTE)
        pm = f" ± {u.rotation_sigma_deg(c.R):.3f}" if u is not None else ""
        self.rotation_label.setText(f"{c.relative_rotation_deg:.3f}{pm}°")
        self.model_label.setText(_model_text(c))
        self.left_label.setText(camera_text(c, "left"))
        self.right_label.setText(camera_text(c, "right"))
        self.corners_label.setText(corners_text(c))
        self.shading_label.setText(shading_text(c.lens_shading) if c.method == "bouguet"
                                   else "—")
        self.pairs_label.setText(pairs)


_MODEL_NAMES = {"pinhole": "pinhole, 5 coefficients", "rational": "rational, 8 coefficients",
                "fisheye": "fisheye (equidistant), 4 coefficients"}


def _model_text(c: StereoCalibration) -> str:
    text = _MODEL_NAMES.get(c.model, c.model)
    text += "; ± is 1 sigma" if c.uncertainty is not None else "; no uncertainty recorded"
    if c.swapped_inputs:
        text += "; left and right exchanged"
    return text


def camera_text(c: StereoCalibration, side: str) -> str:
    """'fx 752.08±0.35  fy ...  cx ...  cy ... px' of one camera (± 1 sigma)."""
    M = c.M1 if side == "left" else c.M2
    u = c.uncertainty
    parts = []
    for k, (i, j) in zip(("fx", "fy", "cx", "cy"), ((0, 0), (1, 1), (0, 2), (1, 2))):
        pm = f"±{u.sigma(f'{side}.{k}'):.2f}" if u is not None else ""
        parts.append(f"{k} {M[i, j]:.2f}{pm}")
    return "  ".join(parts) + " px"


def corners_text(c: StereoCalibration) -> str:
    """How uncertain the lens models are at the image corners (1 sigma)."""
    if c.uncertainty is None:
        return "—"
    return (f"±{corner_sigma_px(c, 'left'):.2f} px left, ±{corner_sigma_px(c, 'right'):.2f} px "
            "right")
