"""Bounded option values for the subcommands: every count, size and seed has a range, said in
the one line a value outside it gives ("argument --frames: a whole number from 1 to 10000, not
99999999999999999999"), so that no value makes a command run for ever or fail deep inside.

The checks and their words are those of `core.params.Param`, the declaration every parameter
of the matcher, the presets and the settings has: an option that sets a declared parameter takes
its type from the declaration (`declared`), so the command line accepts exactly what a preset
file or the parameter panel does."""

from __future__ import annotations

from collections.abc import Callable

from stereo_gui.core.params import Param, params_of

SEED_MAX = 2**32 - 1  # numpy's seeds are never negative, and 32 bits as OpenCV takes them
MAX_PAIRS = 10_000  # the pairs of a calibration set: more than anyone needs


def whole(lo: int, hi: int) -> Callable[[str], object]:
    """An argparse type: a whole number from `lo` to `hi`."""
    return Param(lo=lo, hi=hi, type=int, name="value").argparse_type()


def number(lo: float, hi: float, unit: str = "") -> Callable[[str], object]:
    """An argparse type: a finite number from `lo` to `hi` (`unit` said after them)."""
    return Param(lo=lo, hi=hi, unit=unit, type=float, name="value").argparse_type()


def declared(cls: type, name: str) -> Callable[[str], object]:
    """An argparse type for field `name` of the parameter dataclass `cls` (MatcherParams,
    Settings, ...): its declared range, choices and words."""
    return params_of(cls)[name].argparse_type()


seed = whole(0, SEED_MAX)
