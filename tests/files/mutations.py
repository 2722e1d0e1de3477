"""Hypothesis strategies that damage a valid file the way a disk, an editor or a hostile person
would, for the loaders' property tests (`test_fuzz_loaders.py`, `test_any_calibration_fuzz.py`).

`damaged(valid, doc)` draws a damaged copy of a file: its bytes cut, flipped, repeated, reversed
or given a hostile token or number; or, for a JSON file (`doc` its document), the document with
one value at any depth replaced by a hostile one (NaN, -1, 1e308, huge integers, lists where
objects belong, deep nesting, 128 KiB strings) or removed.
"""

from __future__ import annotations

import copy
import json
import re

from hypothesis import strategies as st

HOSTILE = [float("nan"), float("inf"), -1, 0, -0.0, 1e308, -1e308, 1e-300, 10**30, 99999999999,
           True, None, "", "x" * 131_073, [], {}, [[1]], {"a": 1}, "../../etc/passwd", "NaN"]
HOSTILE_TEXT = ["nan", ".nan", "-1", "0", "1e308", "-1e308", "1e-300", "99999999999", "[]",
                "{}", "[" * 200, "x" * 140_000, "\x00", "é€", "!!opencv-matrix", "rows: 4"]
HOSTILE_NUMBERS = HOSTILE_TEXT[:8]
_NUMBER = re.compile(r"-?\d+(\.\d+)?(e[-+]?\d+)?")
_DAMAGES = ("truncate", "flip", "repeat", "insert", "number", "reverse")


@st.composite
def damaged_bytes(draw, valid: bytes) -> bytes:
    """`valid` with one kind of damage."""
    b = bytearray(valid)
    n = len(b)
    kind = draw(st.sampled_from(_DAMAGES))
    if kind == "truncate" and n:
        return bytes(b[:draw(st.integers(0, n - 1))])
    if kind == "flip" and n:
        for i, value in draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, 255)),
                                      min_size=1, max_size=8)):
            b[i] = value
        return bytes(b)
    if kind == "repeat" and n:
        i = draw(st.integers(0, n - 1))
        j = min(n, i + draw(st.integers(1, 200)))
        return bytes(b[:j] + b[i:j] * draw(st.integers(1, 50)) + b[j:])
    if kind == "insert":
        i = draw(st.integers(0, n))
        return bytes(b[:i]) + draw(st.sampled_from(HOSTILE_TEXT)).encode() + bytes(b[i:])
    if kind == "number":
        text = b.decode("utf-8", "replace")
        numbers = list(_NUMBER.finditer(text))
        if numbers:
            m = numbers[draw(st.integers(0, len(numbers) - 1))]
            return (text[:m.start()] + draw(st.sampled_from(HOSTILE_NUMBERS))
                    + text[m.end():]).encode()
    return bytes(b[::-1])


def _places(doc, path=()) -> list[tuple]:
    """Every place a value sits in a JSON document (key paths), the document itself first."""
    out = [path]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _places(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _places(v, path + (i,))
    return out


@st.composite
def damaged_document(draw, doc):
    """A copy of the JSON document `doc` with one value replaced by a hostile one or removed, or
    (rarely) the whole document replaced."""
    doc = copy.deepcopy(doc)
    if draw(st.integers(0, 19)) == 0:
        return draw(st.sampled_from([[doc], "x", 1, None,
                                     {"deep": json.loads("[" * 500 + "]" * 500)}]))
    places = _places(doc)
    path = draw(st.sampled_from(places[1:] or places))
    if not path:
        return draw(st.sampled_from(HOSTILE))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if isinstance(parent, dict) and draw(st.integers(0, 6)) == 0:
        del parent[path[-1]]
    else:
        parent[path[-1]] = draw(st.sampled_from(HOSTILE))
    return doc


def damaged(valid: bytes, doc=None) -> st.SearchStrategy[bytes]:
    """Damaged copies of a file: its bytes; for a JSON file (`doc`), also its document."""
    if doc is None:
        return damaged_bytes(valid)
    as_bytes = damaged_document(doc).map(lambda d: json.dumps(d, allow_nan=True).encode())
    return st.one_of(as_bytes, damaged_bytes(valid))
