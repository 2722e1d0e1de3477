"""State machines' tables (core.states): a move not in the table is refused."""

from enum import Enum

import pytest

from stereo_gui.core.states import TransitionError, Transitions


class Light(Enum):
    RED = 1
    GREEN = 2
    BROKEN = 3


MOVES = Transitions("light", {Light.RED: {Light.GREEN, Light.BROKEN},
                              Light.GREEN: {Light.RED, Light.BROKEN},
                              Light.BROKEN: set()})


def test_a_move_in_the_table_is_allowed_and_one_not_in_it_refused():
    assert MOVES.allows(Light.RED, Light.GREEN)
    assert MOVES.check(Light.GREEN, Light.RED) is Light.RED
    assert MOVES.targets(Light.RED) == {Light.GREEN, Light.BROKEN}
    assert not MOVES.allows(Light.RED, Light.RED)  # staying is a move only where listed
    with pytest.raises(TransitionError, match="light: BROKEN cannot become GREEN"):
        MOVES.check(Light.BROKEN, Light.GREEN)


def test_a_table_without_a_row_for_every_state_is_refused():
    with pytest.raises(ValueError, match="BROKEN"):
        Transitions("light", {Light.RED: {Light.GREEN}, Light.GREEN: {Light.RED}})
