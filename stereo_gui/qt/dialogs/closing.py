"""What closing the window asks and shows when something would be lost.

- `ask_unsaved_calibration(parent, what)`: Save / Discard / Cancel for a calibration that was
  computed and not saved.
- `CloseWaiter`: shown while exports still run when the window is closed. It lists them (with
  their progress) and a countdown, and ends in one of three ways: every export is done (`workDone`:
  the window closes), the user insists or the time is up (`cancelRequested(timed_out)`: the window
  cancels them, says what became of each, and closes), or the user keeps working (`aborted`).
  Nothing here waits in a loop: a timer looks at `pending()` a few times a second.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import QDialog, QLabel, QMessageBox, QPushButton, QVBoxLayout, QWidget

from stereo_gui.qt.widgets.flow_layout import FlowLayout

CLOSE_WAIT_S = 60.0  # closing waits at most this long for running exports, then cancels them
_TICK_MS = 200


def ask_unsaved_calibration(parent: QWidget, what: str) -> QMessageBox.StandardButton:
    """Ask whether to save the calibration `what` (e.g. "calibrated from ... (12 pairs, stereo
    RMS 0.31 px)") before closing: Save, Discard or Cancel (Escape cancels)."""
    box = QMessageBox(QMessageBox.Icon.Warning, "Unsaved calibration",
                      "The calibration is not saved.", parent=parent)
    box.setInformativeText(f"The calibration in use was {what} and exists in no file yet. "
                           "Save it before closing?")
    box.setStandardButtons(QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard
                           | QMessageBox.StandardButton.Cancel)
    box.setDefaultButton(QMessageBox.StandardButton.Save)
    box.setEscapeButton(QMessageBox.StandardButton.Cancel)
    box.button(QMessageBox.StandardButton.Save).setText("Save…")
    box.button(QMessageBox.StandardButton.Discard).setText("Discard and close")
    box.setObjectName("unsaved-calibration")
    return QMessageBox.StandardButton(box.exec())


def tell_cancelled(parent: QWidget, lines: list[str], timed_out_s: float | None) -> None:
    """Say what became of the work cancelled at closing (a modal message the user confirms);
    `timed_out_s` is the wait that ran out, None when the user cancelled."""
    box = QMessageBox(QMessageBox.Icon.Information, "Export cancelled",
                      "Closing cancelled what was still being written." if timed_out_s is None
                      else f"The export did not finish within {timed_out_s:g} s of closing; "
                      "it was cancelled.", parent=parent)
    box.setInformativeText("\n\n".join(lines) if lines else "Nothing was left half-written.")
    box.setObjectName("export-cancelled")
    box.exec()


class CloseWaiter(QDialog):
    """Waits (without blocking) for `pending()` (descriptions of the work still running) to
    be empty; see the module docstring."""

    workDone = Signal()  # (not `done`: that is QDialog's own slot, done(result))
    cancelRequested = Signal(bool)  # True when the wait ran out, False when the user insisted
    aborted = Signal()

    def __init__(self, parent: QWidget, pending: Callable[[], list[str]],
                 wait_s: float | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("close-waiter")
        self.setWindowTitle("Closing Stereo GUI")
        self.setWindowModality(Qt.WindowModality.WindowModal)
        self._pending = pending
        self.wait_s = float(CLOSE_WAIT_S if wait_s is None else wait_s)
        self._deadline = time.monotonic() + self.wait_s
        self._ended = False
        col = QVBoxLayout(self)
        self.label = QLabel()
        self.label.setWordWrap(True)
        self.label.setMinimumWidth(460)
        col.addWidget(self.label)
        buttons = QWidget()
        row = FlowLayout(buttons)
        row.add_stretch()
        self.cancel_button = QPushButton("Cancel the export and close")
        self.cancel_button.clicked.connect(self.insist)
        self.keep_button = QPushButton("Don't close")
        self.keep_button.setToolTip("Keep the window open; the export goes on")
        self.keep_button.clicked.connect(self._keep_working)
        row.addWidget(self.cancel_button)
        row.addWidget(self.keep_button)
        col.addWidget(buttons)
        self._timer = QTimer(self)
        self._timer.setInterval(_TICK_MS)
        self._timer.timeout.connect(self._tick)
        self._timer.start()
        self._tick()

    def seconds_left(self) -> float:
        return max(0.0, self._deadline - time.monotonic())

    def _tick(self) -> None:
        if self._ended:
            return
        work = self._pending()
        if not work:
            self._end(self.workDone.emit)
            return
        left = self.seconds_left()
        if left <= 0:
            self._end(lambda: self.cancelRequested.emit(True))
            return
        items = "".join(f"<li>{w}</li>" for w in work)
        self.label.setText(f"Stereo GUI closes as soon as this is done:<ul>{items}</ul>"
                           f"Waiting at most {math.ceil(left)} s more; then it is cancelled (nothing "
                           "half-written is left).")

    def insist(self) -> None:
        """Cancel the work and close now (the button, or closing the window again)."""
        self._end(lambda: self.cancelRequested.emit(False))

    def dismiss(self) -> None:
        """Stop waiting and hide, announcing nothing (the window closes without asking)."""
        self._end(lambda: None)

    def _keep_working(self) -> None:
        self._end(self.aborted.emit)

    def reject(self) -> None:  # Escape, or the dialog's own close button: keep working
        self._keep_working()

    def _end(self, emit: Callable[[], object]) -> None:
        if self._ended:
            return
        self._ended = True
        self._timer.stop()
        if self.isVisible():
            super().reject()
        emit()
