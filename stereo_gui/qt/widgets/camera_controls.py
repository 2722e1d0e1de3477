"""The camera controls panel of the Capture and Live tabs: each camera's focus, exposure, gain,
white balance and brightness, "same for both cameras", lock focus, match exposure, the restore
of a calibration's controls with what still differs, and the two cameras' skew.

`CameraSetup` is the model: one per application context, shared by the panels of both tabs,
so that a source is restored once and both panels show the same state. It never touches a
device: every read and write is a task the frame worker's reader thread runs
(FrameWorker.run_on_source, pipeline.camera_setup), and the panels draw the ControlsReport that
comes back. A control the camera does not have (or that refused or ignored a write) is shown as
"not available", never as a slider; a value its automatic mode sets is shown and disabled.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QFrame,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSlider,
    QSpinBox,
    QStackedWidget,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.camera_settings import PairSettings
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.session import CaptureSession
from stereo_gui.pipeline import camera_setup as setup
from stereo_gui.sources.base import FrameSource, StereoFrame
from stereo_gui.sources.camera_controls import ControlReading, PairControls

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

# the panel's rows: (title, automatic switch or None, value)
ROWS = (("Focus", "focus_auto", "focus"), ("Exposure", "exposure_auto", "exposure"),
        ("Gain", None, "gain"), ("White balance", "wb_auto", "wb_temperature"),
        ("Brightness", None, "brightness"))
SKEW_POLL_MS = 500
BODY_MAX_PX = 170  # the unfolded rows' height at most (they scroll beyond it)
NO_CONTROLS = ("This source has no camera controls (a recording, a folder of pairs or a video "
               "plays back what was captured)")
WARN_STYLE = "background: #fff3b0; color: #3e2700; border: 1px solid #d4a017; padding: 3px"
BAD_STYLE = "background: #ffcdd2; color: #5d0000; padding: 2px 4px"


T = TypeVar("T")
# what the reader thread runs on the cameras: (pair, calibration in use, frame size, source,
# newest frame) -> the answer its `on_answer` takes on the UI thread
SetupTask = Callable[[PairControls, StereoCalibration | None, tuple[int, int] | None,
                      FrameSource, StereoFrame | None], T]
# a match step's answer: the step and the controls read after it, or the step alone (no frame)
MatchAnswer = setup.MatchStep | tuple[setup.MatchStep, setup.ControlsReport]


def _sides_text(sides: Sequence[str]) -> str:
    return " and ".join(sides) + (" cameras" if len(sides) > 1 else " camera")


class CameraSetup(QObject):
    """The cameras' controls as last read back, and the requests that change them (see the
    module doc). `report` is the newest pipeline.camera_setup.ControlsReport (None before one
    came, or when the source has none: `unavailable` says why)."""

    changed = Signal()  # report, note, unavailable or matching changed
    OBJECT_NAME = "cameraSetup"

    @classmethod
    def of(cls, ctx: AppContext) -> CameraSetup:
        """The one CameraSetup of application context `ctx` (its child: it lives as long)."""
        found = ctx.findChild(cls, cls.OBJECT_NAME)
        return found if found is not None else cls(ctx)

    def __init__(self, ctx: AppContext) -> None:
        super().__init__(ctx)
        self.setObjectName(self.OBJECT_NAME)
        self.ctx = ctx
        self.report: setup.ControlsReport | None = None
        self.unavailable = ""  # why there are no controls ("" when there are, or not known yet)
        self.note = ""  # what the last request did, for the technician ("" when nothing to say)
        self.matching = False  # exposure matching under way
        # task id -> how to take its answer (it comes back through FrameWorker.sourceTaskDone,
        # an object; _run pairs each task with the taker of its own answer's type)
        self._tasks: dict[int, Callable[[Any], None]] = {}
        self._match_steps = 0
        self._write_busy = False
        # the newest write asked while one was under way: (name, value, sides)
        self._queued_write: tuple[str, bool | float, tuple[str, ...]] | None = None
        ctx.frames.sourceTaskDone.connect(self._answered)
        ctx.frames.sourceChanged.connect(self._source_changed)
        ctx.calibration_model.changed.connect(lambda _c: self.refresh())

    # ---- requests (UI thread) ------------------------------------------------------------------
    def _run(self, fn: SetupTask[T], on_answer: Callable[[T], None],
             after_frames: int = 0) -> int:
        calib = self.ctx.calibration

        def task(source: FrameSource, frame: StereoFrame | None) -> T | None:
            pair = source.camera_controls()
            if pair is None:
                return None
            size = frame.size if frame is not None else None
            return fn(pair, calib, size, source, frame)

        tid = self.ctx.frames.run_on_source(task, after_frames)
        self._tasks[tid] = on_answer
        return tid

    def refresh(self) -> None:
        """Read the controls again (and compare them with the calibration in use)."""
        self._run(lambda pair, calib, size, _s, _f: setup.read_controls(pair, calib, size),
                  self._take_report)

    def restore(self) -> None:
        """Write back the controls the calibration in use was made with."""
        self._run(lambda pair, calib, size, _s, _f:
                  setup.restore_calibration_controls(pair, calib, size), self._take_report)

    def write(self, name: str, value: bool | float,
              sides: Sequence[str] = ("left", "right")) -> None:
        """Write one control (newest wins: a slider dragged sends its last value once the
        write before it is answered)."""
        if self._write_busy:
            self._queued_write = (name, value, tuple(sides))
            return
        self._write_busy = True
        self._run(lambda pair, calib, size, _s, _f:
                  setup.write_control(pair, name, value, tuple(sides), calib, size),
                  self._take_write)

    def lock_focus(self, sides: Sequence[str] = ("left", "right")) -> None:
        self._run(lambda pair, calib, size, _s, _f:
                  setup.lock_focus(pair, tuple(sides), calib, size), self._take_report)

    def match_exposure(self) -> None:
        """Set the right camera's exposure and gain until its image matches the left's."""
        if self.matching:
            return
        self.matching = True
        self._match_steps = 0
        self.note = "Matching the right camera's exposure to the left's…"
        self.changed.emit()

        def begin(pair: PairControls, calib: StereoCalibration | None,
                  size: tuple[int, int] | None, source: FrameSource,
                  frame: StereoFrame | None) -> setup.ControlsReport:
            setup.begin_exposure_matching(pair)
            return setup.read_controls(pair, calib, size)

        self._run(begin, self._match_begun)

    def record_in(self, session_of: Callable[[], CaptureSession | None]) -> None:
        """Keep the controls in the capture session `session_of()` gives when they are read
        (the tab's session then: it may have been opened again meanwhile): read again now,
        since automatic modes move them between requests."""
        def keep(report: setup.ControlsReport) -> None:
            self._take_report(report)
            session = session_of()
            if session is None:
                return
            try:
                session.set_camera_controls(report.settings)
            except Exception as exc:  # noqa: BLE001 - the pair is saved; only this note is lost
                self.ctx.report_error(f"could not record the cameras' controls in the session: "
                                      f"{exc}")

        self._run(lambda pair, calib, size, _s, _f: setup.read_controls(pair, calib, size), keep)

    # ---- answers (UI thread) -------------------------------------------------------------------
    def _answered(self, tid: int, result: object) -> None:
        take = self._tasks.pop(tid, None)
        if take is None:
            return  # another's task
        if isinstance(result, Exception):
            log.warning("camera controls: %s", result)
            self.note = f"The cameras could not be reached: {result}"
            self.matching = False
            self._write_busy = False
            self.changed.emit()
            return
        if result is None:
            self.report, self.unavailable, self.matching = None, NO_CONTROLS, False
            self._write_busy = False
            self.changed.emit()
            return
        take(result)

    def _take_report(self, report: setup.ControlsReport) -> None:
        self.report, self.unavailable = report, ""
        failures = [r.message for r in report.failures if r.message]
        self.note = "; ".join(failures)
        self.changed.emit()

    def _take_write(self, report: setup.ControlsReport) -> None:
        self._write_busy = False
        self._take_report(report)
        if self._queued_write is not None:
            name, value, sides = self._queued_write
            self._queued_write = None
            self.write(name, value, sides)

    def _match_begun(self, report: setup.ControlsReport) -> None:
        self._take_report(report)
        self._match_next()

    def _match_next(self) -> None:
        def step(pair: PairControls, calib: StereoCalibration | None,
                 size: tuple[int, int] | None, source: FrameSource,
                 frame: StereoFrame | None) -> MatchAnswer:
            if frame is None:
                return setup.MatchStep(float("nan"), True, "no frame to measure")
            limit = setup.exposure_limit(pair.right.read_one("exposure"),
                                         float(source.nominal_fps))
            out = setup.exposure_match_step(pair, frame.left, frame.right, limit)
            return out, setup.read_controls(pair, calib, size)

        self._run(step, self._match_answered, setup.MATCH_SETTLE_FRAMES)

    def _match_answered(self, answer: MatchAnswer) -> None:
        if isinstance(answer, setup.MatchStep):  # (no frame yet)
            step, report = answer, None
        else:
            step, report = answer
        if report is not None:
            self.report, self.unavailable = report, ""
        self._match_steps += 1
        if step.done or self._match_steps >= setup.MATCH_MAX_STEPS:
            self.matching = False
            self.note = ("Exposure " + step.message if step.done else
                         f"Exposure matching stopped after {self._match_steps} steps: "
                         f"{step.message}")
            self.ctx.show_status(self.note)
        else:
            self.note = f"Matching exposure: {step.message}"
            self._match_next()
        self.changed.emit()

    def _source_changed(self, name: str) -> None:
        self.report, self.unavailable, self.note, self.matching = None, "", "", False
        self._write_busy, self._queued_write = False, None
        self.changed.emit()
        if name:  # once its first frame is read: restore the calibration's controls, or read
            self._run(lambda pair, calib, size, _s, _f:
                      setup.restore_calibration_controls(pair, calib, size),
                      self._take_report, after_frames=1)


class _CameraCell(QWidget):
    """One camera's widgets of one row: its automatic switch (when the row has one), a slider
    and a number for the value, or "not available" in their place."""

    def __init__(self, switch: str | None, value: str, panel: CameraControlsPanel,
                 side: str) -> None:
        super().__init__()
        self.switch, self.value, self.panel, self.side = switch, value, panel, side
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        self.auto = QCheckBox("auto")
        self.auto.setVisible(switch is not None)
        self.auto.toggled.connect(self._auto_toggled)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setMinimumWidth(90)
        self.spin = QSpinBox()
        self.spin.setKeyboardTracking(False)
        self.slider.valueChanged.connect(self._slid)
        self.spin.valueChanged.connect(self._typed)
        self.missing = QLabel("not available")
        self.missing.setStyleSheet("color: #777")
        self.stack = QStackedWidget()
        live = QWidget()
        lr = QHBoxLayout(live)
        lr.setContentsMargins(0, 0, 0, 0)
        lr.addWidget(self.slider, 1)
        lr.addWidget(self.spin)
        self.stack.addWidget(live)
        self.stack.addWidget(self.missing)
        row.addWidget(self.auto)
        row.addWidget(self.stack, 1)

    def show_readings(self, switch: ControlReading | None, value: ControlReading) -> None:
        """Show what the camera read back (no write is sent from here)."""
        for w in (self.auto, self.slider, self.spin):
            w.blockSignals(True)
        try:
            if switch is not None:
                self.auto.setEnabled(switch.available)
                self.auto.setChecked(switch.value is True)
                self.auto.setToolTip(switch.note if not switch.available else
                                     f"{switch.label}: on = the camera sets "
                                     f"{value.label.lower()} itself")
            held = switch is not None and switch.value is True
            if value.available:
                self.stack.setCurrentIndex(0)
                lo, hi = int(round(value.lo)), int(round(value.hi))
                for w in (self.slider, self.spin):
                    w.setRange(lo, hi)
                    w.setSingleStep(max(1, int(round(value.step))))
                    if value.value is not None:
                        w.setValue(int(round(value.value)))
                self.spin.setSuffix(f" {value.unit}" if value.unit else "")
                for w in (self.slider, self.spin):
                    w.setEnabled(not held)
                tip = (f"set by the camera while auto is on ({value.value:g} now)"
                       if held and value.value is not None else
                       f"{value.label}, {value.unit or 'device units'} (read back after "
                       "every write)")
                self.slider.setToolTip(tip)
                self.spin.setToolTip(tip)
            else:
                self.stack.setCurrentIndex(1)
                shown = f" (reads {value.value:g})" if value.value is not None else ""
                self.missing.setText(f"not available{shown}")
                self.missing.setToolTip(value.note)
        finally:
            for w in (self.auto, self.slider, self.spin):
                w.blockSignals(False)

    def _auto_toggled(self, on: bool) -> None:
        if self.switch is None:  # (a row without a switch hides its box)
            return
        self.panel.edited(self.switch, bool(on), self.side)

    def _slid(self, v: int) -> None:
        self.spin.blockSignals(True)
        self.spin.setValue(v)
        self.spin.blockSignals(False)
        self.panel.edited(self.value, float(v), self.side)

    def _typed(self, v: int) -> None:
        self.slider.blockSignals(True)
        self.slider.setValue(v)
        self.slider.blockSignals(False)
        self.panel.edited(self.value, float(v), self.side)


class CameraControlsPanel(QWidget):
    """The panel (see the module doc): a header line with the skew and what needs attention,
    and, unfolded, a row per control with the left and right camera side by side. `purpose`
    is "capture" (calibration pairs) or "live" (measuring): it words the autofocus warning."""

    def __init__(self, ctx: AppContext, purpose: str = "capture",
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self.purpose = purpose
        self.model = CameraSetup.of(ctx)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.setSpacing(2)
        outer.addLayout(self._build_head())
        outer.addWidget(self._build_warning_row())
        outer.addWidget(self._build_body())

        self._timer = QTimer(self)
        self._timer.setInterval(SKEW_POLL_MS)
        self._timer.timeout.connect(self.show_timing)
        self._timer.start()
        self.model.changed.connect(self.show_state)
        self.show_state()

    def _build_head(self) -> QHBoxLayout:
        """The header line: the fold button and the skew."""
        head = QHBoxLayout()
        self.fold = QToolButton()
        self.fold.setText("Camera controls")
        self.fold.setCheckable(True)
        self.fold.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.fold.setArrowType(Qt.ArrowType.RightArrow)
        self.fold.toggled.connect(self.set_unfolded)
        self.skew_label = QLabel("Skew: no frames")
        self.skew_label.setToolTip(
            "How far apart in time the two cameras take their pictures (right minus left), "
            "over the last second. Above a third of a frame interval a moving board or robot "
            "is seen at two moments.")
        head.addWidget(self.fold)
        head.addWidget(self.skew_label, 1)
        return head

    def _build_warning_row(self) -> QWidget:
        """What needs attention, with Restore and Lock focus beside it (hidden until then)."""
        self.warning = QLabel()
        self.warning.setWordWrap(True)
        self.warning.setStyleSheet(WARN_STYLE)
        self.restore_button = QPushButton("Restore")
        self.restore_button.setToolTip("Write back the focus and exposure the calibration in "
                                       "use was made with")
        self.restore_button.clicked.connect(self.model.restore)
        self.lock_warning_button = QPushButton("Lock focus")
        self.lock_warning_button.clicked.connect(self._lock_autofocus_sides)
        self.warning_row = QWidget()
        wr = QHBoxLayout(self.warning_row)
        wr.setContentsMargins(0, 0, 0, 0)
        wr.addWidget(self.warning, 1)
        wr.addWidget(self.restore_button)
        wr.addWidget(self.lock_warning_button)
        self.warning_row.hide()
        return self.warning_row

    def _build_body(self) -> QScrollArea:
        """The unfolded part: the rows of controls, the buttons under them and the note, in a
        scroll area."""
        self.body = QWidget()
        body = QVBoxLayout(self.body)
        body.setContentsMargins(0, 0, 0, 0)
        body.addLayout(self._build_rows())
        body.addLayout(self._build_buttons())
        self.note_label = QLabel()
        self.note_label.setWordWrap(True)
        body.addWidget(self.note_label)
        # the rows scroll within BODY_MAX_PX: unfolded, they must not make the window ask for
        # more height than a 720 px screen has (they asked for 735 px, 772 with the warning)
        self.body_scroll = QScrollArea()
        self.body_scroll.setWidget(self.body)
        self.body_scroll.setWidgetResizable(True)
        self.body_scroll.setFrameShape(QFrame.Shape.NoFrame)
        self.body_scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.body_scroll.setMaximumHeight(BODY_MAX_PX)
        self.body_scroll.setMinimumHeight(0)
        self.body_scroll.hide()
        return self.body_scroll

    def _build_rows(self) -> QGridLayout:
        """A row per control (ROWS), the left and the right camera's cell side by side."""
        grid = QGridLayout()
        grid.setHorizontalSpacing(8)
        grid.setVerticalSpacing(1)
        self.left_title = QLabel("<b>Left camera</b>")
        self.right_title = QLabel("<b>Right camera</b>")
        grid.addWidget(self.left_title, 0, 1)
        grid.addWidget(self.right_title, 0, 2)
        self.cells: dict[tuple[str, str], _CameraCell] = {}
        for r, (title, switch, value) in enumerate(ROWS, start=1):
            grid.addWidget(QLabel(title), r, 0)
            for c, side in enumerate(("left", "right"), start=1):
                cell = _CameraCell(switch, value, self, side)
                self.cells[(value, side)] = cell
                grid.addWidget(cell, r, c)
        grid.setColumnStretch(1, 1)
        grid.setColumnStretch(2, 1)
        return grid

    def _build_buttons(self) -> QHBoxLayout:
        """Same for both cameras, Lock focus, Match exposure, Read again."""
        buttons = QHBoxLayout()
        self.same_check = QCheckBox("Same for both cameras")
        self.same_check.setToolTip("A change to one camera's control is written to both")
        self.same_check.setChecked(True)
        self.lock_button = QPushButton("Lock focus")
        self.lock_button.setToolTip("Autofocus off on both cameras, the focus held where it is")
        self.lock_button.clicked.connect(lambda: self.model.lock_focus(("left", "right")))
        self.match_button = QPushButton("Match exposure")
        self.match_button.setToolTip(
            "Hold both cameras' exposure and set the right camera's exposure and gain so that "
            "its image is as bright as the left's where both see the scene")
        self.match_button.clicked.connect(self.model.match_exposure)
        self.read_button = QPushButton("Read again")
        self.read_button.clicked.connect(self.model.refresh)
        for w in (self.same_check, self.lock_button, self.match_button, self.read_button):
            buttons.addWidget(w)
        buttons.addStretch(1)
        return buttons

    # ---- showing -------------------------------------------------------------------------------
    def set_unfolded(self, on: bool) -> None:
        """Show (True) or hide the rows of controls."""
        if self.fold.isChecked() != on:
            self.fold.setChecked(on)
            return
        self.fold.setArrowType(Qt.ArrowType.DownArrow if on else Qt.ArrowType.RightArrow)
        self.body_scroll.setVisible(on)
        if on:
            self.model.refresh()

    def show_timing(self) -> None:
        """The skew line (polled: it changes with every frame; drawing it each frame is waste)."""
        if not self.isVisible():
            return
        t = self.ctx.frames.timing()
        self.skew_label.setText(t.text())
        self.skew_label.setStyleSheet(BAD_STYLE if t.too_large else "")
        self._show_warnings()

    def warnings(self) -> list[str]:
        """What needs the technician's attention now, in words."""
        m = self.model
        out = []
        if m.report is not None:
            out += [x.message[0].upper() + x.message[1:] + "." for x in m.report.mismatches]
            af = [s for s in m.report.autofocus_on()
                  if not any(x.what == "autofocus" and x.side == s
                             for x in m.report.mismatches)]
            if af:
                what = ("calibration pairs taken so will not hold" if self.purpose == "capture"
                        else "distances read so will be wrong when it refocuses")
                focus = ", ".join(f"{s} {m.report.settings.side(s).focus:g}" for s in af
                                  if m.report.settings.side(s).focus is not None)
                out.append(f"Autofocus is on ({_sides_text(af)}): the lens refocuses when the "
                           f"scene changes, and with it the focal length: {what}. Lock the "
                           f"focus where it is{' (last read: ' + focus + ')' if focus else ''}.")
        t = self.ctx.frames.timing()
        if t.too_large and self.purpose == "capture":
            out.append(f"The cameras take their pictures {abs(t.median_ms):.0f} ms apart, more "
                       "than a third of a frame: hold the board still for each pair.")
        return out

    def show_state(self) -> None:
        m = self.model
        report = m.report
        for (value, side), cell in self.cells.items():
            switch = next(s for _t, s, v in ROWS if v == value)
            if report is None:
                cell.setEnabled(False)
                continue
            cell.setEnabled(not m.matching)
            state = report.left if side == "left" else report.right
            cell.show_readings(state.reading(switch) if switch else None, state.reading(value))
        if report is not None:
            for title, side, state in ((self.left_title, "Left", report.left),
                                       (self.right_title, "Right", report.right)):
                title.setText(f"<b>{side} camera</b> ({state.backend})")
        has = report is not None
        for b in (self.lock_button, self.match_button, self.same_check):
            b.setEnabled(has and not m.matching)
        self.lock_button.setEnabled(report is not None and bool(report.autofocus_on()))
        self.note_label.setText(m.unavailable or m.note)
        self._show_warnings()
        self.fold.setText("Camera controls" + (" (none on this source)" if m.unavailable else ""))

    def _show_warnings(self) -> None:
        report = self.model.report
        warns = self.warnings()
        text = "\n".join(warns)
        if text != self.warning.text():
            self.warning.setText(text)
        self.warning_row.setVisible(bool(warns))
        self.restore_button.setVisible(report is not None
                                       and any(x.restorable for x in report.mismatches))
        self.lock_warning_button.setVisible(report is not None and bool(report.autofocus_on()))

    # ---- edits -----------------------------------------------------------------------------
    def edited(self, name: str, value: bool | float, side: str) -> None:
        """A control changed in the panel: write it (to both cameras with "same for both")."""
        sides = ("left", "right") if self.same_check.isChecked() else (side,)
        self.model.write(name, value, sides)

    def _lock_autofocus_sides(self) -> None:
        if self.model.report is not None:
            self.model.lock_focus(self.model.report.autofocus_on())

    # ---- for the tabs and tests ------------------------------------------------------------------
    def settings(self) -> PairSettings | None:
        """The controls as last read back (None before they were read)."""
        r = self.model.report
        return r.settings if r is not None else None

    def record_in(self, session_of: Callable[[], CaptureSession | None]) -> None:
        """Keep the controls, read again, in the session `session_of()` gives."""
        self.model.record_in(session_of)
