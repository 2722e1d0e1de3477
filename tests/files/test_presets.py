"""Matcher presets: built-ins from resources/presets, the user's own in the settings folder."""

import json
import os
from pathlib import Path

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import Preset
from stereo_gui.files.presets import (
    BUILTIN,
    delete_user_preset,
    list_presets,
    load_preset,
    load_presets,
    save_user_preset,
    user_preset_dir,
)


def test_seed_is_exactly_the_reference_loops_matcher():
    preset = load_preset("seed")
    p = preset.matcher
    assert (p.block_size, p.min_disparity, p.num_disparities) == (3, 2, 128)
    assert (p.uniqueness_ratio, p.speckle_window_size, p.speckle_range, p.disp12_max_diff) == (10, 100, 32, 5)
    assert (p.p1_value, p.p2_value) == (8 * 3 * 3**2, 32 * 3 * 3**2)
    assert p.mode == "sgbm" and p.closing_kernel == 3 and p.wls
    assert (p.wls_lambda, p.wls_sigma) == (80000.0, 1.8)
    assert p.scale == 1.0 and not preset.threads.parallel and p.z_min_mm is None
    assert (preset.display.colormap, preset.display.color_range) == ("ocean", "minmax")


def test_builtin_presets_load_and_differ():
    ps = {n: load_preset(n) for n in BUILTIN}
    assert {p.name for p in ps.values()} == set(BUILTIN)
    live = ps["live"]
    assert live.matcher.scale < 1.0 and live.threads.parallel and live.matcher.mode == "3way"
    assert ps["quality"].matcher.scale == 1.0
    assert list_presets()[:3] == list(BUILTIN)


def test_user_presets_live_in_the_settings_folder(_isolated_config):
    assert user_preset_dir() == Path(os.environ["STEREO_GUI_CONFIG_DIR"]) / "presets"
    mine = load_preset("live").replace(block_size=7, description="wider window")
    path = save_user_preset(mine, "wide")
    assert path.parent == _isolated_config / "presets"
    doc = json.loads(path.read_text())
    assert doc["format_version"] == 1 and doc["params"]["block_size"] == 7
    back = load_preset("wide")
    assert back == mine.replace(name="wide")
    assert "wide" in list_presets()
    delete_user_preset("wide")
    assert "wide" not in list_presets()


def test_builtin_names_are_protected():
    with pytest.raises(InputError, match="built-in"):
        save_user_preset(Preset(), "live")
    with pytest.raises(InputError, match="built-in"):
        delete_user_preset("seed")
    with pytest.raises(InputError, match="name"):
        save_user_preset(Preset(), "../evil")


def test_unknown_and_corrupt_presets_are_clear_errors(_isolated_config, caplog):
    with pytest.raises(InputError, match="unknown preset 'nope'.*live"):
        load_preset("nope")
    folder = _isolated_config / "presets"
    folder.mkdir()
    (folder / "broken.json").write_text("{")
    with pytest.raises(InputError, match="broken.json.*not valid JSON"):
        load_preset("broken")
    (folder / "typo.json").write_text(json.dumps({"params": {"block_size": 5, "blok": 3}}))
    assert load_preset("typo").matcher.block_size == 5
    assert "blok" in caplog.text
    (folder / "bad.json").write_text(json.dumps({"params": {"block_size": 4}}))
    with pytest.raises(InputError, match="block_size"):
        load_preset("bad")
    (folder / "future.json").write_text(json.dumps({"format_version": 99, "params": {}}))
    with pytest.raises(InputError, match="format version"):
        load_preset("future")


