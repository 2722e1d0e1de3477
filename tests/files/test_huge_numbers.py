"""A number of 400 digits where a float belongs, in any file the application reads at start or
on request, is refused by name (or the default used, for the settings): never an OverflowError."""

from __future__ import annotations

import json

import pytest

from stereo_gui.core.errors import InputError

HUGE = "1" + "0" * 400  # JSON's integer 10**400: Python reads it, a float cannot hold it


@pytest.mark.parametrize("key", ["square_mm", "marker_mm", "nominal_baseline_mm",
                                 "region_alarm_m"])
def test_settings_with_a_huge_number_start_with_the_default(key):
    from stereo_gui.files.settings import Settings, load_settings, settings_path

    settings_path().parent.mkdir(parents=True, exist_ok=True)
    settings_path().write_text('{"format_version": 1, "%s": %s}' % (key, HUGE))
    settings, warnings = load_settings()
    assert getattr(settings, key) == getattr(Settings(), key)
    assert any(key in w and len(w) < 300 for w in warnings), warnings


def test_a_measurement_log_with_a_huge_true_distance_is_refused_by_name(tmp_path):
    from stereo_gui.files.measurement_log import load_log

    rec = {"time": "2026-01-01T00:00:00", "x_px": 1, "y_px": 2, "disparity_px": 30,
           "X_mm": 0, "Y_mm": 0, "Z_mm": 1000, "range_mm": 1000, "valid": True}
    path = tmp_path / "log.json"
    path.write_text(json.dumps({"format_version": 1, "records": [rec]})
                    .replace('"Z_mm": 1000', '"Z_mm": 1000, "true_mm": ' + HUGE))
    kept, warnings = load_log(path)  # (the log is set aside, and the window starts)
    assert kept.records == () and any("true_mm" in w for w in warnings)


@pytest.mark.parametrize("key", ["z_min_mm", "z_max_mm", "wls_lambda"])
def test_a_user_preset_with_a_huge_number_is_refused_by_name(tmp_path, key):
    from stereo_gui.files.presets import load_preset

    path = tmp_path / "p.json"
    path.write_text('{"params": {"%s": %s}}' % (key, HUGE))
    with pytest.raises(InputError, match=key):
        load_preset(str(path))


def test_camera_controls_with_a_huge_number_are_refused_by_name():
    from stereo_gui.core.camera_settings import PairSettings

    with pytest.raises(ValueError, match="focus"):
        PairSettings.from_json(json.loads('{"left": {"focus": %s}, "right": {}}' % HUGE))
