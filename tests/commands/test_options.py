"""Option types of the subcommands: a bad value is one line in the declaration's words."""

from __future__ import annotations

import argparse

import pytest

from stereo_gui.commands import options
from stereo_gui.core.matching import MatcherParams


@pytest.mark.parametrize("text,message", [
    ("0", "a whole number from 1 to 10000, not 0"),
    ("99999999999999999999", "a whole number from 1 to 10000, not 99999999999999999999"),
    ("1.5", "a whole number from 1 to 10000, not '1.5'"),
])
def test_whole_numbers_are_bounded(text, message):
    with pytest.raises(argparse.ArgumentTypeError) as err:
        options.whole(1, 10_000)(text)
    assert str(err.value) == message
    assert options.whole(1, 10_000)("17") == 17


def test_numbers_are_finite_and_bounded_with_their_unit():
    parse = options.number(0.5, 20.0, "m")
    assert parse("1.25") == 1.25
    for text in ("nan", "inf", "30"):
        with pytest.raises(argparse.ArgumentTypeError, match="a number from 0.5 to 20 m"):
            parse(text)


def test_seeds_say_their_whole_range():
    with pytest.raises(argparse.ArgumentTypeError, match=f"from 0 to {options.SEED_MAX},"):
        options.seed("-1")


def test_a_declared_parameter_takes_what_its_declaration_takes():
    parse = options.declared(MatcherParams, "num_disparities")
    assert parse("64") == 64
    with pytest.raises(argparse.ArgumentTypeError, match="a multiple of 16"):
        parse("100")  # the preset files and the panel refuse it too
    odd = options.declared(MatcherParams, "block_size")
    with pytest.raises(argparse.ArgumentTypeError, match="an odd whole number from 1 to 51"):
        odd("4")
