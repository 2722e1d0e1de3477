"""Reading our JSON and CSV files, with errors that name the file."""

from __future__ import annotations

import csv
import json
import logging
import os
from pathlib import Path

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import os_error_text

log = logging.getLogger(__name__)

MAX_JSON_BYTES = 64 << 20  # none of our JSON files comes near this
UNREADABLE_SUFFIX = ".unreadable"


def set_aside(path: str | os.PathLike) -> Path | None:
    """Rename a remembered file that cannot be used to `<name>.unreadable` (replacing an older
    one), so that the next save does not overwrite what a person may still want; return the new
    path, or None when it could not be renamed (the reason is logged)."""
    path = Path(path)
    aside = path.with_name(path.name + UNREADABLE_SUFFIX)
    try:
        os.replace(path, aside)
    except OSError as exc:
        log.info("cannot set %s aside: %s", path, os_error_text(exc))
        return None
    return aside


def read_json_object(path: str | os.PathLike, what: str) -> dict:
    """The JSON object in `path`; InputError naming `what` and the file if it cannot be read,
    is not JSON or holds something other than an object."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_JSON_BYTES:
            raise InputError(f"{what} {path} is too large ({path.stat().st_size} bytes) to be one")
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {os_error_text(exc)}") from exc
    except RecursionError:
        raise InputError(f"{what} {path} is nested too deeply to be one") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path} is not valid JSON: {exc}") from exc
    except ValueError:  # Python refuses integer literals of more than 4300 digits
        raise InputError(f"{what} {path} holds an integer too long to be a number") from None
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
    except OSError as exc:
        raise InputError(f"cannot read {path}: {os_error_text(exc)}") from exc
    except UnicodeDecodeError as exc:
        raise InputError(f"cannot read {path}: it is not UTF-8 text ({exc})") from exc
    except csv.Error as exc:  # a field over csv's limit (128 KiB), a NUL byte, ...
        raise InputError(f"{path} is not {what}: {exc}") from exc
    if not rows or tuple(rows[0]) != tuple(columns):
        raise InputError(f"{path} is not {what} (its first row is not {', '.join(columns)})")
    return rows[1:]
