"""Parameters declared once: a field's Param is its validation, its JSON reading and its words."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_gui.core.errors import InputError
from stereo_gui.core.params import check_all, convert, param, params_of
from stereo_gui.core.preset import PRESET_PARAMS, MatcherParams, Preset


@dataclass(frozen=True)
class Example:
    window: int = param(3, lo=1, hi=9, odd=True, unit="px", help="a window")
    second: int = param(0, lo=0, hi=9, odd=True, zero_off=True)
    gain: float | None = param(None, lo=0.0, hi=2.0)
    mode: str = param("a", choices=("a", "b"))
    flag: bool = False
    size: tuple[int, int] = param((1, 2), check=lambda v: v[0] < v[1], check_text="a < b")

    def __post_init__(self) -> None:
        check_all(self, "example")


def test_a_declaration_knows_its_field():
    spec = params_of(Example)["window"]
    assert (spec.name, spec.type, spec.default, spec.unit, spec.help) == ("window", int, 3, "px",
                                                                         "a window")
    assert params_of(Example)["gain"].optional and not spec.optional
    assert spec.wants() == "an odd whole number from 1 to 9 px"
    assert params_of(Example)["second"].wants() == "an odd whole number from 1 to 9 (or 0: none)"


@pytest.mark.parametrize("changes,word", [
    ({"window": 4}, "window"), ({"window": 11}, "window"), ({"second": 2}, "second"),
    ({"gain": math.nan}, "gain"), ({"gain": 3.0}, "gain"), ({"mode": "c"}, "one of a, b"),
    ({"flag": 1}, "true or false"), ({"size": (2, 1)}, "a < b"), ({"window": True}, "window"),
])
def test_building_checks_every_declared_field(changes, word):
    with pytest.raises(InputError, match=word):
        Example(**changes)


def test_unset_and_zero_off_values_are_values():
    assert Example(gain=None, second=0).second == 0
    assert Example(second=5, gain=1.5).gain == 1.5


def test_json_values_convert_to_the_declared_type_or_not_at_all():
    assert convert([640, 480], tuple[int, int]) == (640, 480)
    assert convert(3, float) == 3.0 and isinstance(convert(3, float), float)
    assert convert(None, int | None) is None
    assert convert(5.0, int, whole_floats=True) == 5
    for value, tp in ((True, int), (1, bool), ("5", int), ([1], tuple[int, int]), (5.5, int),
                      (5.0, int)):
        with pytest.raises(TypeError):
            convert(value, tp)


def test_every_preset_parameter_is_declared_with_a_default_that_passes():
    assert set(PRESET_PARAMS) == set(Preset().to_dict()) - {"name", "description"}
    for key, spec in PRESET_PARAMS.items():
        assert spec.problem(spec.default) is None, key
        if spec.panel is not None:  # what the panel offers lies within what files may hold
            lo, hi, _step = spec.panel
            if key == "z_max_mm":
                lo = max(lo, spec.lo)  # the panel's 0 is "infinity": the unset value
            assert spec.lo <= lo and hi <= spec.hi, key


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3), max_leaves=6)


@settings(max_examples=300, derandomize=True, database=None, deadline=None)
@given(data=st.dictionaries(st.sampled_from(sorted(PRESET_PARAMS) + ["window_size", "other"]),
                            json_values, max_size=6))
def test_any_json_object_gives_a_preset_or_one_clear_error(data):
    try:
        preset = Preset.from_dict(data, where="fuzz")
    except InputError as exc:
        assert str(exc).startswith("fuzz: ")
        return
    assert Preset.from_dict(preset.to_dict()) == preset
    assert isinstance(preset.matcher, MatcherParams)