def test_a_presets_folder_that_cannot_be_read_is_said_as_such(_isolated_config, monkeypatch):
    """A presets folder without permission to look in (mode 000, tried as a user that is not
    root) said "unknown preset 'mine'" of a preset that is there; a name too long for the system
    is still no preset of that name."""
    from pathlib import Path

    folder = _isolated_config / "presets"
    folder.mkdir()
    (folder / "mine.json").write_text(json.dumps({"params": {}}))
    real = Path.is_file

    def is_file(self):
        if self.parent == folder:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "is_file", is_file)
    with pytest.raises(InputError, match=r"cannot read the presets folder .*'mine'.*Permission"):
        load_preset("mine")
    monkeypatch.undo()
    with pytest.raises(InputError, match="unknown preset"):
        load_preset("x" * 300)


def test_a_preset_file_path_works(tmp_path):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({"name": "mine", "params": {"mode": "3way"}}))
    assert load_preset(str(path)).matcher.mode == "3way"


def test_presets_for_a_table_are_labelled_by_their_own_names(tmp_path):
    """A file's preset is labelled by the name inside it; where two share a name, by what was
    given (a built-in's name or the file's path)."""
    mine, twin = tmp_path / "mine.json", tmp_path / "twin.json"
    mine.write_text(json.dumps({"name": "wider", "params": {"block_size": 7}}))
    twin.write_text(json.dumps({"name": "live", "params": {"block_size": 9}}))
    got = load_presets(["live", str(mine), "live"])
    assert list(got) == ["live", "wider"] and got["wider"].matcher.block_size == 7
    got = load_presets(["live", str(twin)])
    assert list(got) == ["live", str(twin)] and got[str(twin)].matcher.block_size == 9
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps({"name": "plain@live", "params": {}}))
    assert list(load_presets([str(mine), str(odd)], reserved=("plain",))) == ["wider", str(odd)]


OLD_USER_PRESET = {  # a user preset as saved before the display and thread fields had parts
    "format_version": 1, "name": "mine", "description": "old",
    "params": {"block_size": 5, "min_disparity": 2, "num_disparities": 128, "z_min_mm": None,
               "z_max_mm": None, "uniqueness_ratio": 10, "speckle_window_size": 100,
               "speckle_range": 32, "disp12_max_diff": 5, "p1": None, "p2": None,
               "pre_filter_cap": 63, "mode": "sgbm", "check_block_size": 0, "agree_px": 1.0,
               "range_end_px": 0.0, "normalize_window": 0, "full_frame": True,
               "remap_interpolation": "linear", "closing_kernel": 3, "wls": True,
               "wls_lambda": 80000.0, "wls_sigma": 1.8, "wls_full_resolution": True,
               "wls_confident_only": True, "wls_disables_checks": False, "check_scale": 1.0,
               "bilateral": False, "bilateral_d": 5, "bilateral_sigma_color": 25.0,
               "bilateral_sigma_space": 5.0, "scale": 1.0, "max_match_width": None,
               "colormap": "jet", "color_range": "fixed", "color_z_near_mm": 400.0,
               "color_z_far_mm": 2000.0, "parallel": True, "cv_threads": 1}}


def test_a_preset_saved_before_the_split_loads_and_saves_as_it_was(_isolated_config):
    folder = _isolated_config / "presets"
    folder.mkdir()
    path = folder / "mine.json"
    path.write_text(json.dumps(OLD_USER_PRESET))
    p = load_preset("mine")
    assert (p.matcher.block_size, p.display.colormap, p.display.color_z_near_mm) == (5, "jet", 400)
    assert p.threads.parallel and p.threads.cv_threads == 1 and p.description == "old"
    path.unlink()
    save_user_preset(p, "mine")
    again = json.loads(path.read_text())
    # as it was, with the fields added since at their defaults (in their places)
    params = {}
    for key, value in OLD_USER_PRESET["params"].items():
        params[key] = value
        if key == "range_end_px":
            params["range_from_scene"] = False
        if key == "normalize_window":
            params["fill_scale"] = 0.0
            params["fill_modes"] = "3way"
        if key == "max_match_width":
            params["max_match_pixels"] = None
    assert again == {**OLD_USER_PRESET, "params": params}
    assert list(again["params"]) == list(params)  # the same order too
