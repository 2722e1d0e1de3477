"""The Live tab's Record button: starts and stops recording the source's raw frames (the
context's Recorder) and shows the running time; its menu records into a chosen folder or
changes the folder new recordings go into."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QMenu, QToolButton, QWidget

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.workers.recorder import (
    RecordingResult,
    describe_result,
    format_elapsed,
    new_recording_folder,
    recordings_dir,
)

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

RECORD_TEXT = "● Record"


class RecordButton(QToolButton):
    """Record / Stop for `ctx.recorder`; checked while recording."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.setText(RECORD_TEXT)
        self.setCheckable(True)
        self.setPopupMode(QToolButton.ToolButtonPopupMode.MenuButtonPopup)
        self.setStyleSheet(
            "QToolButton:checked { background: #c62828; color: white; font-weight: bold; }")
        # wide enough for the running time, so the toolbar does not jump (the frame count is in
        # the status bar and the tooltip)
        self.setMinimumWidth(self.fontMetrics().horizontalAdvance("■ Stop 00:00") + 40)
        self.clicked.connect(self._record_clicked)
        record_menu = QMenu(self)
        record_menu.addAction("Record into a folder…", self._record_into_clicked)
        record_menu.addAction("Change the recordings folder…", self._choose_recordings_dir)
        self.setMenu(record_menu)
        self._update_record_tooltip()
        self._record_timer = QTimer(self)
        self._record_timer.setInterval(250)
        self._record_timer.timeout.connect(self._update_record_button)
        ctx.recorder.started.connect(self._recording_started)
        ctx.recorder.stopped.connect(self._recording_stopped)
        base = recordings_dir(ctx.settings)
        if base.exists() and not base.is_dir():  # said now, not only when a recording fails
            ctx.report_error(f"The recordings folder {base} is a file, not a folder: choose "
                             "another with Record ▾ > Change the recordings folder…")

    def _update_record_tooltip(self) -> None:
        base = recordings_dir(self.ctx.settings)
        self.setToolTip(
            f"Record the raw stereo frames with their timestamps into a new folder in {base}; "
            "the arrow offers another folder")

    def _record_clicked(self, checked: bool) -> None:
        if checked:
            self.start_recording()
        else:
            self.ctx.recorder.stop_recording()
        self._sync_record_button()

    def _record_into_clicked(self) -> None:
        if self.ctx.recorder.is_recording:
            return
        folder = folder_dialog.choose_folder(
            self, "Record into (an empty or new folder)", str(recordings_dir(self.ctx.settings)))
        if folder:
            self.start_recording(folder)

    def _choose_recordings_dir(self) -> None:
        folder = folder_dialog.choose_folder(self, "Folder for new recordings",
                                             str(recordings_dir(self.ctx.settings)))
        if folder:
            self.ctx.settings_model.update(recordings_dir=folder)
            self._update_record_tooltip()

    def start_recording(self, folder: str | Path | None = None) -> Path | None:
        """Record the source's raw frames into `folder` (new or empty), or into a new folder in
        the recordings folder; returns the folder, or None (with a message) if it cannot."""
        src = self.ctx.frames.source()
        if src is None:
            self.ctx.report_error("Nothing to record: no source is open.")
            self._sync_record_button()
            return None
        if folder is None:
            folder = new_recording_folder(recordings_dir(self.ctx.settings))
        try:
            path = self.ctx.recorder.start(folder, source_name=src.name, fps=src.nominal_fps)
        except StereoGuiError as exc:
            self.ctx.report_error(f"Cannot start recording: {exc}")
            self._sync_record_button()
            return None
        return path

    def stop_recording(self) -> int | None:
        return self.ctx.recorder.stop_recording()

    def _sync_record_button(self) -> None:
        rec = self.ctx.recorder
        self.blockSignals(True)
        self.setChecked(rec.is_recording)
        self.blockSignals(False)
        self._update_record_button()

    def _update_record_button(self) -> None:
        rec = self.ctx.recorder
        if rec.is_recording:
            self.setText(f"■ Stop {format_elapsed(rec.elapsed_s)}")
            self.setToolTip(f"Recording into {rec.folder}: {rec.frames_written} "
                                          "frames written; click to stop")
        else:
            self.setText(RECORD_TEXT)

    def _recording_started(self, folder: str) -> None:
        self._record_timer.start()
        self._sync_record_button()
        self.ctx.show_status(f"Recording into {folder}")

    def _recording_stopped(self, result: RecordingResult) -> None:
        self._record_timer.stop()
        self._sync_record_button()
        self._update_record_tooltip()
        text = describe_result(result)
        if result.error:
            self.ctx.report_error(text)
        else:
            self.ctx.show_status(text)
