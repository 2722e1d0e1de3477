"""The region box's line and alarm as a technician uses them: read while paused, the alarm's
words gone when the alarm is, and an alarm distance taken when typing is done."""

from __future__ import annotations

from PySide6.QtCore import Qt

from tests.qt.tabs.test_live_tab import LEFT_EDGE_REGION_LINE, _wall_live, region_median_mm


def test_a_paused_frame_reads_the_region_at_once(qtbot, ctx, live, sim_rig, wall_pair,
                                                 array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.set_paused(True)
    qtbot.wait(200)
    shown = live.frames_shown
    live.set_region((250, 180, 400, 300), alarm_m=1.0)
    # no frame came (paused), and the line reads the frame shown
    assert live.frames_shown == shown
    assert live.region_label.text().startswith("Region: nearest")
    assert region_median_mm(live) > 1400
    live.panels["depth"].show_region((10, 10, 40, 40))
    live.panels["depth"].regionChanged.emit((10, 10, 40, 40))  # dragged while paused
    assert live.region_label.text() == LEFT_EDGE_REGION_LINE


def test_the_alarm_words_go_when_the_alarm_ends(qtbot, ctx, live, sim_rig, wall_pair,
                                                array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    statuses = []
    ctx.statusMessage.connect(statuses.append)
    live.set_region((250, 180, 400, 300), alarm_m=2.0)  # the wall at 1.5 m: alarm
    qtbot.waitUntil(lambda: "ALARM" in live.region_label.text(), timeout=30000)
    assert statuses[-1].startswith("ALARM")
    live.alarm_spin.setValue(1.0)  # nothing nearer than 1 m now
    qtbot.waitUntil(lambda: "ALARM" not in live.region_label.text(), timeout=30000)
    assert statuses[-1].startswith("Alarm over: the nearest in the region is 1.")
    assert live.region_label.text().startswith("Region: nearest")


def test_an_alarm_distance_takes_effect_when_typing_is_done(qtbot, ctx, live):
    live.region_button.click()
    spin = live.alarm_spin
    spin.setValue(0.5)
    edit = spin.lineEdit()
    spin.setFocus()
    spin.selectAll()  # (the number, without the prefix and the unit)
    qtbot.keyClicks(edit, "1.2")
    assert spin.value() == 0.5  # "1" on the way to "1.2" is not an alarm distance
    qtbot.keyClick(edit, Qt.Key.Key_Return)
    assert spin.value() == 1.2 and ctx.settings.region_alarm_m == 1.2
