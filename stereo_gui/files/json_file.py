"""Reading the JSON documents our files hold, with errors that name the file."""

from __future__ import annotations

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
