"""The Live tab's calibration health: the figure (median vertical disparity of feature matches
in the rectified pair, every two seconds, computed off the UI thread by pipeline.health), a
warning when the cameras moved since calibration, "Refine rectification from the scene" (a job
off the UI thread: core.health.refine_rotation on the frame shown, saved as a new calibration
that records where it came from), and on the simulated rig a control that turns the right
camera by a small angle, to try it out."""

from __future__ import annotations

import logging
from collections.abc import Callable, Generator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFrame,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.health import CalibrationHealth, Refinement, refine_rotation
from stereo_gui.core.jobs import JobControl, Progress
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.live import LiveOutput
from stereo_gui.qt.source_capabilities import simulated_rig
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.workers.job_worker import JobWorker
from stereo_gui.sources.base import StereoFrame
from stereo_gui.sources.sim.rig import SimRig

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

_OK = "color: #1e7b34"
_WARN = "background: #fde2c8; color: #7a3300; padding: 2px 6px; font-weight: bold"


def refine_job(calib: StereoCalibration, left: np.ndarray, right: np.ndarray, source: str
               ) -> Callable[[JobControl], Generator[Progress, None, Refinement]]:
    """A JobWorker job: refine the rotation between the cameras from one scene pair."""

    def job(control: JobControl) -> Generator[Progress, None, Refinement]:
        yield Progress(0, 1, "matching features in the scene")
        result = refine_rotation(calib, left, right, source)
        yield Progress(1, 1, "done")
        return result

    return job


