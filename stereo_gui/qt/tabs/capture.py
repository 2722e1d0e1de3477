"""The Capture tab: take target pairs for calibration (the reference program's
Take_images_for_calibration, with buttons), with coverage by image region (core.coverage) that
says in words what is still missing, and Print a target... for printing one at true scale.

Both cameras live side by side with the board's corners drawn where found. When both see the
board the pair freezes for review: Save (S) writes both raw images to the session folder,
Cancel (C) goes live again. Automatic capture instead takes a pair by itself when the board is
steady and its pose is new. Detection runs in the frame worker's thread (the processor made by
`stereo_gui.pipeline.capture.make_capture_processor`); this widget only draws what it gets.
Sessions and saved pairs: `capture_session.SessionPairs`, a part the tab owns and hands what it
uses.
"""

from __future__ import annotations

import logging
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QFontMetrics
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.coverage import regions_in_words
from stereo_gui.core.detect import (
    PairDetection,
)
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.session import CaptureSession
from stereo_gui.pipeline.capture import (
    STEADY_FRAMES,
    STEADY_PX,
    STEADY_S,
    CaptureAction,
    CaptureOutput,
    CaptureRules,
    make_capture_processor,
)
from stereo_gui.pipeline.images import display_rgb
from stereo_gui.qt.source_capabilities import simulated_rig
from stereo_gui.qt.tabs.capture_session import SessionPairs
from stereo_gui.qt.tabs.capture_state import CAPTURE_MOVES, CaptureState
from stereo_gui.qt.widgets.board_row import BoardRow
from stereo_gui.qt.widgets.camera_controls import CameraControlsPanel
from stereo_gui.qt.widgets.helpers import pane, wrapping_label
from stereo_gui.qt.widgets.playback_bar import PlaybackBar
from stereo_gui.qt.widgets.saved_pairs import SavedPairsPanel
from stereo_gui.qt.widgets.stereo_pair_view import StereoPairView
from stereo_gui.qt.widgets.target_dialog import TargetDialog
from stereo_gui.sources.base import StereoFrame

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)



