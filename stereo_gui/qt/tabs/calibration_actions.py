"""The Calibration tab's one-click actions besides calibrating: the remedies its warnings offer
(hold k3, exchange the cameras), the session's "cameras swapped" box, and saving and loading a
calibration file.

`CalibrationActions` is owned by `calibration.CalibrationTab` and is handed what it uses: the
calibration model, the session (`calibration_pairs.SessionFolder`), where to report, how to
start a calibration, the Fix k3 box, the Pairs folder typed and the parent of its dialogs. It
makes the swap box, which the tab places.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QCheckBox, QFileDialog, QWidget

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.qt.models.calibration import CalibrationModel, Reporter
from stereo_gui.qt.tabs.calibration_pairs import SessionFolder
from stereo_gui.qt.widgets import folder_dialog


class CalibrationActions(QObject):
    """Remedies, the swap box, save and load (see the module docstring)."""

    def __init__(self, calibration: CalibrationModel, session: SessionFolder, report: Reporter,
                 start_calibration: Callable[[], bool], fix_k3_check: QCheckBox,
                 typed_folder: Callable[[], str], dialogs: QWidget) -> None:
        super().__init__(dialogs)
        self._calibration = calibration
        self._session = session
        self._report = report
        self._start_calibration = start_calibration  # False when it could not start
        self._fix_k3_check = fix_k3_check
        self._typed_folder = typed_folder  # the Pairs folder as typed ("" for none)
        self._dialogs = dialogs  # the parent of the file dialogs
        self.swap_check = QCheckBox("Swap L/R")
        self.swap_check.setToolTip("The cameras are swapped: exchange the left and right images "
                                   "of the session's pairs (the session remembers; the images stay "
                                   "as they were taken)")
        self.swap_check.toggled.connect(self._swap_toggled)

    def apply_remedy(self, proposal: str) -> bool:
        """One click: "fix_k3" holds k3 and recalibrates; "swap" exchanges left and right in the
        session (it remembers) and recalibrates. False if it could not start."""
        if proposal == "fix_k3":
            self._fix_k3_check.setChecked(True)
            return self._start_calibration()
        if proposal == "swap":
            self.swap_check.setChecked(not self.swap_check.isChecked())
            if self._session.swapped() != self.swap_check.isChecked():
                return False  # the session could not record it (the error is shown)
            return self._start_calibration()
        return False

    def show_session_swap(self) -> None:
        """The swap box says what the session records (off, and disabled, without one)."""
        swapped = self._session.swapped() if self._typed_folder().strip() else None
        self.swap_check.blockSignals(True)
        self.swap_check.setChecked(bool(swapped))
        self.swap_check.blockSignals(False)
        self.swap_check.setEnabled(swapped is not None)

    def _swap_toggled(self, on: bool) -> None:
        try:
            session = self._session.open()
            if bool(session.swapped) != on:
                session.set_swapped(on)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not record the swap in the session: {exc}")
            self.show_session_swap()
            return
        self._report.show_status(
            "The session now exchanges left and right: press Recalibrate" if on
            else "The session takes left and right as they are: press Recalibrate")

    # ---- files ---------------------------------------------------------------------------------
    def choose_save(self) -> None:
        """Save calibration…: ask for a file and save the calibration in use there."""
        if self._calibration.calibration is None:
            return
        start = str(self._calibration.path
                    or (Path(self._typed_folder() or Path.home()) / "calibration.yaml"))
        path, _ = folder_dialog.save_file_name(self._dialogs, "Save calibration", start,
                                              "OpenCV YAML (*.yaml *.yml)")
        if path:
            self.save_calibration(path)

    def save_calibration(self, path: str | Path) -> bool:
        """Save the calibration in use to `path`; False (said why) when it was not."""
        calib = self._calibration.calibration
        if calib is None:  # (the window's Save says the same)
            self._report.report_error(
                "There is no calibration to save: calibrate or open one first.")
            return False
        return self._calibration.save_file(calib, path)

    def choose_load(self) -> None:
        """Load calibration…: ask for a file and use the calibration it holds."""
        cp = self._calibration.path
        start = str(cp.parent) if cp else str(Path.home())
        path, _ = QFileDialog.getOpenFileName(
            self._dialogs, "Load calibration (ours, OpenCV's, ROS's or Middlebury's)", start,
            "Calibration files (*.yaml *.yml *.xml *.txt);;All files (*)")
        if path:
            self.load_calibration(path)

    def load_calibration(self, path: str | Path) -> bool:
        return self._calibration.open_file(path)
