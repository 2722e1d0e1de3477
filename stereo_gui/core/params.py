"""Parameters declared once: each field of a parameter dataclass carries a `Param` (its range,
unit, choices, help and the panel's offer) in its metadata, and everything that reads, checks or
shows the field is made from that: the dataclass's own validation (`check_all`), reading from
JSON (`convert`, `from_json`), the command line's argument types and the parameter panel's
widgets. Validation runs when an object is built, never when it is used.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from stereo_gui.core.errors import InputError

_NONE = type(None)
_T = TypeVar("_T")


@dataclass(frozen=True)
class Param:
    """What a field holds and what it means. `lo`/`hi` bound a number (inclusive), `choices` a
    text; `odd` asks for an odd whole number (`zero_off`: 0 too, meaning "none"); `check` is one
    more test of a value of the right type, `check_text` what it asks for. `label` is the name a
    person sees (default the field's), `panel` = (lo, hi, step) what the parameter panel offers
    (narrower than what files may hold). `name`, `type` and `default` are filled in from the
    dataclass field by `params_of`."""

    lo: float | None = None
    hi: float | None = None
    unit: str = ""
    help: str = ""
    choices: tuple[str, ...] = ()
    odd: bool = False
    zero_off: bool = False
    check: Callable[[Any], bool] | None = None  # (given a value of the field's type)
    check_text: str = ""
    label: str = ""
    panel: tuple[float, float, float] | None = None
    name: str = ""
    type: object = None
    default: object = None

    # ---- the type ------------------------------------------------------------------------
    @property
    def optional(self) -> bool:
        """None is a value of the field ("not set")."""
        return _NONE in typing.get_args(self.type)

    @property
    def base(self) -> object:
        """The field's type without None."""
        args = [a for a in typing.get_args(self.type) if a is not _NONE]
        if typing.get_origin(self.type) in (typing.Union, types.UnionType) and len(args) == 1:
            return args[0]
        return self.type

    # ---- words ---------------------------------------------------------------------------
    def wants(self) -> str:
        """What a value must be, in words ("an odd whole number from 1 to 51")."""
        tp = self.base
        unit = f" {self.unit}" if self.unit else ""
        if tp is bool:
            return "true or false"
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.check_text:
            return self.check_text
        if tp is str:
            return "text"
        if tp in (int, float):
            what = ("an odd whole number" if self.odd else "a whole number") if tp is int \
                else "a number"
            if self.lo is not None and self.hi is not None:
                lo = 1 if self.zero_off and self.lo == 0 else self.lo
                what += f" from {_num(lo, tp)} to {_num(self.hi, tp)}{unit}"
            if self.zero_off:
                what += " (or 0: none)"
            return what
        return describe_type(tp)

    # ---- checks --------------------------------------------------------------------------
    def problem(self, value: object) -> str | None:
        """Why `value` (of the field's type already) is not a value of this field, or None."""
        if value is None:
            return None if self.optional else f"{self.name} must be {self.wants()}, not None"
        tp = self.base
        bad = f"{self.name} must be {self.wants()}, not {value!r:.40}"
        if tp in (int, float):
            if isinstance(value, bool) or not isinstance(value, int | float):
                return bad
            if isinstance(value, float) and not math.isfinite(value):
                return bad
            if self.lo is not None and not self.lo <= value:
                return bad
            if self.hi is not None and not value <= self.hi:
                return bad
            if self.odd and value % 2 != 1 and not (self.zero_off and value == 0):
                return bad
        elif tp is bool and not isinstance(value, bool):
            return bad
        elif tp is str and not isinstance(value, str):
            return bad
        if self.choices and value not in self.choices:
            return bad
        if self.check is not None and not self.check(value):
            return bad
        return None

    def argparse_type(self) -> Callable[[str], object]:
        """An argparse type for the field: its words in the one line a bad value gives."""
        tp = self.base

        def parse(text: str) -> object:
            try:
                value = _PARSERS[tp](text) if tp in _PARSERS else None
            except ValueError:
                raise argparse.ArgumentTypeError(f"{self.wants()}, not {text[:40]!r}") from None
            why = self.problem(value)
            if why is not None:
                raise argparse.ArgumentTypeError(f"{self.wants()}, not {text[:40]}")
            return value

        parse.__name__ = _PARSED_NAMES.get(tp, "value")
        return parse


# what the command line's argument types convert a word with, and call it
_PARSERS: dict[object, Callable[[str], object]] = {int: int, float: float, str: str}
_PARSED_NAMES: dict[object, str] = {int: "whole number", float: "number"}


def param(default: _T, **info: Any) -> _T:
    """A dataclass field declared with its `Param` (keywords as Param's). Typed as its default
    (as `dataclasses.field` is), so that the field's annotation is checked against it."""
    return field(default=default, metadata={"param": Param(**info)})


_PARAMS_OF: dict[type, Mapping[str, Param]] = {}  # params_of's answers, by class


def params_of(cls: type) -> Mapping[str, Param]:
    """Each field of dataclass `cls` by name, with its Param completed (name, type, default)."""
    known = _PARAMS_OF.get(cls)
    if known is not None:
        return known
    hints = typing.get_type_hints(cls)
    out: dict[str, Param] = {}
    for f in dataclasses.fields(cls):
        info = f.metadata.get("param", Param())
        out[f.name] = dataclasses.replace(info, name=f.name, type=hints[f.name],
                                          default=f.default)
    return _PARAMS_OF.setdefault(cls, types.MappingProxyType(out))


def check_all(obj: object, what: str = "") -> None:
    """Raise InputError listing every field of `obj` (a dataclass of Param fields) whose value
    is not one of its field's; `what` names the object in front of the message."""
    problems = [p for p in (spec.problem(getattr(obj, name))
                            for name, spec in params_of(type(obj)).items()) if p]
    if problems:
        raise InputError((f"{what}: " if what else "") + "; ".join(problems))


def from_json(cls: type, data: Mapping[str, object], where: str, whole_floats: bool = True
              ) -> dict[str, Any]:
    """Keyword arguments for `cls` from parsed JSON values of its fields (keys not of `cls`
    are not looked at); InputError naming `where` for a value of the wrong type."""
    specs = params_of(cls)
    kwargs: dict[str, Any] = {}  # (JSON's values, converted to the fields' types)
    for key, raw in data.items():
        spec = specs.get(key)
        if spec is None:
            continue
        try:
            kwargs[key] = convert(raw, spec.type, whole_floats)
        except TypeError:
            tp = spec.base
            if tp is bool:
                raise InputError(f"{where}: {key} must be true or false") from None
            if tp is str:
                raise InputError(f"{where}: {key} must be a string") from None
            if tp is int and isinstance(raw, float) and not isinstance(raw, bool):
                raise InputError(f"{where}: {key} must be a whole number, not {raw}") from None
            raise InputError(f"{where}: {key} must be a number, not {raw!r:.40}") from None
    return kwargs


def convert(value: object, tp: object, whole_floats: bool = False) -> object:
    """`value` (parsed JSON) converted to type `tp` (bool, int, float, str, tuples, X | None),
    or raise TypeError. A bool is never a number; with `whole_floats` a float with no fraction
    is an int."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and _NONE in args:
            return None
        for a in args:
            if a is _NONE:
                continue
            try:
                return convert(value, a, whole_floats)
            except TypeError:
                pass
        raise TypeError
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list | tuple):
            raise TypeError
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(convert(v, args[0], whole_floats) for v in value)
        if len(value) != len(args):
            raise TypeError
        return tuple(convert(v, a, whole_floats) for v, a in zip(value, args, strict=True))
    if tp is bool:
        if not isinstance(value, bool):
            raise TypeError
        return value
    if tp is int:
        if whole_floats and isinstance(value, float) and value.is_integer():
            return int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TypeError
        try:
            return float(value)
        except OverflowError:  # a whole number of 400 digits: as large as a float goes, which
            return math.inf if value > 0 else -math.inf  # every range refuses by its name
    if tp is str:
        if not isinstance(value, str):
            raise TypeError
        return value
    raise TypeError


def _num(v: float, tp: object) -> str:
    """A bound as said to a person: a whole number's in full, a number's short (1e+07)."""
    return str(int(v)) if tp is int else f"{v:g}"


def describe_type(tp: object) -> str:
    """A type as a person reads it ("int", "tuple[str, ...]", "str | None")."""
    return str(tp).replace("typing.", "").replace("<class '", "").replace("'>", "")
