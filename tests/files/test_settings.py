"""Settings: round trip, isolation from the real user's folder, tolerance of bad files."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.files import settings as st
from stereo_gui.files.settings import Settings, load_settings, save_settings, settings_path


def test_settings_live_in_the_test_config_dir(_isolated_config):
    assert settings_path() == Path(_isolated_config) / "settings.json"
    assert os.environ["STEREO_GUI_CONFIG_DIR"] == str(_isolated_config)


def test_platformdirs_used_without_the_variable(monkeypatch):
    monkeypatch.delenv("STEREO_GUI_CONFIG_DIR")
    import platformdirs

    assert st.config_dir() == Path(platformdirs.user_config_dir("stereo-gui", appauthor=False))


def test_missing_file_gives_defaults_without_warnings():
    s, warnings = load_settings()
    assert s == Settings()
    assert warnings == []
    assert s.nominal_baseline_mm == 110.0
    assert s.resolution == (640, 480)


def test_round_trip_keeps_every_field():
    s = Settings(
        source="cams:1,2", resolution=(1280, 720), swap_lr=True, board_cols=7, board_rows=5,
        square_mm=30.5, nominal_baseline_mm=120.0, preset="seed", last_calibration="/x/calib.yaml",
        last_session="/x/session", window_geometry="AdnQywADAAA=", window_state="AAAA/wAA",
        recent_files=("/a.xlsx", "/b.yaml"), colormap="jet", patch_size=5, auto_capture=True,
        measure_model="cubic", visible_views=("wls", "raw"),
    )
    save_settings(s)
    loaded, warnings = load_settings()
    assert warnings == []
    assert loaded == s
    data = json.loads(settings_path().read_text())
    assert data["format_version"] == st.FORMAT_VERSION
    assert data["resolution"] == [1280, 720]


def test_save_creates_the_folder_and_leaves_no_temp_file(tmp_path):
    target = tmp_path / "deep" / "cfg" / "settings.json"
    save_settings(Settings(preset="seed"), target)
    assert [p.name for p in target.parent.iterdir()] == ["settings.json"]
    assert load_settings(target)[0].preset == "seed"


@pytest.mark.parametrize("content", ["{not json", "", "[1, 2]", "\xff\xfe garbage"])
def test_corrupt_file_is_reported_and_ignored(content, caplog):
    settings_path().write_text(content, encoding="latin-1")
    s, warnings = load_settings()
    assert s == Settings()
    assert len(warnings) == 1 and "defaults used" in warnings[0]
    assert any("settings" in r.getMessage() for r in caplog.records)


UNREADABLE = {
    "truncated": json.dumps({"format_version": 1, "preset": "quality"})[:20].encode(),
    "garbage": b"\x00\x13garbage{{{",
    "utf-16": json.dumps({"format_version": 1, "preset": "quality"}).encode("utf-16"),
    "deeply nested": b"[" * 100_000 + b"]" * 100_000,
    "5000 digits": b'{"format_version": 1, "patch_size": ' + b"1" * 5000 + b"}",
    "old version": b'{"format_version": 0, "preset": "quality"}',
}


@pytest.mark.parametrize("kind", sorted(UNREADABLE))
def test_an_unreadable_file_is_kept_aside_and_a_new_one_written_next_to_it(kind):
    """An unreadable settings file is kept aside, not overwritten with the defaults at exit."""
    data = UNREADABLE[kind]
    path = settings_path()
    path.write_bytes(data)
    s, warnings = load_settings()
    assert s == Settings() and len(warnings) == 1
    assert "kept as settings.json.unreadable" in warnings[0]
    aside = path.with_name("settings.json.unreadable")
    assert aside.read_bytes() == data and not path.exists()
    save_settings(s.with_updates(preset="seed"))  # what the window does at exit
    assert aside.read_bytes() == data and load_settings()[0].preset == "seed"


def test_a_newer_versions_file_is_not_set_aside():
    settings_path().write_text(json.dumps({"format_version": 99, "preset": "seed"}))
    load_settings()
    assert settings_path().exists() and not settings_path().with_name(
        "settings.json.unreadable").exists()


def test_a_settings_folder_that_is_a_file_is_said(tmp_path):
    folder = tmp_path / "cfg"
    folder.write_text("not a folder")
    s, warnings = load_settings(folder / "settings.json")
    assert s == Settings()
    assert len(warnings) == 1 and "is a file, not a folder" in warnings[0]


def test_unknown_version_is_reported_and_ignored():
    settings_path().write_text(json.dumps({"format_version": 99, "preset": "seed"}))
    s, warnings = load_settings()
    assert s == Settings()
    assert "format version 99" in warnings[0]


def test_unknown_keys_and_bad_values_are_skipped_one_by_one():
    settings_path().write_text(json.dumps({
        "format_version": 1,
        "preset": "seed",                 # good
        "swap_lr": "yes",                 # wrong type
        "resolution": [640],              # wrong shape
        "board_cols": 1,                  # wrong value
        "patch_size": 4,                  # even
        "square_mm": 30,                  # int is fine for a float
        "recent_files": ["/a", 3],        # wrong element type
        "last_calibration": None,         # None allowed
        "colour": "red",                  # unknown key
        "auto_capture": 1,                # an int is not a bool
    }))
    s, warnings = load_settings()
    assert s.preset == "seed"
    assert s.square_mm == 30.0 and isinstance(s.square_mm, float)
    assert s.swap_lr is False and s.resolution == (640, 480) and s.board_cols == 9
    assert s.patch_size == 9 and s.recent_files == () and s.auto_capture is False
    joined = "\n".join(warnings)
    for key in ("swap_lr", "resolution", "board_cols", "patch_size", "recent_files", "colour",
                "auto_capture"):
        assert key in joined
    assert len(warnings) == 7


def test_board_and_recent_helpers():
    s = Settings().with_board(BoardSpec(7, 5, 30.0))
    assert s.board == BoardSpec(7, 5, 30.0)
    s = s.with_recent("/a").with_recent("/b").with_recent("/a")
    assert s.recent_files == ("/a", "/b")
    s2 = Settings()
    for i in range(20):
        s2 = s2.with_recent(f"/f{i}")
    assert len(s2.recent_files) == st.RECENT_LIMIT and s2.recent_files[0] == "/f19"


def test_save_into_unwritable_place_raises_input_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError):
        save_settings(Settings(), blocker / "settings.json")


def test_failed_save_keeps_the_old_file(monkeypatch):
    save_settings(Settings(preset="seed"))
    before = settings_path().read_bytes()

    from disk_faults import install

    install(monkeypatch, "write")
    with pytest.raises(InputError, match="(?i)no space left"):
        save_settings(Settings(preset="live"))
    assert settings_path().read_bytes() == before
    assert [p.name for p in settings_path().parent.iterdir()] == ["settings.json"]


def test_a_bad_value_is_warned_about_in_its_declarations_words():
    settings_path().write_text(json.dumps({"format_version": 1, "patch_size": 4,
                                           "lens_model": "fish", "square_mm": 1e9}))
    s, warnings = load_settings()
    assert (s.patch_size, s.lens_model, s.square_mm) == (9, "pinhole", 25.0)
    joined = "\n".join(warnings)
    assert "'patch_size' should be an odd whole number from 1 to 101 px, found 4" in joined
    assert "'lens_model' should be one of pinhole, rational, fisheye" in joined
    assert "'square_mm' should be a number from" in joined and " mm, found 1000000000.0" in joined


def test_a_field_left_out_keeps_the_file_as_it_was_and_copies_are_numbered():
    """A setting of the wrong type is dropped (default used) and the next save writes the file
    without it: the file as it was is copied aside first, and a second copy never replaces the
    first."""
    from stereo_gui.files.settings import load_settings, settings_path

    path = settings_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    first = '{"format_version": 1, "square_mm": "twenty-five"}'
    path.write_text(first)
    settings, warnings = load_settings()
    assert "square_mm" in warnings[-1] and "kept as settings.json.unreadable" in warnings[-1]
    assert path.with_name("settings.json.unreadable").read_text() == first
    second = '{"format_version": 1, "patch_size": "big"}'
    path.write_text(second)
    _settings, warnings = load_settings()
    assert "settings.json.unreadable.2" in warnings[-1]
    assert path.with_name("settings.json.unreadable").read_text() == first
    assert path.with_name("settings.json.unreadable.2").read_text() == second
