"""Reading our JSON and CSV files, with errors that name the file."""

from __future__ import annotations

import csv
import json
import logging
import os
import shutil
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import os_error_text

log = logging.getLogger(__name__)

MAX_JSON_BYTES = 64 << 20  # none of our JSON files comes near this
UNREADABLE_SUFFIX = ".unreadable"


def _aside_name(path: Path) -> Path:
    """`<name>.unreadable`, or `<name>.unreadable.2`, .3, ... when that is taken: a copy set
    aside before is never replaced."""
    aside = path.with_name(path.name + UNREADABLE_SUFFIX)
    n = 2
    while aside.exists():
        aside = path.with_name(f"{path.name}{UNREADABLE_SUFFIX}.{n}")
        n += 1
    return aside


def set_aside(path: str | os.PathLike[str]) -> Path | None:
    """Rename a remembered file that cannot be used to `<name>.unreadable` (numbered when one is
    there already), so that the next save does not overwrite what a person may still want;
    return the new path, or None when it could not be renamed (the reason is logged)."""
    return _put_aside(Path(path), os.rename)


def copy_aside(path: str | os.PathLike[str]) -> Path | None:
    """Copy a remembered file used only in part to `<name>.unreadable` (numbered), before the
    next save writes it without what was left out; the copy's path, or None (logged)."""
    return _put_aside(Path(path), shutil.copy2)


def _put_aside(path: Path, how: Callable[[Path, Path], object]) -> Path | None:
    aside = _aside_name(path)
    try:
        how(path, aside)
    except OSError as exc:
        log.info("cannot keep %s aside: %s", path, os_error_text(exc))
        return None
    return aside


def read_user_text(path: str | os.PathLike[str], what: str, max_bytes: int = MAX_JSON_BYTES) -> str:
    """The UTF-8 text of the regular file `path`, at most `max_bytes`; InputError naming `what`
    for a device, a pipe or a folder (/dev/zero never ends, a FIFO waits for ever), a file too
    large, or a name the system cannot take. UnicodeDecodeError for text that is not UTF-8."""
    path = Path(path)
    try:
        st = path.stat()
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{what} {path} is not a regular file (a folder, a device or a "
                             "pipe)")
        if st.st_size > max_bytes:
            raise InputError(f"{what} {path} is too large ({st.st_size} bytes) to be one")
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {os_error_text(exc)}") from exc
    if len(data) > max_bytes:
        raise InputError(f"{what} {path} is too large to be one")
    return data.decode("utf-8")


def read_json_object(path: str | os.PathLike[str], what: str) -> dict[str, Any]:
    """The JSON object in `path`; InputError naming `what` and the file if it cannot be read,
    is not JSON or holds something other than an object."""
    path = Path(path)
    try:
        doc = json.loads(read_user_text(path, what))  # (a file that cannot be read: InputError)
    except RecursionError:
        raise InputError(f"{what} {path} is nested too deeply to be one") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path} is not valid JSON: {exc}") from exc
    except ValueError:  # Python refuses integer literals of more than 4300 digits
        raise InputError(f"{what} {path} holds an integer too long to be a number") from None
    if not isinstance(doc, dict):
        raise InputError(f"{what} {path} does not hold a JSON object")
    return doc


def read_csv_rows(path: str | os.PathLike[str], columns: tuple[str, ...],
                  what: str) -> list[list[str]]:
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
