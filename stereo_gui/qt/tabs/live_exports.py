"""The Live tab's snapshot and depth exports of the frame shown, written off the UI thread (jobs
on the context's job runner), every file atomically."""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog, QMenu, QToolButton, QWidget

from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.core.jobs import JobState, JobTicket
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.util import how_many
from stereo_gui.files import depth_export as dx
from stereo_gui.files.atomic import write_bytes_atomic
from stereo_gui.pipeline.live import LiveOutput
from stereo_gui.qt.widgets import folder_dialog

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

# depth exports of the frame shown: key -> (menu text, file suffix, what the file holds)
EXPORTS: dict[str, tuple[str, str, str]] = {
    "disparity_png": ("Disparity, 16-bit PNG (x16)…", "-disparity-x16.png",
                      "disparity as 16-bit PNG (OpenCV's x16 fixed point, 0 = invalid)"),
    "disparity_npy": ("Disparity, float32 .npy…", "-disparity.npy",
                      "disparity in px as float32 .npy (NaN = invalid)"),
    "depth_png": ("Depth in mm, 16-bit PNG…", "-depth-mm.png",
                  "depth in mm as 16-bit PNG (0 = invalid)"),
    "ply": ("Point cloud, coloured PLY…", "-cloud.ply", "coloured point cloud (binary PLY, mm)"),
}


# what an export wrote: (kind, file, a note such as the number of points)
Written = tuple[str, Path, str]


def _stamp() -> str:
    return _dt.datetime.now().strftime("%Y%m%d-%H%M%S")


