"""The Capture tab's session and saved pairs: New session…, Open session…, the saved pairs read
in the background for coverage, a saved pair's images, and Delete pair.

`SessionPairs` is owned by `capture.CaptureTab` and is handed what it uses: the settings, where
to report, the worker registry, the saved-pairs panel it fills, the board in use (and how to
adopt the board a session records), the size of the frames seen and the source's name. It owns
the session and what is known of its pairs; the tab owns what is on screen (its state, the view,
the prompt) and follows `sessionChanged` and `pairsChanged`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.coverage import Readiness, cell_counts, readiness, regions_filled
from stereo_gui.core.detect import PairDetection, PoseDescriptor, coverage, pair_pose
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.pairs import load_image
from stereo_gui.files.session import MANIFEST, CaptureSession
from stereo_gui.pipeline.capture import ScannedPair, session_scan_job
from stereo_gui.qt.models.calibration import Reporter
from stereo_gui.qt.models.settings import SettingsModel
from stereo_gui.qt.models.workers import WorkerRegistry
from stereo_gui.qt.widgets import folder_dialog
from stereo_gui.qt.widgets.saved_pairs import (
    THUMB_SIZE,
    SavedPairInfo,
    SavedPairsPanel,
    pair_thumbnail,
)
from stereo_gui.qt.workers.job_worker import JobWorker


class SessionPairs(QObject):
    """The capture session open and its saved pairs (see the module docstring)."""

    sessionChanged = Signal(CaptureSession)  # the session now open
    pairsChanged = Signal()  # the list of saved pairs was filled again (read, scanned, deleted)

    def __init__(self, settings: SettingsModel, report: Reporter, workers: WorkerRegistry,
                 panel: SavedPairsPanel, board: Callable[[], BoardSpec],
                 adopt_board: Callable[[BoardSpec], None],
                 seen_size: Callable[[], tuple[int, int] | None],
                 source_name: Callable[[], str], dialogs: QWidget) -> None:
        super().__init__(dialogs)
        self._settings = settings
        self._report = report
        self._workers = workers
        self._panel = panel
        self._board = board  # the board in use now
        self._adopt_board = adopt_board  # use the board a session opened records
        self._seen_size = seen_size  # (width, height) px of the last live frame, None before
        self._source_name = source_name
        self._dialogs = dialogs  # the parent of the dialogs
        self._session: CaptureSession | None = None
        self._saved: dict[str, SavedPairInfo] = {}
        self._scan: JobWorker | None = None

    @property
    def session(self) -> CaptureSession | None:
        return self._session

    # ---- choosing a session ----------------------------------------------------------------------
    def choose_new(self) -> bool:
        """New session…: ask for a folder and start a session there; False if none was."""
        last = self._settings.current.last_session
        start = str(Path(last).parent) if last else str(Path.home())
        # a new folder's name may be typed: it is created after asking
        folder = folder_dialog.choose_folder(self._dialogs, "Folder for the new capture session",
                                             start)
        if not folder or not self._confirm_session_folder(Path(folder)):
            return False
        try:
            self.new_session(folder)
        except StereoGuiError as exc:
            self._report.report_error(str(exc))
            return False
        return True

    def _confirm_session_folder(self, folder: Path) -> bool:
        """New session…: a folder that already holds files but no session is written into only
        when the technician says so (a manifest must never appear in a folder without a word);
        a folder that holds a session is offered for opening instead."""
        if (folder / MANIFEST).exists():
            answer = QMessageBox.question(
                self._dialogs, "New session", f"{folder} already holds a capture session. Open "
                "it to go on capturing into it?")
            if answer == QMessageBox.StandardButton.Yes:
                self._open_reporting(folder)
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
            self._dialogs, "New session in a folder that is not empty",
            f"{folder} is not empty: it holds {what}{kept}.\n\nStart the capture session "
            f"here anyway? Its manifest ({MANIFEST}) and the new pairs are written into this "
            "folder; nothing in it is changed or removed.",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.No)
        return answer == QMessageBox.StandardButton.Yes

    def choose_open(self) -> None:
        """Open session…: ask for a session folder and open it."""
        start = self._settings.current.last_session or str(Path.home())
        folder = QFileDialog.getExistingDirectory(self._dialogs, "Open a capture session folder",
                                                  start)
        if folder:
            self._open_reporting(folder)

    def _open_reporting(self, folder: str | Path) -> None:
        try:
            self.open_session(folder)
        except StereoGuiError as exc:
            self._report.report_error(str(exc))

    def _camera_names(self) -> tuple[str, str]:
        name = self._source_name()
        return (f"{name} left", f"{name} right") if name else ("left", "right")

    def new_session(self, folder: str | Path) -> None:
        """Start a session in `folder` with the current board."""
        w, h = self._settings.current.resolution
        size = self._seen_size() or (w, h)
        session = CaptureSession.create(folder, self._board(), size, self._camera_names())
        self._use_session(session)

    def open_session(self, folder: str | Path) -> None:
        """Open an existing session (or a folder of pairs) to continue, review or delete."""
        session = CaptureSession.open(folder)
        self._use_session(session)
        if session.warnings:  # an unreadable session.json, pairs with missing images, ...
            self._report.report_error("; ".join(session.warnings))

    def _use_session(self, session: CaptureSession) -> None:
        if self._scan is not None:  # (of the session before)
            self._scan.stop()
            self._scan = None
        self._session = session
        board = session.board
        if board is not None and board != self._board():
            self._adopt_board(board)
        self._settings.update(last_session=str(session.folder))
        self._saved.clear()
        self._panel.clear()
        self._update_coverage()
        self.sessionChanged.emit(session)
        self._start_scan(session)

    def reload(self) -> bool:
        """Read the session again (the Calibration tab may have excluded pairs meanwhile);
        False when there is none, it is still being scanned or it cannot be read (said)."""
        if self._session is None or self._scan is not None:
            return False
        try:
            self._session = CaptureSession.open(self._session.folder)
        except StereoGuiError as exc:
            self._report.report_error(str(exc))
            return False
        self._refill_list()
        return True

    def record_board(self, board: BoardSpec) -> None:
        """The session records the target its pairs show (a failure is said)."""
        if self._session is not None and self._session.board != board:
            try:
                self._session.set_board(board)
            except (StereoGuiError, OSError) as exc:
                self._report.report_error(f"could not record the board in the session: {exc}")

    # ---- reading the saved pairs -----------------------------------------------------------------
    def _image_size(self) -> tuple[int, int]:
        res = self._session.resolution if self._session is not None else None
        if res:
            return (int(res[0]), int(res[1]))
        return self._seen_size() or (640, 480)

    def _start_scan(self, session: CaptureSession) -> None:
        """Detect the board in the session's saved pairs (off the UI thread) for coverage."""
        pairs = list(session.pairs)
        if not pairs:
            return
        job = session_scan_job(pairs, self._board(),
                               (THUMB_SIZE.width() // 2, THUMB_SIZE.height()))
        self._panel.pairs_label.setText(f"Saved pairs: reading {len(pairs)}…")
        worker = JobWorker(job, "reading the session")
        worker.finished_ok.connect(self._scan_done)
        worker.failed.connect(self._report.report_error)
        worker.done.connect(lambda: self._workers.unregister(worker))
        self._workers.register(worker)
        self._scan = worker
        worker.start()

    def _scan_done(self, results: list[ScannedPair]) -> None:
        if self.sender() is not self._scan:
            return
        self._scan = None
        for name, det, small in results:
            if name in self._saved:
                continue  # saved while the scan ran
            icon = pair_thumbnail(*small) if small is not None else None
            self._saved[name] = SavedPairInfo(name, det, icon)
        self._refill_list()
        self._update_coverage()

    def scanning(self) -> bool:
        return self._scan is not None

    def cancel_scan(self) -> None:
        """Stop reading the saved pairs (the worker registry joins the thread)."""
        if self._scan is not None:
            self._scan.cancel()
            self._scan = None

    def _refill_list(self) -> None:
        self._panel.clear()
        order = [p.name for p in self._session.pairs] if self._session is not None else []
        for name in order:
            self._add_list_item(self._saved.get(name) or SavedPairInfo(name, None, None))
        self._panel.update_label()
        self.pairsChanged.emit()

    def _add_list_item(self, info: SavedPairInfo) -> None:
        excluded = False
        if self._session is not None:
            for p in self._session.pairs:
                if p.name == info.name:
                    excluded = p.excluded
        self._panel.add_item(info, excluded)

    # ---- coverage ----------------------------------------------------------------------------
    def saved_poses(self) -> list[PoseDescriptor]:
        """Pose descriptors of the saved pairs in which both cameras saw the board."""
        board = self._board()
        return [pose for d in self._kept_detections()
                if (pose := pair_pose(d, board)) is not None]  # (found: each has its pose)

    def _kept_detections(self) -> list[PairDetection]:
        return [i.detection for i in self._saved.values()
                if i.detection is not None and i.detection.found]

    def readiness(self) -> Readiness:
        return readiness(self._kept_detections(), self._board(), self._image_size())

    def fills(self, det: PairDetection) -> dict[str, list[str]]:
        """The empty regions of each image that the detection's points would reach."""
        size = det.image_size
        out = {}
        kept = self._kept_detections()
        # (kept: found in both images)
        kept_left = [k.left.corners for k in kept if k.left is not None]
        kept_right = [k.right.corners for k in kept if k.right is not None]
        for side, d, kept_side in (("left", det.left, kept_left),
                                   ("right", det.right, kept_right)):
            out[side] = ([] if d is None else
                         regions_filled(d.corners, cell_counts(kept_side, size), size))
        return out

    def _update_coverage(self) -> None:
        self._panel.coverage.set_coverage(coverage(self.saved_poses()))
        self._panel.coverage.set_readiness(self.readiness())

    def saved_names(self) -> list[str]:
        return self._panel.names()

    # ---- saved pairs -----------------------------------------------------------------------------
    def add_pair(self, left: np.ndarray, right: np.ndarray, det: PairDetection) -> str | None:
        """Write a pair into the session and list it; its name, or None (after saying why)."""
        session = self._session
        if session is None:  # (the tab takes no pair without one)
            self._report.report_error("could not save the pair: there is no session")
            return None
        try:
            pair = session.add_pair(left, right)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not save the pair: {exc}")
            return None
        info = SavedPairInfo(pair.name, det, pair_thumbnail(left, right))
        self._saved[pair.name] = info
        self._add_list_item(info)
        self._panel.show_newest()  # the pair just taken is in view, however long the list
        self._update_coverage()
        self._report.show_status(f"Saved pair {pair.name} to {session.folder}")
        return pair.name

    def load_pair(self, name: str) -> tuple[np.ndarray, np.ndarray, PairDetection | None]:
        """The saved pair's images and what the scan detected in them (None: not read yet);
        StereoGuiError when it is gone or cannot be read."""
        pairs = self._session.pairs if self._session is not None else []
        pair = next((p for p in pairs if p.name == name), None)
        if pair is None:
            raise StereoGuiError(f"pair {name} is no longer in the session")
        left, right = load_image(pair.left), load_image(pair.right)
        info = self._saved.get(name)
        return left, right, info.detection if info is not None else None

    def ask_delete(self, name: str) -> bool:
        """Whether the technician wants pair `name` deleted (the files go, not only the list
        entry)."""
        folder = self._session.folder if self._session else "the session folder"
        answer = QMessageBox.question(
            self._dialogs, "Delete pair", f"Delete pair {name}? Its two images are removed from "
            f"{folder}.")
        return answer == QMessageBox.StandardButton.Yes

    def delete_pair(self, name: str) -> bool:
        """Delete a saved pair's files from the session; False if it was not (said why)."""
        if self._session is None:
            return False
        try:
            self._session.delete_pair(name)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not delete pair {name}: {exc}")
            return False
        self._saved.pop(name, None)
        self._refill_list()
        self._update_coverage()
        self._report.show_status(f"Deleted pair {name}")
        return True
