"""Option types of the subcommands: a bad value is one line in the declaration's words."""

from __future__ import annotations

import argparse

import pytest

from stereo_gui.commands import options
from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import MatcherParams


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


def test_no_option_of_any_command_takes_a_bare_int_or_float():
    """Every number on the command line is read through a declaration (its range in its
    words), never by argparse's plain int or float."""
    from stereo_gui import cli

    parsers = [("stereo-gui", cli._gui_parser())]
    parsers += [(name, cli._sub_parser(name)[0]) for name in cli.SUBCOMMANDS]
    bare = [(name, action.dest) for name, parser in parsers for action in parser._actions
            if action.type in (int, float)]
    assert bare == []


@pytest.mark.parametrize("command", ["calibrate", "simulate", "target"])
def test_the_board_options_say_what_the_board_declares(command):
    from stereo_gui import cli
    from stereo_gui.core.board import BoardSpec

    types = {a.dest: a.type for a in cli._sub_parser(command)[0]._actions}
    for dest, field, text, words in (
            ("square_mm", "square_mm", "0", "a number from 0.01 to 10000 mm, not 0"),
            ("marker_mm", "marker_mm", "-1", "a number from 0 to 10000 mm, not -1")):
        assert types[dest]("30") == 30.0
        with pytest.raises(argparse.ArgumentTypeError) as err:
            types[dest](text)
        assert str(err.value) == words
        with pytest.raises(InputError, match=f"{field} must be {words[:-len(text)]}"):
            BoardSpec(**{field: float(text)})  # a session's or the window's board alike


def test_alpha_is_refused_in_the_same_words_everywhere():
    """One declaration (StereoCalibration's alpha): the command line, calibrate_stereo and a
    calibration being built refuse the same values."""
    from stereo_gui.core.stereo_calibration import ALPHA, StereoCalibration

    parse = options.declared(StereoCalibration, "alpha")
    assert parse("0.5") == 0.5
    for text in ("-1", "1.5", "nan"):
        with pytest.raises(argparse.ArgumentTypeError, match="a number from 0 to 1"):
            parse(text)
        assert ALPHA.problem(float(text)) == f"alpha must be a number from 0 to 1, not {float(text)}"