class LiveExports(QObject):
    """Snapshot and exports of the frame `current()` returns (a LiveOutput, or None before the
    first frame); `views()` lists the views shown, which a snapshot saves. File dialogs open
    over `parent`; results and failures reach the user through the context."""

    def __init__(self, ctx: AppContext, parent: QWidget,
                 current: Callable[[], LiveOutput | None],
                 views: Callable[[], list[str]]) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._parent = parent
        self._current = current
        self._views = views
        self._exports: dict[int, str] = {}  # job id -> what is being exported
        self._snapshots: set[int] = set()
        # job id -> (its ticket, what it writes "the export of the ... to PATH", for messages)
        self._runs: dict[int, tuple[JobTicket, str]] = {}
        self.last_export: list[Path] = []  # files written by the last finished export
        ctx.jobs.finished.connect(self._job_finished)
        ctx.jobs.failed.connect(self._job_failed)

    def make_export_button(self) -> QToolButton:
        """The "Export frame" tool button with its menu of EXPORTS."""
        button = QToolButton()
        button.setText("Export frame ▾")
        # the arrow is in the text: the style's own indicator overlaps it
        button.setStyleSheet("QToolButton::menu-indicator { image: none; }")
        button.setToolTip("Write the depth of the frame shown for other tools")
        button.setPopupMode(QToolButton.ToolButtonPopupMode.InstantPopup)
        export_menu = QMenu(button)
        for key, (text, _suffix, _what) in EXPORTS.items():
            export_menu.addAction(text, partial(self._export_clicked, key))
        export_menu.addSeparator()
        export_menu.addAction("All four into a folder…", self._export_all_clicked)
        button.setMenu(export_menu)
        return button

    def _submit(self, write: Callable[[], object], where: str) -> int:
        """Run `write()` on the job thread, followed for closing (`unfinished_work`)."""
        ticket = self.ctx.jobs.submit(lambda _control: write())
        self._runs[ticket.id] = (ticket, where)
        return ticket.id

    # ---- closing -------------------------------------------------------------------------------
    def unfinished_work(self) -> list[str]:
        """What closing now would cut short: exports and snapshots not written yet."""
        return [where for ticket, where in self._runs.values() if not ticket.ended]

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        """Drop the exports not started yet and wait at most `timeout_ms` for the one being
        written (a frame's files take well under a second); says what became of each."""
        deadline = time.monotonic() + timeout_ms / 1000.0
        said = []
        for job_id, (ticket, where) in list(self._runs.items()):
            if ticket.ended:
                continue
            what = f"{where[0].upper()}{where[1:]}"
            if self.ctx.jobs.cancel(job_id):
                self._runs.pop(job_id, None)
                self._exports.pop(job_id, None)
                self._snapshots.discard(job_id)
                said.append(f"{what} was cancelled: nothing was written.")
            elif ticket.wait(deadline - time.monotonic()):
                written = ticket.state is JobState.FINISHED
                said.append(f"{what} {'was written' if written else 'failed'}.")
            else:
                said.append(f"{what} was still being written when the window closed: each file "
                            "is written whole or not at all.")
        return said

    def _job_finished(self, job_id: int, result: object) -> None:
        self._runs.pop(job_id, None)
        if not isinstance(result, list):
            return  # another's job (a snapshot's and an export's results are lists)
        if not self._snapshot_done(job_id, result):
            self._export_done(job_id, result)

    def _job_failed(self, job_id: int, message: str) -> None:
        self._runs.pop(job_id, None)
        if job_id in self._exports:
            what = self._exports.pop(job_id)
            self.ctx.report_error(f"Export of the {what} failed: {message}")
        elif job_id in self._snapshots:
            self._snapshots.discard(job_id)
            self.ctx.report_error(f"Snapshot not saved: {message}")

    def snapshot_clicked(self) -> None:
        start = self.ctx.settings.last_export_dir or str(Path.home())
        folder = QFileDialog.getExistingDirectory(self._parent, "Save snapshot into", start)
        if folder:
            self.snapshot(folder)
            self.ctx.settings_model.update(last_export_dir=folder)

    def snapshot(self, folder: str | Path) -> int | None:
        """Save the views shown as PNG files in `folder` (atomically, off the UI thread).

        Files are named snapshot-<time>-<view>.png. Returns the job id.
        """
        out = self._current()
        if out is None:
            self.ctx.report_error("No frame to save yet.")
            return None
        folder = Path(folder)
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
        images = {k: out.images[k] for k in self._views() if k in out.images}

        def write() -> list[Path]:
            written: list[Path] = []
            for key, img in images.items():
                bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
                ok, buf = cv2.imencode(".png", bgr)
                if not ok:
                    raise StereoGuiError(f"could not encode the {key} view as PNG")
                written.append(write_bytes_atomic(folder / f"snapshot-{stamp}-{key}.png",
                                                  buf.tobytes()))
            return written

        job = self._submit(write, f"the snapshot into {folder}")
        self._snapshots.add(job)
        return job

    def _snapshot_done(self, job_id: int, paths: list[Path]) -> bool:
        if job_id in self._snapshots:
            self._snapshots.discard(job_id)
            self.ctx.show_status(f"Snapshot saved: {how_many(len(paths), 'file')} in {Path(paths[0]).parent}"
                                 if paths else "Snapshot: no views shown")
            return True
        return False

    # ---- depth exports of the frame shown ----------------------------------------------------
    def _export_start_dir(self) -> str:
        return self.ctx.settings.last_export_dir or str(Path.home())

    def _export_clicked(self, kind: str) -> None:
        if self._current() is None:
            self.ctx.report_error("No frame to export yet.")
            return
        text, suffix, _what = EXPORTS[kind]
        start = str(Path(self._export_start_dir()) / f"frame-{_stamp()}{suffix}")
        ext = Path(suffix).suffix
        path, _ = folder_dialog.save_file_name(self._parent, text.rstrip("…"), start,
                                              f"{ext[1:].upper()} files (*{ext})")
        if path:
            if not path.lower().endswith(ext):
                path += ext
            self.export_frame(path, kinds=(kind,))
            self.ctx.settings_model.update(last_export_dir=str(Path(path).parent))

    def _export_all_clicked(self) -> None:
        if self._current() is None:
            self.ctx.report_error("No frame to export yet.")
            return
        folder = QFileDialog.getExistingDirectory(self._parent, "Export the frame's depth into",
                                                  self._export_start_dir())
        if folder:
            self.export_frame(folder)
            self.ctx.settings_model.update(last_export_dir=folder)

    def export_frame(self, target: str | Path, kinds: Iterable[str] = tuple(EXPORTS)
                     ) -> int | None:
        """Write the shown frame's depth off the UI thread; returns the job id.

        With one kind, `target` is the file; with several, a folder that receives
        frame-<time><suffix> for each (see EXPORTS). Every file is written atomically.
        """
        out = self._current()
        if out is None:
            self.ctx.report_error("No frame to export yet.")
            return None
        chosen = tuple(kinds)
        target = Path(target)
        if len(chosen) == 1:
            paths = {chosen[0]: target}
        else:
            stamp = _stamp()
            paths = {k: target / f"frame-{stamp}{EXPORTS[k][1]}" for k in chosen}
        result = out.result
        disparity = result.final_px
        calib = result.calibration  # the one the frame was rectified with (scaled if it was)

        def calibrated() -> StereoCalibration:
            if calib is None:  # (the Live tab shows frames only with a calibration)
                raise InputError("depth in millimetres needs the frame's calibration")
            return calib

        def write() -> list[Written]:
            done: list[Written] = []
            for kind, path in paths.items():
                if kind == "disparity_png":
                    dx.write_disparity_png16(path, disparity)
                    note = ""
                elif kind == "disparity_npy":
                    dx.write_disparity_npy(path, disparity)
                    note = ""
                elif kind == "depth_png":
                    dx.write_depth_png16(path, disparity, calibrated())
                    note = ""
                else:
                    n = dx.write_ply(path, disparity, result.rectified_left, calibrated())
                    note = how_many(n, "point")
                done.append((kind, Path(path), note))
            return done

        what = "frame's depth" if len(chosen) > 1 else EXPORTS[chosen[0]][2]
        job = self._submit(write, f"the export of the {what} to {target}")
        self._exports[job] = what
        return job

    def _export_done(self, job_id: int, done: list[Written]) -> bool:
        if job_id not in self._exports:
            return False
        del self._exports[job_id]
        self.last_export = [p for _k, p, _n in done]
        if len(done) == 1:
            kind, path, note = done[0]
            extra = f", {note}" if note else ""
            self.ctx.show_status(f"Exported the {EXPORTS[kind][2]} to {path}{extra}")
        else:
            self.ctx.show_status(f"Exported the frame's depth: {how_many(len(done), 'file')} in "
                                 f"{done[0][1].parent} (disparity PNG and .npy, depth PNG, PLY)")
        return True

