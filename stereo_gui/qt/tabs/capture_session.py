"""The Capture tab's session and saved pairs: New session…, Open session…, the saved pairs read
in the background for coverage, a saved pair shown with its corners, and Delete pair.

`SessionPairs` is a part of `CaptureTab` (a mixin: it uses the tab's widgets, board and context).
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QMessageBox

from stereo_gui.core.coverage import cell_counts, readiness, regions_filled
from stereo_gui.core.detect import PairDetection, PoseDescriptor, coverage, pair_pose
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.pairs import load_image
from stereo_gui.pipeline.capture import session_scan_job
from stereo_gui.pipeline.images import display_rgb
from stereo_gui.qt.tabs.capture_state import CaptureState
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.widgets.saved_pairs import THUMB_SIZE, SavedPairInfo, pair_thumbnail
from stereo_gui.qt.workers.job_worker import JobWorker


class SessionPairs:
    """Sessions and saved pairs of the Capture tab (see the module docstring)."""

    # ---- sessions --------------------------------------------------------------------------------
    def _choose_new_session(self) -> bool:
        last = self.ctx.settings.last_session
        start = str(Path(last).parent) if last else str(Path.home())
        # a new folder's name may be typed: it is created after asking
        folder = folder_dialog.choose_folder(self, "Folder for the new capture session", start)
        if not folder or not self._confirm_session_folder(Path(folder)):
            return False
        try:
            self.new_session(folder)
        except StereoGuiError as exc:
            self.ctx.report_error(str(exc))
            return False
        return True

    def _confirm_session_folder(self, folder: Path) -> bool:
        """New session…: a folder that already holds files but no session is written into only
        when the technician says so (a manifest must never appear in a folder without a word);
        a folder that holds a session is offered for opening instead."""
        from stereo_gui.files.session import MANIFEST, CaptureSession

        if (folder / MANIFEST).exists():
            answer = QMessageBox.question(
                self, "New session", f"{folder} already holds a capture session. Open it to "
                "go on capturing into it?")
            if answer == QMessageBox.StandardButton.Yes:
                try:
                    self.open_session(folder)
                except StereoGuiError as exc:
                    self.ctx.report_error(str(exc))
            return False
        try:
            entries = [p for p in folder.iterdir() if not p.name.startswith(".")]
        except OSError:
            return True  # (it may not exist yet: creating the session says what goes wrong)
        if not entries:
            return True
        try:
            pairs = len(CaptureSession.open(folder).pairs)
        except StereoGuiError:
            pairs = 0
        what = (f"{len(entries)} file{'s' if len(entries) != 1 else ''} or folder"
                f"{'s' if len(entries) != 1 else ''}")
        kept = (f", among them {pairs} image pair{'s' if pairs != 1 else ''} that the session "
                "will list as saved pairs" if pairs else "")
        answer = QMessageBox.question(
            self, "New session in a folder that is not empty",
            f"{folder} is not empty: it holds {what}{kept}.\n\nStart the capture session "
            f"here anyway? Its manifest ({MANIFEST}) and the new pairs are written into this "
            "folder; nothing in it is changed or removed.",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes

    def _choose_open_session(self) -> None:
        start = self.ctx.settings.last_session or str(Path.home())
        folder = QFileDialog.getExistingDirectory(self, "Open a capture session folder", start)
        if folder:
            try:
                self.open_session(folder)
            except StereoGuiError as exc:
                self.ctx.report_error(str(exc))

    def _camera_names(self) -> tuple[str, str]:
        src = self.ctx.frames.source()
        name = src.name if src is not None else ""
        return (f"{name} left", f"{name} right") if name else ("left", "right")

    def new_session(self, folder: str | Path) -> None:
        """Start a session in `folder` with the current board."""
        from stereo_gui.files.session import CaptureSession

        out = self._last_output
        size = (out.detection.image_size if out is not None else
                tuple(self.ctx.settings.resolution))
        session = CaptureSession.create(folder, self.board, size, self._camera_names())
        self._use_session(session)

    def open_session(self, folder: str | Path) -> None:
        """Open an existing session (or a folder of pairs) to continue, review or delete."""
        from stereo_gui.files.session import CaptureSession

        session = CaptureSession.open(folder)
        self._use_session(session)
        if session.warnings:  # an unreadable session.json, pairs with missing images, ...
            self.ctx.report_error("; ".join(session.warnings))

    def _use_session(self, session) -> None:
        if self._scan is not None:
            self._scan.stop()
            self._scan = None
        self.session = session
        board = session.board
        if board is not None and board != self.board:
            self.set_board(board)
        self.ctx.settings_model.update(last_session=str(session.folder))
        self.session_label.setText(f"Session: {session.folder}")
        if self.state is CaptureState.REVIEW:  # the prompt need not warn that Save asks for one
            self._show_review_prompt()
        self._saved.clear()
        self.shown_pair = None
        self.saved_panel.clear()
        self._update_coverage()
        self.sessionChanged.emit(session)
        self._start_scan()
        self._update_controls()

    def _image_size(self) -> tuple[int, int]:
        res = self.session.resolution if self.session is not None else None
        if res:
            return (int(res[0]), int(res[1]))
        if self._last_output is not None:
            return self._last_output.detection.image_size
        return (640, 480)

    def _start_scan(self) -> None:
        """Detect the board in the session's saved pairs (off the UI thread) for coverage."""
        pairs = list(self.session.pairs)
        if not pairs:
            return
        board = self.board

        job = session_scan_job(pairs, board, (THUMB_SIZE.width() // 2, THUMB_SIZE.height()))
        self.pairs_label.setText(f"Saved pairs: reading {len(pairs)}…")
        worker = JobWorker(job, "reading the session")
        worker.finished_ok.connect(self._scan_done)
        worker.failed.connect(self.ctx.report_error)
        worker.done.connect(lambda: self.ctx.workers.unregister(worker))
        self.ctx.workers.register(worker)
        self._scan = worker
        worker.start()

    def _scan_done(self, results) -> None:
        if self.sender() is not self._scan:
            return
        self._scan = None
        for name, det, small in results:
            icon = pair_thumbnail(*small) if small is not None else None
            info = SavedPairInfo(name, det, icon)
            if name in self._saved:
                continue  # saved while the scan ran
            self._saved[name] = info
        self._refill_list()
        self._update_coverage()
        if self.state is CaptureState.REVIEW:  # what a frozen pair adds is known now
            self._show_review_prompt()

    def scanning(self) -> bool:
        return self._scan is not None

    def _refill_list(self) -> None:
        self.saved_panel.clear()
        order = [p.name for p in self.session.pairs] if self.session is not None else []
        for name in order:
            info = self._saved.get(name) or SavedPairInfo(name, None, None)
            self._add_list_item(info)
        self.saved_panel.update_label()
        self._update_controls()  # Delete pair needs pairs in the list

    def _add_list_item(self, info: SavedPairInfo) -> None:
        excluded = False
        if self.session is not None:
            for p in self.session.pairs:
                if p.name == info.name:
                    excluded = p.excluded
        self.saved_panel.add_item(info, excluded)

    def _saved_poses(self) -> list[PoseDescriptor]:
        """Pose descriptors of the saved pairs in which both cameras saw the board."""
        return [pair_pose(i.detection, self.board) for i in self._saved.values()
                if i.detection is not None and i.detection.found]

    def _kept_detections(self) -> list[PairDetection]:
        return [i.detection for i in self._saved.values()
                if i.detection is not None and i.detection.found]

    def _readiness(self):
        return readiness(self._kept_detections(), self.board, self._image_size())

    def _fills(self, det: PairDetection) -> dict[str, list[str]]:
        """The empty regions of each image that the detection's points would reach."""
        size = det.image_size
        out = {}
        kept = self._kept_detections()
        for side, d, kept_side in (("left", det.left, [k.left.corners for k in kept]),
                                   ("right", det.right, [k.right.corners for k in kept])):
            out[side] = ([] if d is None else
                         regions_filled(d.corners, cell_counts(kept_side, size), size))
        return out

    def _update_coverage(self) -> None:
        self.coverage.set_coverage(coverage(self._saved_poses()))
        self.coverage.set_readiness(self._readiness())

    def saved_names(self) -> list[str]:
        return self.saved_panel.names()

    # ---- saved pairs -----------------------------------------------------------------------------
    def show_saved_pair(self, name: str) -> None:
        """Show a saved pair (with its corners) instead of the live view; it is the pair
        selected in the list (and the one Delete pair deletes)."""
        if self.session is None:
            return
        pair = next((p for p in self.session.pairs if p.name == name), None)
        try:
            if pair is None:
                raise StereoGuiError(f"pair {name} is no longer in the session")
            left, right = load_image(pair.left), load_image(pair.right)
        except StereoGuiError as exc:
            self.ctx.report_error(str(exc))
            if self.shown_pair is not None:  # the list goes back to what is on screen
                self.saved_panel.select(self.shown_pair)
            else:
                self.saved_panel.clear_selection()
            return
        self._move(CaptureState.SAVED)
        self.shown_pair = name
        self._set_processing(False)
        self.frozen = None
        self._frozen_frame = None
        self.view.show_pair(display_rgb(left), display_rgb(right))
        info = self._saved.get(name)
        det = info.detection if info is not None else None
        if det is not None:
            self.view.show_detection(det)
        else:
            for i, side in enumerate(("Left", "Right")):
                self.view.show_corners(i, None, False)
                self.view.set_title(i, side)
        for i, side in enumerate(("Left", "Right")):
            self.view.titles[i].setText(f"{side} — saved pair {name}: "
                                        + self.view.titles[i].text.split(": ", 1)[-1])
        self.prompt.setText(f"Reviewing saved pair {name}. Delete it, or go back to live.")
        self.saved_panel.select(name)
        self._update_controls()

    def _delete_selected(self) -> None:
        """Delete pair: the pair on screen (asks first)."""
        name = self.shown_pair if self.state is CaptureState.SAVED else None
        if name is None:
            return
        answer = QMessageBox.question(  # the files go, not only the list entry
            self, "Delete pair", f"Delete pair {name}? Its two images are removed from "
            f"{self.session.folder if self.session else 'the session folder'}.")
        if answer == QMessageBox.StandardButton.Yes:
            self.delete_pair(name)

    def delete_pair(self, name: str) -> None:
        """Delete a saved pair's files from the session."""
        if self.session is None:
            return
        try:
            self.session.delete_pair(name)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not delete pair {name}: {exc}")
            return
        self._saved.pop(name, None)
        self._refill_list()
        self._update_coverage()
        self.ctx.show_status(f"Deleted pair {name}")
        if self.state is CaptureState.SAVED and self.shown_pair == name:
            self.go_live()
        elif self.shown_pair is not None:
            self.saved_panel.select(self.shown_pair)
