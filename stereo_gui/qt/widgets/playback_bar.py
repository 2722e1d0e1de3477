"""Playback controls for a recorded source (a recording, a folder of pairs, a side-by-side video):
play/pause, one frame back/forward, loop, and a position slider with "frame i of N".

The bar shows itself only while the frame worker's source is a playback source. The controls
call the source's thread-safe methods directly (they only set state under its lock; the reader
thread loads the frame); the position is polled a few times a second while shown.
"""

from __future__ import annotations

import logging

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import QCheckBox, QHBoxLayout, QLabel, QSlider, QToolButton, QWidget

log = logging.getLogger(__name__)

_CONTROLS = ("frame_count", "position", "paused", "pause", "resume", "step", "seek", "set_loop")
POLL_MS = 100


def playback_of(source):
    """`source` if it is a playback source (pause/step/seek/loop), else None."""
    if source is None:
        return None
    try:
        return source if all(hasattr(source, a) for a in _CONTROLS) else None
    except Exception:  # noqa: BLE001 - a property of a closed source may raise
        return None


class PlaybackBar(QWidget):
    """Playback controls bound to the context's frame worker source. `used` is emitted when the
    user moves playback (a paused view then resumes, or the step would not be seen)."""

    used = Signal()

    def __init__(self, ctx, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._source = None

        def button(text: str, tip: str) -> QToolButton:
            b = QToolButton()
            b.setText(text)
            b.setToolTip(tip)
            return b

        self.play_button = button("Pause", "Play or pause the recording")
        self.play_button.setMinimumWidth(64)
        self.back_button = button("◀ 1", "One frame back (pauses)")
        self.forward_button = button("1 ▶", "One frame forward (pauses)")
        self.loop_check = QCheckBox("Loop")
        self.loop_check.setToolTip("Start again at the first frame after the last one")
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setToolTip("Position in the recording: drag to go to a frame")
        self.slider.setMinimum(0)
        self.label = QLabel("frame – of –")
        widest = "frame 00000 of 00000 (end)"
        self.label.setMinimumWidth(self.label.fontMetrics().horizontalAdvance(widest))
        self.title = QLabel("Playback:")
        self.title.setStyleSheet("font-weight: bold")
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        for w in (self.title, self.play_button, self.back_button, self.forward_button,
                  self.loop_check):
            row.addWidget(w)
        row.addWidget(self.slider, 1)
        row.addWidget(self.label)

        self.play_button.clicked.connect(self.toggle_play)
        self.back_button.clicked.connect(lambda: self.step(-1))
        self.forward_button.clicked.connect(lambda: self.step(1))
        self.loop_check.toggled.connect(self._loop_toggled)
        self.slider.valueChanged.connect(self._slider_moved)
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self.refresh)
        ctx.frames.sourceChanged.connect(lambda _name: self._source_changed())
        self._source_changed()

    # ---- binding ------------------------------------------------------------------------------
    def source(self):
        return self._source

    def _source_changed(self) -> None:
        self._source = playback_of(self.ctx.frames.source())
        self.setVisible(self._source is not None)
        if self._source is None:
            self._timer.stop()
            return
        n = int(self._source.frame_count)
        self.slider.blockSignals(True)
        self.slider.setMaximum(max(n - 1, 0))
        self.slider.setPageStep(max(1, n // 10))
        self.slider.blockSignals(False)
        self.loop_check.blockSignals(True)
        self.loop_check.setChecked(bool(getattr(self._source, "loop", True)))
        self.loop_check.blockSignals(False)
        self._timer.start()
        self.refresh()

    # ---- controls -----------------------------------------------------------------------------
    def toggle_play(self) -> None:
        s = self._source
        if s is None:
            return
        if s.paused:
            s.resume()
        else:
            s.pause()
        self.used.emit()
        self.refresh()

    def step(self, n: int) -> int | None:
        """Pause and move `n` frames; return the new position (0-based)."""
        s = self._source
        if s is None:
            return None
        pos = s.step(n)
        self.used.emit()
        self.refresh()
        return pos

    def seek(self, i: int) -> int | None:
        s = self._source
        if s is None:
            return None
        pos = s.seek(i)
        self.used.emit()
        self.refresh()
        return pos

    def _slider_moved(self, value: int) -> None:
        if self._source is not None and value != self._source.position:
            self.seek(value)

    def _loop_toggled(self, on: bool) -> None:
        if self._source is not None:
            self._source.set_loop(on)

    def refresh(self) -> None:
        """Show the source's position and state."""
        s = self._source
        if s is None:
            return
        try:
            n, pos, paused = int(s.frame_count), int(s.position), bool(s.paused)
            finished = bool(getattr(s, "finished", False))
        except Exception:  # noqa: BLE001 - the source may have been closed meanwhile
            return
        self.play_button.setText("Play" if paused else "Pause")
        end = " (end)" if finished else ""
        self.label.setText(f"frame {pos + 1} of {n}{end}")
        if not self.slider.isSliderDown() and self.slider.value() != pos:
            self.slider.blockSignals(True)
            self.slider.setValue(pos)
            self.slider.blockSignals(False)
