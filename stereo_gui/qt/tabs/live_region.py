"""The Live tab's watched region: a box on the colour view whose nearest and median distance
are shown every frame, with an alarm when anything in it is nearer than a set distance.

The processor measures the region in the frame worker (`pipeline.region`); here are its button,
alarm box and line, and what they hand to the processor."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import QCheckBox, QDoubleSpinBox, QLabel, QPushButton, QSizePolicy, QWidget

from stereo_gui.pipeline.live import LiveOutput, LiveProcessor
from stereo_gui.pipeline.readout import format_distance
from stereo_gui.pipeline.region import Region, RegionStats, region_stats
from stereo_gui.qt.widgets.image_view import ImagePanel

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext


class LiveRegion(QObject):
    """Owns the Region button, the alarm box and the region line. `panel` is the view carrying
    the box, `view_check` its Show box, `processor` returns the LiveProcessor in use (or None)."""

    def __init__(self, ctx: AppContext, owner: QWidget, panel: ImagePanel, view_check: QCheckBox,
                 processor: Callable[[], LiveProcessor | None],
                 output: Callable[[], LiveOutput | None]) -> None:
        super().__init__(owner)
        self.ctx = ctx
        self._panel = panel
        self._view_check = view_check
        self._processor = processor
        self._output = output  # the LiveOutput shown (None: none yet)
        self._alarm_on = False
        self.button = QPushButton("Region")
        self.button.setCheckable(True)
        self.button.setToolTip("A box on the colour view: its nearest and median distance "
                               "every frame, and an alarm when anything in it is nearer")
        self.button.toggled.connect(self._toggled)
        self.alarm_spin = QDoubleSpinBox()
        self.alarm_spin.setRange(0.0, 20.0)
        self.alarm_spin.setDecimals(2)
        self.alarm_spin.setSingleStep(0.05)
        self.alarm_spin.setSuffix(" m")
        self.alarm_spin.setPrefix("alarm < ")
        self.alarm_spin.setSpecialValueText("no alarm")
        self.alarm_spin.setToolTip("The region box turns red and the status bar says so when "
                                   "anything in it is nearer than this")
        # the distance takes effect when typing is done (Enter, leaving the box, the arrows),
        # not at "1" on the way to "1.2"
        self.alarm_spin.setKeyboardTracking(False)
        self.alarm_spin.valueChanged.connect(lambda _v: self.apply())
        self.alarm_spin.hide()
        self.label = QLabel()
        self.label.setTextFormat(Qt.TextFormat.PlainText)
        self.label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.label.hide()
        panel.regionChanged.connect(lambda _box: self.apply())
        ctx.measurement_log.activeFitChanged.connect(lambda _fit: self.apply())

    def restore(self) -> None:
        """The region and alarm of the last run (the settings); called once the button, the
        alarm box and the line are in the tab's layout."""
        s = self.ctx.settings
        if s is None:
            return
        if s.region_alarm_m:
            self.alarm_spin.setValue(s.region_alarm_m)
        if len(s.region_box) == 4:
            x0, y0, x1, y1 = s.region_box
            self.set_region((x0, y0, x1, y1))

    def _remember(self) -> None:
        """Keep the region and alarm in the settings, for the next run."""
        if self.ctx.settings is None:
            return
        box = self._panel.region() if self.button.isChecked() else None
        alarm = float(self.alarm_spin.value())
        kept = (tuple(box) if box else (), alarm)
        if kept != (tuple(self.ctx.settings.region_box), self.ctx.settings.region_alarm_m):
            self.ctx.settings_model.update(region_box=kept[0], region_alarm_m=alarm)

    def _toggled(self, on: bool) -> None:
        if on:
            if not self._view_check.isChecked():
                self._view_check.setChecked(True)
            w, h = self._panel.image_size() or (640, 480)
            self._panel.show_region((w * 3 // 8, h * 3 // 8, w * 5 // 8, h * 5 // 8))
        else:
            self._panel.show_region(None)
        self.alarm_spin.setVisible(on)
        self.label.setVisible(on)
        self.apply()

    def set_region(self, box: tuple[int, int, int, int] | None,
                   alarm_m: float | None = None) -> None:
        """Watch the box (x0, y0, x1, y1) px of the colour view (None: stop), with an alarm
        below `alarm_m` metres (None or 0: none)."""
        if alarm_m is not None:
            self.alarm_spin.setValue(alarm_m)
        if box is None:
            self.button.setChecked(False)
            return
        self.button.setChecked(True)
        self._panel.show_region(box)
        self.apply()

    def apply(self) -> None:
        """Hand the region, the alarm and the fit to the processor (from the next frame), and
        read the frame shown with them at once: a paused frame is a frame too."""
        self._remember()
        box = self._panel.region() if self.button.isChecked() else None
        alarm_mm = 1000.0 * self.alarm_spin.value() or None
        region = None if box is None else Region(*box)
        processor = self._processor()
        if processor is not None:
            processor.set_region(region, alarm_mm, self.ctx.active_fit)
        shown = self._output()
        if region is not None and shown is not None:
            self.show(region_stats(shown.result, region, alarm_mm, self.ctx.active_fit))

    def show(self, stats: RegionStats | None) -> None:
        """Show the region figures of the frame drawn (None: it has none)."""
        if stats is None or not self.button.isChecked():
            return
        if stats.note:
            text = f"Region: {stats.note}"
        else:
            text = (f"Region: nearest {format_distance(stats.nearest_mm)}   median "
                    f"{format_distance(stats.median_mm)}   {stats.valid_fraction:.0%} with depth")
        alarm_mm = stats.alarm_mm if stats.alarm else None  # (an alarm has its distance)
        if alarm_mm is not None:
            text += f"   ALARM: nearer than {format_distance(alarm_mm)}"
        self.label.setText(text)
        self.label.setStyleSheet("background: #c62828; color: white; font-weight: bold;"
                                 if stats.alarm else "")
        self._panel.set_region_alarm(stats.alarm)
        if alarm_mm is not None and not self._alarm_on:
            self.ctx.show_status(f"ALARM: something at {format_distance(stats.nearest_mm)} in "
                                 f"the region, nearer than {format_distance(alarm_mm)}")
        elif self._alarm_on and not stats.alarm:  # the alarm's words go with the alarm
            self.ctx.show_status("Alarm over: " + (
                stats.note if stats.note else
                f"the nearest in the region is {format_distance(stats.nearest_mm)}"))
        self._alarm_on = stats.alarm