# ---- the tab -------------------------------------------------------------------------------------
class CaptureTab(QWidget):
    """Capture target pairs into a session folder, with review, auto-capture and coverage."""

    # the CaptureSession now open, or None: object, as Signal(CaptureSession) would promise a
    # session every time
    sessionChanged = Signal(object)
    pairSaved = Signal(str)  # name of the pair just written

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._state = CaptureState.LIVE
        self.frozen: CaptureOutput | None = None
        self.shown_pair: str | None = None  # the saved pair on screen (state SAVED)
        self._frozen_frame: StereoFrame | None = None
        self._frozen_at = ""  # the wall-clock time the pair under review was frozen, HH:MM:SS
        self._left_while_frozen = False  # the tab was hidden with that pair on screen
        self._active = False
        self._last_output: CaptureOutput | None = None
        self.frames_shown = 0  # live frames drawn (for the status and tests)
        self.shown_frame: StereoFrame | None = None  # the live frame drawn last
        self.rules = CaptureRules()  # when a live frame becomes a pair
        self._build()
        self._load_board_settings()
        ctx.frames.frameReady.connect(self._on_frame_ready)
        ctx.frames.sourceChanged.connect(self._source_changed)
        last = ctx.settings.last_session
        if last and Path(last).is_dir():
            try:
                self.open_session(last)
            except StereoGuiError as exc:
                ctx.report_error(f"The last capture session {last} was not reopened: {exc}")

    # ---- layout ------------------------------------------------------------------------------
    def _build(self) -> None:
        root = QHBoxLayout(self)
        split = QSplitter(Qt.Orientation.Horizontal)
        root.addWidget(split)
        split.addWidget(self._build_main())
        split.addWidget(self._build_side())
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 1)
        split.setSizes([900, 330])
        self._update_controls()

    def _build_main(self) -> QWidget:
        """The session line, the board, playback and camera controls, the pair's views and
        the review under them."""
        main, ml = pane()
        ml.addLayout(self._build_session_bar())
        ml.addWidget(self._build_board_row())
        self.playback = PlaybackBar(self.ctx)  # shown only for a recorded source
        self.playback.used.connect(self._playback_used)
        ml.addWidget(self.playback)
        self.camera_controls = CameraControlsPanel(self.ctx, "capture")
        ml.addWidget(self.camera_controls)
        self.pairSaved.connect(lambda _name: self.camera_controls.record_in(lambda: self.session))
        self.view = StereoPairView()
        ml.addWidget(self.view, 1)
        ml.addLayout(self._build_review())
        return main

    def _build_session_bar(self) -> QHBoxLayout:
        """New session…, Open session… and the session's name."""
        bar = QHBoxLayout()
        self.new_button = QPushButton("New session…")
        self.open_button = QPushButton("Open session…")
        self.session_label = QLabel("No session: choose New session… before saving pairs")
        self.session_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        bar.addWidget(self.new_button)
        bar.addWidget(self.open_button)
        bar.addWidget(self.session_label, 1)
        return bar

    def _build_board_row(self) -> BoardRow:
        """The board's size, its squares, automatic capture and Print a target…."""
        self.board_row = BoardRow(
            f"Take a pair by itself when the board holds still (corners move less than "
            f"{STEADY_PX:g} px over {STEADY_FRAMES} frames or {STEADY_S:g} s) and its pose differs "
            "from those kept")
        row = self.board_row
        self.cols_spin, self.rows_spin = row.cols_spin, row.rows_spin
        self.square_spin, self.auto_check = row.square_spin, row.auto_check
        row.edited.connect(self._board_edited)
        row.auto_check.toggled.connect(self._auto_toggled)
        row.printRequested.connect(self.open_target_dialog)
        return row

    def _build_review(self) -> QHBoxLayout:
        """The prompt, and Save pair, Cancel and Back to live stacked beside it."""
        review = QHBoxLayout()
        self.prompt = wrapping_label()
        f = self.prompt.font()
        f.setPointSize(f.pointSize() + 2)
        self.prompt.setFont(f)
        # three lines always: a prompt of one line and one of three must not move the views
        self.prompt.setMinimumHeight(3 * QFontMetrics(f).lineSpacing() + 12)
        self.prompt.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter)
        self.save_button = QPushButton("Save pair (S)")
        self.save_button.setShortcut("S")
        self.cancel_button = QPushButton("Cancel (C)")
        self.cancel_button.setShortcut("C")
        self.live_button = QPushButton("Back to live")
        self.save_button.clicked.connect(self.save_frozen)
        self.cancel_button.clicked.connect(self.cancel_frozen)
        self.live_button.clicked.connect(self.go_live)
        review.addWidget(self.prompt, 1)
        buttons = QVBoxLayout()  # stacked: the prompt gets the width, three lines hold it
        buttons.setSpacing(2)
        for b in (self.save_button, self.cancel_button, self.live_button):
            buttons.addWidget(b)
        review.addLayout(buttons)
        return review

    def _build_side(self) -> SavedPairsPanel:
        """The saved pairs and their coverage, with the session they are kept in
        (`SessionPairs`)."""
        side = SavedPairsPanel()
        side.pairClicked.connect(self.show_saved_pair)
        side.delete_button.clicked.connect(self._delete_selected)
        self.saved_panel = side
        self.pairs = SessionPairs(
            self.ctx.settings_model, self.ctx, self.ctx.workers, side, lambda: self.board,
            self.set_board, self._seen_size, self._source_name, self)
        self.pairs.sessionChanged.connect(self._session_changed)
        self.pairs.pairsChanged.connect(self._pairs_changed)
        self.new_button.clicked.connect(self.pairs.choose_new)
        self.open_button.clicked.connect(self.pairs.choose_open)
        self.coverage, self.pairs_label = side.coverage, side.pairs_label
        self.pair_list, self.delete_button = side.pair_list, side.delete_button
        return side

    @property
    def state(self) -> CaptureState:
        """What the tab shows: live frames, a frozen pair under review or a saved pair."""
        return self._state

    def _move(self, to: CaptureState) -> None:
        """Show `to` from now on (a move CAPTURE_MOVES refuses is a bug: TransitionError)."""
        self._state = CAPTURE_MOVES.check(self._state, to)

    def _playback_used(self) -> None:
        """Moving through a recording shows live frames again (leaves a frozen pair)."""
        if self.state is not CaptureState.LIVE:
            self.go_live()

    # ---- board settings ----------------------------------------------------------------------
    def _load_board_settings(self) -> None:
        self.board_row.show_board(self.ctx.settings.board)
        self.board_row.show_auto(bool(self.ctx.settings.auto_capture))

    @property
    def board(self) -> BoardSpec:
        return self.board_row.board

    def set_board(self, board: BoardSpec) -> None:
        """Use `board` (updates the spin boxes, the settings and the live detector)."""
        self.board_row.show_board(board)
        self._board_edited()

    def _board_edited(self) -> None:
        board = self.board
        self.ctx.settings_model.update(board_cols=board.cols, board_rows=board.rows,
                                       square_mm=board.square_mm, board_target=board.target,
                                       marker_mm=board.marker_mm,
                                       board_dictionary=board.dictionary)
        self.rules.reset_steadiness()
        self._show_board_on_sim(board)
        if self.state is CaptureState.LIVE:
            self._set_processing(True)
        self.pairs.record_board(board)

    def _show_board_on_sim(self, board: BoardSpec) -> None:
        """On the simulated rig, show the target chosen (it renders every target)."""
        rig = simulated_rig(self.ctx.frames.source())
        if rig is not None and rig.config.board != board:
            rig.set_board(board)

    def open_target_dialog(self) -> None:
        """Print a target...: write the current target as PDF, SVG or PNG at true scale."""
        start = (self.session.folder if self.session is not None else Path.home())
        dlg = TargetDialog(self.board, Path(start), self)
        dlg.written.connect(lambda path: self.ctx.show_status(f"Wrote the target to {path}"))
        dlg.exec()

    def _auto_toggled(self, on: bool) -> None:
        self.ctx.settings_model.update(auto_capture=bool(on))
        self.rules.reset_steadiness()
        if on and self.state is CaptureState.REVIEW:
            self.cancel_frozen()
        self._update_controls()

    # ---- activity ----------------------------------------------------------------------------
    def set_active(self, active: bool) -> None:
        """Called when the tab is shown (True) or hidden: the shown tab owns the processor."""
        if active == self._active:
            return
        self._active = active
        if not active:
            self._left_while_frozen = self.state is CaptureState.REVIEW
        if active:
            self._show_board_on_sim(self.board)
            self._set_processing(self.state is CaptureState.LIVE)
            self._reload_session()
            if self.state is CaptureState.REVIEW:  # the pair on screen is from before: say so
                self._show_review_prompt()

    def _reload_session(self) -> None:
        """Read the session again (the Calibration tab may have excluded pairs meanwhile)."""
        if self.pairs.reload() and self.shown_pair is not None:
            self.saved_panel.select(self.shown_pair)

    def _source_changed(self, name: str) -> None:
        """Another source: a pair frozen from the previous one is no pair of this one (Save must
        not offer it, even for a folder without a board), and what is on screen until its first
        frame is not this source's picture."""
        self.rules.reset_steadiness()
        self.rules.last_reviewed_pose = None
        self._last_output = None
        if self.state is CaptureState.SAVED:
            return  # a saved pair of the session stays in review
        if self.state is CaptureState.REVIEW:
            self.go_live()
        self.view.clear(f"waiting for {name}…" if name else "no source")
        self.prompt.setText(f"Live: waiting for the first frame of {name}" if name
                            else "No source: choose one with File > Choose source…")

    def _set_processing(self, on: bool) -> None:
        """Detect in live frames only while live frames are shown (saves CPU while reviewing)."""
        if self._active:
            self.ctx.frames.set_processor(make_capture_processor(self.board) if on else None)

    def _on_frame_ready(self) -> None:
        if not self._active:
            return
        pf = self.ctx.frames.latest()
        if pf is None or not isinstance(pf.output, CaptureOutput):
            return
        self.rules.timing = self.ctx.frames.timing()
        self.show_output(pf.output, pf.frame)

    def show_output(self, out: CaptureOutput, frame: StereoFrame) -> None:
        """Draw one processed live frame and act on it (freeze, or auto-capture)."""
        if self.state is not CaptureState.LIVE:
            return  # a frozen or saved pair is on screen: live frames wait
        self._last_output = out
        self.view.show_pair(out.left_rgb, out.right_rgb)
        self.view.show_detection(out.detection)
        self.frames_shown += 1
        self.shown_frame = frame
        step = self.rules.step(out, self.auto_check.isChecked(), self.pairs.saved_poses,
                               self.session is not None, board=self.board, fills=self.pairs.fills,
                               empty_regions=lambda: self.pairs.readiness().required_empty)
        if step.action is CaptureAction.FREEZE:
            self._freeze(out, frame)
            return
        if step.action is CaptureAction.SAVE:
            self._save_pair(frame, out.detection)
        self.prompt.setText(step.prompt)

    # ---- review --------------------------------------------------------------------------------
    def _freeze(self, out: CaptureOutput, frame: StereoFrame) -> None:
        self._move(CaptureState.REVIEW)
        self.frozen = out
        self._frozen_frame = frame
        self._frozen_at = datetime.now().strftime("%H:%M:%S")
        self._left_while_frozen = False
        self._show_review_prompt()
        self._set_processing(False)  # nothing to detect while a pair is under review
        self._update_controls()

    def _show_review_prompt(self) -> None:
        text = "Both cameras see the board. Save this pair (S) or Cancel (C)?"
        if self._left_while_frozen:  # not the cameras' view now: it waited while away
            text = (f"This pair was frozen at {self._frozen_at}, before you left the Capture tab "
                    "(the cameras have moved on). Save it (S), or Cancel (C) to go live?")
        fills = self.pairs.fills(self.frozen.detection) if self.frozen is not None else {}
        if any(fills.values()):
            text += f"  It reaches {regions_in_words(fills)} (not yet covered)."
        if self.session is None:
            text += "  (Save asks for a session folder first.)"
        self.prompt.setText(text)

    def save_frozen(self) -> str | None:
        """Save the frozen pair into the session (asking for one if none is open)."""
        if (self.state is not CaptureState.REVIEW or self._frozen_frame is None
                or self.frozen is None):
            return None
        if self.session is None and not self.pairs.choose_new():
            return None
        name = self._save_pair(self._frozen_frame, self.frozen.detection)
        self.go_live()
        return name

    def cancel_frozen(self) -> None:
        if self.state is CaptureState.REVIEW:
            self.go_live()

    def go_live(self) -> None:
        if self.state is not CaptureState.LIVE:
            self._set_processing(True)
        self._move(CaptureState.LIVE)
        self.frozen = None
        self._frozen_frame = None
        self._left_while_frozen = False
        self.shown_pair = None
        self.rules.reset_steadiness()
        self.saved_panel.clear_selection()  # no saved pair is shown, none is selected
        self.prompt.setText("Live")
        self._update_controls()

    def _save_pair(self, frame: StereoFrame, det: PairDetection) -> str | None:
        name = self.pairs.add_pair(frame.left, frame.right, det)
        if name is not None:
            self.pairSaved.emit(name)
        return name

    # ---- the session and its saved pairs (see SessionPairs) ------------------------------------
    @property
    def session(self) -> CaptureSession | None:
        """The capture session open (None before one is chosen)."""
        return self.pairs.session

    def new_session(self, folder: str | Path) -> None:
        """Start a session in `folder` with the current board."""
        self.pairs.new_session(folder)

    def open_session(self, folder: str | Path) -> None:
        """Open an existing session (or a folder of pairs) to continue, review or delete."""
        self.pairs.open_session(folder)

    def scanning(self) -> bool:
        """The session's saved pairs are still being read."""
        return self.pairs.scanning()

    def saved_names(self) -> list[str]:
        return self.pairs.saved_names()

    def _seen_size(self) -> tuple[int, int] | None:
        out = self._last_output
        return out.detection.image_size if out is not None else None

    def _source_name(self) -> str:
        src = self.ctx.frames.source()
        return src.name if src is not None else ""

    def _session_changed(self, session: CaptureSession) -> None:
        self.session_label.setText(f"Session: {session.folder}")
        self.shown_pair = None
        if self.state is CaptureState.REVIEW:  # the prompt need not warn that Save asks for one
            self._show_review_prompt()
        self.sessionChanged.emit(session)
        self._update_controls()

    def _pairs_changed(self) -> None:
        self._update_controls()  # Delete pair needs pairs in the list
        if self.state is CaptureState.REVIEW:  # what a frozen pair adds is known now
            self._show_review_prompt()

    def show_saved_pair(self, name: str) -> None:
        """Show a saved pair (with its corners) instead of the live view; it is the pair
        selected in the list (and the one Delete pair deletes)."""
        if self.session is None:
            return
        try:
            left, right, det = self.pairs.load_pair(name)
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
        if name is not None and self.pairs.ask_delete(name):
            self.delete_pair(name)

    def delete_pair(self, name: str) -> None:
        """Delete a saved pair's files from the session."""
        if not self.pairs.delete_pair(name):
            return
        if self.state is CaptureState.SAVED and self.shown_pair == name:
            self.go_live()
        elif self.shown_pair is not None:
            self.saved_panel.select(self.shown_pair)

    # ---- controls --------------------------------------------------------------------------------
    def _update_controls(self) -> None:
        review = self.state is CaptureState.REVIEW
        self.prompt.setStyleSheet(
            "background: #fff3b0; border: 1px solid #d4a017; padding: 4px; font-weight: bold"
            if review else "padding: 4px")
        self.save_button.setEnabled(review)
        self.cancel_button.setEnabled(review)
        self.live_button.setEnabled(self.state is CaptureState.SAVED)
        # Delete pair deletes the saved pair on screen: with none shown there is nothing to delete
        self.delete_button.setEnabled(self.session is not None and self.state is CaptureState.SAVED)
        if review:
            self.save_button.setDefault(True)

    def unfinished_work(self) -> list[str]:
        """Nothing here is cut short by closing: pairs are written as they are saved."""
        return []

    def cancel_unfinished_work(self, timeout_ms: int = 2000) -> list[str]:
        return []

    def shutdown(self, timeout_ms: int = 2000) -> bool:
        """Cancel a session scan; the context joins its thread (it is registered there)."""
        self.pairs.cancel_scan()
        return True

