"""State machines' tables: each state of an enum with the states it may move to, so that a move
no one planned for is refused where it is made instead of showing up later as a wrong label.

Used by every state machine of the application (the frame worker's stream, a background job,
the Capture tab, closing the window); no Qt.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import Enum
from typing import Generic, TypeVar

S = TypeVar("S", bound=Enum)


class TransitionError(RuntimeError):
    """A move its table does not allow: a bug in the code that asked for it."""


class Transitions(Generic[S]):
    """The moves of one state machine: `moves[a]` holds every state `a` may become (`a` itself
    only where staying is a move, e.g. showing another saved pair). Every state of the enum has
    a row; a state with an empty row is final."""

    def __init__(self, name: str, moves: Mapping[S, Iterable[S]]) -> None:
        self.name = name
        self._moves: dict[S, frozenset[S]] = {a: frozenset(b) for a, b in moves.items()}
        states = {s for row in (self._moves, *self._moves.values()) for s in row}
        enum = type(next(iter(states)))
        missing = [s.name for s in enum if s not in self._moves]
        if missing or any(type(s) is not enum for s in states):
            raise ValueError(f"{name}: every {enum.__name__} needs a row (missing: {missing})")

    def allows(self, state: S, to: S) -> bool:
        return to in self._moves[state]

    def targets(self, state: S) -> frozenset[S]:
        """The states `state` may become."""
        return self._moves[state]

    def check(self, state: S, to: S) -> S:
        """`to`, if `state` may become it; else TransitionError."""
        if not self.allows(state, to):
            raise TransitionError(f"{self.name}: {state.name} cannot become {to.name}")
        return to
