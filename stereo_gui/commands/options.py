"""Bounded option values for the subcommands: every count, size and seed has a range, said in
the one line a value outside it gives ("argument --frames: a whole number from 1 to 10000, not
99999999999999999999"), so that no value makes a command run for ever or fail deep inside."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

SEED_MAX = 2**32 - 1  # numpy's seeds are never negative, and 32 bits as OpenCV takes them


def whole(lo: int, hi: int) -> Callable[[str], int]:
    """An argparse type: a whole number from `lo` to `hi`."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"a whole number from {lo} to {hi}, not "
                                             f"{text[:40]!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"a whole number from {lo} to {hi}, not "
                                             f"{text[:40]}")
        return value

    parse.__name__ = "whole number"  # argparse names the type so in its own messages
    return parse


def number(lo: float, hi: float, unit: str = "") -> Callable[[str], float]:
    """An argparse type: a finite number from `lo` to `hi` (`unit` said after them)."""
    unit = f" {unit}" if unit else ""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"a number from {lo:g} to {hi:g}{unit}, not "
                                             f"{text[:40]!r}") from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"a number from {lo:g} to {hi:g}{unit}, not "
                                             f"{text[:40]}")
        return value

    parse.__name__ = "number"
    return parse


seed = whole(0, SEED_MAX)
