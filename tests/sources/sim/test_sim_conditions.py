"""The wall conditions: each webcam effect alone at half contrast, all of them together."""

from __future__ import annotations

import dataclasses

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim import RigConfig
from stereo_gui.sources.sim.conditions import CONDITIONS, condition_named

EFFECTS = ("gain_right", "black_right", "vignetting", "jpeg_quality")


def _effects(name):
    config = CONDITIONS[name].rig_config(RigConfig())
    return {k: getattr(config, k) for k in EFFECTS}


def test_each_single_effect_condition_is_half_contrast_with_that_effect_alone():
    half, webcams = _effects("half"), _effects("webcams")
    for name, changed in (("exposure", {"gain_right", "black_right"}),
                          ("vignetting", {"vignetting"}), ("mjpg", {"jpeg_quality"})):
        c = CONDITIONS[name]
        assert c.contrast == CONDITIONS["half"].contrast
        assert c.noise_sigma == CONDITIONS["half"].noise_sigma
        got = _effects(name)
        assert {k for k in EFFECTS if got[k] != half[k]} == changed
        assert all(got[k] == webcams[k] for k in changed)  # the same strength as in webcams


def test_a_condition_changes_only_the_sensor():
    base = RigConfig()
    config = CONDITIONS["webcams"].rig_config(base)
    kept = [f.name for f in dataclasses.fields(RigConfig)
            if f.name not in (*EFFECTS, "noise_sigma")]
    for name in kept:
        assert getattr(config, name) is getattr(base, name) or \
            getattr(config, name) == getattr(base, name)


def test_unknown_condition_names_the_choices():
    with pytest.raises(InputError, match="rig, weak, half, quarter, webcams"):
        condition_named("paint")
