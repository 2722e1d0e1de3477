"""Matcher presets: built-ins from resources/presets, the user's own in the settings folder."""

import json
import os
from pathlib import Path

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import MatcherParams
from stereo_gui.files.presets import (BUILTIN, delete_user_preset, list_presets, load_preset,
                                      save_user_preset, user_preset_dir)


def test_seed_is_exactly_the_reports_matcher():
    p = load_preset("seed")
    assert (p.block_size, p.min_disparity, p.num_disparities) == (3, 2, 128)
    assert (p.uniqueness_ratio, p.speckle_window_size, p.speckle_range, p.disp12_max_diff) == (10, 100, 32, 5)
    assert (p.p1_value, p.p2_value) == (8 * 3 * 3**2, 32 * 3 * 3**2)
    assert p.mode == "sgbm" and p.closing_kernel == 3 and p.wls
    assert (p.wls_lambda, p.wls_sigma) == (80000.0, 1.8)
    assert p.scale == 1.0 and not p.parallel and p.z_min_mm is None
    assert (p.colormap, p.color_range) == ("ocean", "minmax")


def test_builtin_presets_load_and_differ():
    ps = {n: load_preset(n) for n in BUILTIN}
    assert {p.name for p in ps.values()} == set(BUILTIN)
    assert ps["live"].scale < 1.0 and ps["live"].parallel and ps["live"].mode == "3way"
    assert ps["quality"].scale == 1.0
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
        save_user_preset(MatcherParams(), "live")
    with pytest.raises(InputError, match="built-in"):
        delete_user_preset("seed")
    with pytest.raises(InputError, match="name"):
        save_user_preset(MatcherParams(), "../evil")


def test_unknown_and_corrupt_presets_are_clear_errors(_isolated_config, caplog):
    with pytest.raises(InputError, match="unknown preset 'nope'.*live"):
        load_preset("nope")
    folder = _isolated_config / "presets"
    folder.mkdir()
    (folder / "broken.json").write_text("{")
    with pytest.raises(InputError, match="broken.json.*not valid JSON"):
        load_preset("broken")
    (folder / "typo.json").write_text(json.dumps({"params": {"block_size": 5, "blok": 3}}))
    assert load_preset("typo").block_size == 5
    assert "blok" in caplog.text
    (folder / "bad.json").write_text(json.dumps({"params": {"block_size": 4}}))
    with pytest.raises(InputError, match="block_size"):
        load_preset("bad")
    (folder / "future.json").write_text(json.dumps({"format_version": 99, "params": {}}))
    with pytest.raises(InputError, match="format version"):
        load_preset("future")


def test_a_preset_file_path_works(tmp_path):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({"name": "mine", "params": {"mode": "3way"}}))
    assert load_preset(str(path)).mode == "3way"