class CalibrationHealthPanel(QFrame):
    """See the module docstring. `refined(Refinement)` after a refinement has been applied."""

    refined = Signal(Refinement)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.health: CalibrationHealth | None = None
        self._frame: StereoFrame | None = None
        self._worker: JobWorker | None = None
        self.save_to: str | Path | None = None  # where the next refinement goes (None: ask)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        row = QHBoxLayout()
        self.label = QLabel("Calibration health: waiting for the first check…")
        self.label.setWordWrap(True)
        self.label.setToolTip("The median vertical disparity of feature matches in the rectified "
                              "pair, checked every two seconds: a few tenths of a pixel right "
                              "after calibration, more when a camera has turned since")
        row.addWidget(self.label, 1)
        self.refine_button = QPushButton("Refine rectification from the scene")
        self.refine_button.setToolTip("Re-estimate the rotation between the cameras from feature "
                                      "matches in the frame shown, keeping both cameras' intrinsics "
                                      "and the baseline (distances stay metric); saved as a new "
                                      "calibration that records where it came from")
        self.refine_button.clicked.connect(self.refine)
        row.addWidget(self.refine_button)
        lay.addLayout(row)
        self.sim_row = QWidget()
        sim = QHBoxLayout(self.sim_row)
        sim.setContentsMargins(0, 0, 0, 0)
        sim.addWidget(QLabel("Simulated rig: turn the right camera by"))
        self.angle_spin = QDoubleSpinBox()
        self.angle_spin.setRange(-5.0, 5.0)
        self.angle_spin.setDecimals(2)
        self.angle_spin.setSingleStep(0.1)
        self.angle_spin.setValue(0.3)
        self.angle_spin.setSuffix("°")
        sim.addWidget(self.angle_spin)
        self.axis_combo = QComboBox()
        for text, key in (("tilt (up/down)", "tilt"), ("roll", "roll"), ("pan (left/right)", "pan")):
            self.axis_combo.addItem(text, key)
        sim.addWidget(self.axis_combo)
        self.turn_button = QPushButton("Turn")
        self.turn_button.clicked.connect(self.turn_sim_camera)
        self.reset_button = QPushButton("Put back")
        self.reset_button.clicked.connect(self.reset_sim_camera)
        sim.addWidget(self.turn_button)
        sim.addWidget(self.reset_button)
        self.turned_label = QLabel("")
        sim.addWidget(self.turned_label)
        sim.addStretch(1)
        lay.addWidget(self.sim_row)
        ctx.calibration_model.changed.connect(lambda _c: self._calibration_changed())
        ctx.frames.sourceChanged.connect(lambda _name: self._update_sim_row())
        self._update_sim_row()
        self._update_buttons()

    # ---- the figure ------------------------------------------------------------------------
    def show_output(self, out: LiveOutput, frame: StereoFrame | None) -> None:
        """Called with every frame the Live tab draws (UI thread: text only)."""
        self._frame = frame
        h = out.health
        if h is not None and h is not self.health:
            self.health = h
            self.label.setText(h.text())
            self.label.setStyleSheet(_WARN if (h.drifted or h.swapped) else _OK)
        self._update_buttons()

    def _calibration_changed(self) -> None:
        self.health = None
        self.label.setStyleSheet("")
        self.label.setText("Calibration health: waiting for the first check…")
        self._update_buttons()

    def _update_buttons(self) -> None:
        calib = self.ctx.calibration
        self.refine_button.setEnabled(self._worker is None and self._frame is not None
                                      and calib is not None and calib.metric)

    # ---- refinement ------------------------------------------------------------------------
    def refine(self) -> bool:
        """Start refining from the frame shown; False if it cannot start."""
        calib, frame = self.ctx.calibration, self._frame
        if self._worker is not None or calib is None or frame is None:
            return False
        src = self.ctx.frames.source()
        name = src.name if src is not None else ""
        job = refine_job(calib, frame.left.copy(), frame.right.copy(),
                         f"frame {frame.index}" + (f" of {name}" if name else ""))
        w = JobWorker(job, "refine rectification")
        w.finished_ok.connect(self._refined)
        w.failed.connect(self.ctx.report_error)
        w.done.connect(self._worker_done)
        self.ctx.workers.register(w)
        self._worker = w
        self.refine_button.setText("Refining…")
        self._update_buttons()
        w.start()
        return True

    def _worker_done(self) -> None:
        w, self._worker = self._worker, None
        if w is not None:
            self.ctx.workers.unregister(w)
        self.refine_button.setText("Refine rectification from the scene")
        self._update_buttons()

    def _refined(self, ref: Refinement) -> None:
        path = self.save_to
        if path is None:
            cp = self.ctx.calibration_path
            start = (cp.with_name(cp.stem + "-refined.yaml") if cp is not None
                     else Path.home() / "calibration-refined.yaml")
            path, _ = folder_dialog.save_file_name(self, "Save the refined calibration",
                                                  str(start), "OpenCV YAML (*.yaml *.yml)")
        if path:
            if not self.ctx.calibration_model.save_file(ref.calibration, path):
                return
        else:  # not saved: used until something else is loaded
            self.ctx.calibration_model.set(ref.calibration, None,
                                           note="refined from the scene, not saved")
        self.ctx.show_status(
            f"Refined from {ref.matches} matches: vertical disparity {ref.before_px:.2f} px -> "
            f"{ref.after_px:.2f} px; intrinsics and baseline kept"
            + (f"; saved as {path}" if path else ""))
        self.refined.emit(ref)

    def is_refining(self) -> bool:
        return self._worker is not None

    # ---- the simulated rig -----------------------------------------------------------------
    def _sim_rig(self) -> SimRig | None:
        return simulated_rig(self.ctx.frames.source())

    def _update_sim_row(self) -> None:
        rig = self._sim_rig()
        self.sim_row.setVisible(rig is not None)
        if rig is not None:
            t = rig.turned_deg
            self.turned_label.setText(f"turned {t:.2f}° from where it was built" if t else "")

    def turn_sim_camera(self) -> None:
        rig = self._sim_rig()
        if rig is not None:
            rig.turn_right_camera(self.angle_spin.value(), self.axis_combo.currentData())
            self._update_sim_row()

    def reset_sim_camera(self) -> None:
        rig = self._sim_rig()
        if rig is not None:
            rig.reset_turn()
            self._update_sim_row()

    def shutdown(self) -> None:
        if self._worker is not None:
            self._worker.stop(2000)
