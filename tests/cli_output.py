"""What a command that refuses its input must print: one line, no traceback, exit status 2."""

from __future__ import annotations


def one_line(err: str, code: int, *words: str) -> str:
    """Check that `code` is 2 and `err` (what the terminal got on stderr) is one line holding
    every one of `words`, without a traceback; return that line."""
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]
