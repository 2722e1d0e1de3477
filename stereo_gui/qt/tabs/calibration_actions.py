"""The Calibration tab's one-click actions besides calibrating: the remedies its warnings offer
(hold k3, exchange the cameras), the session's "cameras swapped" box, and saving and loading a
calibration file.

`CalibrationActions` is a part of `calibration.CalibrationTab` (a mixin: it uses the tab's
widgets, session and context).
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.qt.widgets import folder_dialog


class CalibrationActions:
    """Remedies, the swap box, save and load (see the module docstring)."""

    def apply_remedy(self, proposal: str) -> bool:
        """One click: "fix_k3" holds k3 and recalibrates; "swap" exchanges left and right in the
        session (it remembers) and recalibrates. False if it could not start."""
        if proposal == "fix_k3":
            self.fix_k3_check.setChecked(True)
            return self.start_calibration()
        if proposal == "swap":
            self.swap_check.setChecked(not self.swap_check.isChecked())
            if self._session_swapped() != self.swap_check.isChecked():
                return False  # the session could not record it (the error is shown)
            return self.start_calibration()
        return False

    def _session_swapped(self) -> bool | None:
        try:
            return bool(self._session().swapped)
        except (StereoGuiError, OSError):
            return None

    def _show_session_swap(self) -> None:
        swapped = self._session_swapped() if self.folder_edit.text().strip() else None
        self.swap_check.blockSignals(True)
        self.swap_check.setChecked(bool(swapped))
        self.swap_check.blockSignals(False)
        self.swap_check.setEnabled(swapped is not None)

    def _swap_toggled(self, on: bool) -> None:
        try:
            session = self._session()
            if bool(session.swapped) != on:
                session.set_swapped(on)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not record the swap in the session: {exc}")
            self._show_session_swap()
            return
        self.ctx.show_status("The session now exchanges left and right: press Recalibrate" if on
                             else "The session takes left and right as they are: press Recalibrate")

    # ---- files ---------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        if self.calibration is None:
            return
        start = str(self.ctx.calibration_path or (Path(self.folder_edit.text() or Path.home())
                                                   / "calibration.yaml"))
        path, _ = folder_dialog.save_file_name(self, "Save calibration", start,
                                              "OpenCV YAML (*.yaml *.yml)")
        if path:
            self.save_calibration(path)

    def save_calibration(self, path: str | Path) -> bool:
        return self.ctx.calibration_model.save_file(self.calibration, path)

    def _choose_load(self) -> None:
        cp = self.ctx.calibration_path
        start = str(cp.parent) if cp else str(Path.home())
        path, _ = QFileDialog.getOpenFileName(
            self, "Load calibration (ours, OpenCV's, ROS's or Middlebury's)", start,
            "Calibration files (*.yaml *.yml *.xml *.txt);;All files (*)")
        if path:
            self.load_calibration(path)

    def load_calibration(self, path: str | Path) -> bool:
        return self.ctx.calibration_model.open_file(path)
