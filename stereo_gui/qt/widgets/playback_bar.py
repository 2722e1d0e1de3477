"""Playback controls for a recorded source (a recording, a folder of pairs, a side-by-side video):
play/pause, one frame back/forward, loop, speed, and a position bar (a click goes to that place)
with "frame i of N" and the recorded time.

The bar shows itself only while the frame worker's source is a playback source. The controls
call the source's thread-safe methods directly (they only set state under its lock; the reader
thread loads the frame); the position is polled a few times a second while shown.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSlider,
    QStyle,
    QStyleOptionSlider,
    QToolButton,
    QWidget,
)

from stereo_gui.qt.source_capabilities import playback_of

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext
    from stereo_gui.sources.playback import PlaybackSource

log = logging.getLogger(__name__)

POLL_MS = 100
SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)  # playback speeds offered, times the recorded pace


class SeekSlider(QSlider):
    """A horizontal slider that goes to the place clicked (a plain QSlider only pages towards
    it), then drags from there."""

    def value_at(self, x: float) -> int:
        """The value at widget x position `x` (px)."""
        opt = QStyleOptionSlider()
        self.initStyleOption(opt)
        groove = self.style().subControlRect(QStyle.ComplexControl.CC_Slider, opt,
                                             QStyle.SubControl.SC_SliderGroove, self)
        handle = self.style().subControlRect(QStyle.ComplexControl.CC_Slider, opt,
                                             QStyle.SubControl.SC_SliderHandle, self)
        span = max(1, groove.width() - handle.width())
        pos = int(round(x - groove.x() - handle.width() / 2))
        return QStyle.sliderValueFromPosition(self.minimum(), self.maximum(), pos, span,
                                              opt.upsideDown)

    def mousePressEvent(self, ev: QMouseEvent) -> None:  # noqa: N802 - Qt API
        if ev.button() == Qt.MouseButton.LeftButton:
            opt = QStyleOptionSlider()
            self.initStyleOption(opt)
            on_handle = self.style().hitTestComplexControl(
                QStyle.ComplexControl.CC_Slider, opt, ev.position().toPoint(), self) \
                == QStyle.SubControl.SC_SliderHandle
            if not on_handle:
                self.setValue(self.value_at(ev.position().x()))
        super().mousePressEvent(ev)


class PlaybackBar(QWidget):
    """Playback controls bound to the context's frame worker source. `used` is emitted when the
    user moves playback (a paused view then resumes, or the step would not be seen)."""

    used = Signal()

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._source: PlaybackSource | None = None

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
        self.speed_combo = QComboBox()
        for v in SPEEDS:
            self.speed_combo.addItem(f"{v:g}×", v)
        self.speed_combo.setCurrentIndex(SPEEDS.index(1.0))
        self.speed_combo.setToolTip("Playback speed (times the recorded pace)")
        self.slider = SeekSlider(Qt.Orientation.Horizontal)
        self.slider.setToolTip("Position in the recording: click or drag to go to a frame")
        self.slider.setMinimum(0)
        self.label = QLabel("frame – of –")
        widest = "frame 00000 of 00000 (end)"  # the time after it may push the slider
        self.label.setMinimumWidth(self.label.fontMetrics().horizontalAdvance(widest))
        self.title = QLabel("Playback:")
        self.title.setStyleSheet("font-weight: bold")
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        for w in (self.title, self.play_button, self.back_button, self.forward_button,
                  self.loop_check, self.speed_combo):
            row.addWidget(w)
        row.addWidget(self.slider, 1)
        row.addWidget(self.label)

        self.play_button.clicked.connect(self.toggle_play)
        self.back_button.clicked.connect(lambda: self.step(-1))
        self.forward_button.clicked.connect(lambda: self.step(1))
        self.loop_check.toggled.connect(self._loop_toggled)
        self.speed_combo.currentIndexChanged.connect(self._speed_chosen)
        self.slider.valueChanged.connect(self._slider_moved)
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self.refresh)
        ctx.frames.sourceChanged.connect(lambda _name: self._source_changed())
        self._source_changed()

    # ---- binding ------------------------------------------------------------------------------
    def source(self) -> PlaybackSource | None:
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
        self.loop_check.setChecked(self._source.loop)
        self.loop_check.blockSignals(False)
        self.speed_combo.setEnabled(True)
        self._speed_chosen()  # a new recording plays at the speed chosen
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

    def set_speed(self, speed: float) -> None:
        """Play at `speed` (one of SPEEDS) times the recorded pace."""
        i = self.speed_combo.findData(speed)
        if i >= 0:
            self.speed_combo.setCurrentIndex(i)

    def _speed_chosen(self, *_args: object) -> None:
        s = self._source
        if s is not None:
            s.set_speed(float(self.speed_combo.currentData()))

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
            finished = bool(s.finished)
        except Exception:  # noqa: BLE001 - the source may have been closed meanwhile
            return
        self.play_button.setText("Play" if paused else "Pause")
        end = " (end)" if finished else ""
        when = ""
        try:
            when = (f"   {s.time_s(pos):.3f} s of "
                    f"{s.time_s(n - 1):.1f} s" if n else "")
        except Exception:  # noqa: BLE001 - the source may have been closed meanwhile
            when = ""
        self.label.setText(f"frame {pos + 1} of {n}{end}{when}")
        if not self.slider.isSliderDown() and self.slider.value() != pos:
            self.slider.blockSignals(True)
            self.slider.setValue(pos)
            self.slider.blockSignals(False)
