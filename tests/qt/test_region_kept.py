"""The Live tab's region box and its alarm distance are kept across restarts."""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_the_region_and_its_alarm_are_back_after_a_restart(qtbot, sim_rig, tmp_path):
    """Region on, moved, alarm 0.75 m; quit; start: the same box and alarm, watched again;
    Region off, quit, start: no region."""
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.settings import Settings, save_settings
    from stereo_gui.qt.app import build_window

    calib = tmp_path / "rig.yaml"
    save_calibration(sim_rig.true_calibration(), calib)
    save_settings(Settings(source="sim", last_calibration=str(calib)))
    box = (100, 120, 300, 260)

    ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        live = window.live_tab
        assert not live.region_button.isChecked()
        live.region_button.click()
        live.panels["depth"].show_region(box)
        live.panels["depth"].regionChanged.emit(box)  # what the end of a drag sends
        live.alarm_spin.setValue(0.75)
    finally:
        window.close()

    ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        live = window.live_tab
        assert live.region_button.isChecked() and live.alarm_spin.isVisibleTo(live)
        assert live.panels["depth"].region() == box
        assert live.alarm_spin.value() == 0.75
        assert live.view_checks["depth"].isChecked()
        live.region_button.click()  # off
    finally:
        window.close()

    ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        assert not window.live_tab.region_button.isChecked()
        assert window.live_tab.panels["depth"].region() is None
        assert window.live_tab.alarm_spin.value() == 0.75  # the alarm distance is kept too
    finally:
        window.close()


def test_a_bad_remembered_region_is_reported_and_not_used(tmp_path):
    from stereo_gui.files.settings import load_settings, settings_path

    settings_path().parent.mkdir(parents=True, exist_ok=True)
    settings_path().write_text('{"format_version": 1, "region_box": [300, 10, 100, 50], '
                               '"region_alarm_m": -1}')
    settings, warnings = load_settings()
    assert settings.region_box == () and settings.region_alarm_m == 0.0
    assert any("region_box" in w for w in warnings) and any("region_alarm_m" in w for w in warnings)
