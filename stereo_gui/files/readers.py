"""Reading our JSON and CSV files, with errors that name the file."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

from stereo_gui.core.errors import InputError


def read_json_object(path: str | os.PathLike, what: str) -> dict:
    """The JSON object in `path`; InputError naming `what` and the file if it cannot be read,
    is not JSON or holds something other than an object."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror or exc}") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path} is not valid JSON: {exc}") from exc
    if not isinstance(doc, dict):
        raise InputError(f"{what} {path} does not hold a JSON object")
    return doc


def read_csv_rows(path: str | os.PathLike, columns: tuple[str, ...], what: str) -> list[list[str]]:
    """The rows after the header of the UTF-8 CSV file `path`; InputError naming `what` and the
    file if it cannot be read or its first row is not `columns`."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from exc
    if not rows or tuple(rows[0]) != tuple(columns):
        raise InputError(f"{path} is not {what} (its first row is not {', '.join(columns)})")
    return rows[1:]
