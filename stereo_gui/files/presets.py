"""Matcher presets: the built-in ones shipped in resources/presets/*.json, and the user's own,
saved as JSON in the settings folder's `presets/` sub-folder.

File format: {"format_version": 1, "name": ..., "description": ..., "params": {...}}, the params
one flat object of the matcher's, display's and threads' fields (`Preset.to_dict`).
A built-in name cannot be overwritten by a user preset.
"""

from __future__ import annotations

import errno
import logging
import os
import re
from collections.abc import Iterable
from pathlib import Path

import platformdirs

from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import Preset
from stereo_gui.files.atomic import write_json_atomic
from stereo_gui.files.readers import read_json_object
from stereo_gui.resources import resource_path

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
BUILTIN = ("seed", "live", "quality")
DEFAULT_PRESET = "live"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 _.-]{0,63}$")


def user_preset_dir() -> Path:
    """Folder of the user's presets (not created here)."""
    base = os.environ.get("STEREO_GUI_CONFIG_DIR")
    if base:
        return Path(base) / "presets"
    return Path(platformdirs.user_config_dir("stereo-gui")) / "presets"


def _read(path: Path) -> Preset:
    data = read_json_object(path, "preset")
    if not isinstance(data.get("params"), dict):
        raise InputError(f"preset {path} has no \"params\" object")
    version = data.get("format_version", FORMAT_VERSION)
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise InputError(f"preset {path} has format version {version!r}; this program reads "
                         f"up to {FORMAT_VERSION}")
    params = dict(data["params"])
    params["name"] = str(data.get("name", path.stem))
    params["description"] = str(data.get("description", ""))
    return Preset.from_dict(params, where=f"preset {path}")


def list_presets() -> list[str]:
    """Built-in names first, then the user's presets, alphabetically."""
    names = list(BUILTIN)
    folder = user_preset_dir()
    if folder.is_dir():
        names += sorted(p.stem for p in folder.glob("*.json") if p.stem not in BUILTIN)
    return names


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:  # a name too long for the system
        return False


def load_preset(name: str) -> Preset:
    """A preset by name (built-in or user), or from a path ending in .json."""
    if name.endswith(".json") and (os.sep in name or "/" in name or _is_file(Path(name))):
        return _read(Path(name))
    if name in BUILTIN:
        return _read(resource_path("presets", f"{name}.json"))
    path = user_preset_dir() / f"{name}.json"
    try:
        found = path.is_file()
    except OSError as exc:
        if exc.errno != errno.ENAMETOOLONG:  # a folder that cannot be read (permissions, ...)
            raise InputError(f"cannot read the presets folder {path.parent} for preset "
                             f"{name!r}: {exc.strerror or exc}") from None
        found = False  # a name the system cannot take: no preset of that name
    if found:
        return _read(path)
    raise InputError(f"unknown preset {name[:60]!r}; known presets: "
                     f"{', '.join(list_presets())}")


def load_presets(names: Iterable[str], reserved: tuple[str, ...] = ()) -> dict[str, Preset]:
    """`load_preset` of each name or path, labelled by the preset's own name (a file's path is
    no label for a table), or by what was given where two presets share a name or the name is
    one of the table's others (`reserved`, also as "name@...")."""
    loaded = [(n, load_preset(n)) for n in dict.fromkeys(names)]
    counts: dict[str, int] = {}
    for _, p in loaded:
        counts[p.name] = counts.get(p.name, 0) + 1

    def label(given: str, p: Preset) -> str:
        taken = p.name in reserved or p.name.startswith(tuple(f"{r}@" for r in reserved))
        return p.name if p.name and counts[p.name] == 1 and not taken else given

    return {label(n, p): p for n, p in loaded}


def save_user_preset(params: Preset, name: str | None = None) -> Path:
    """Save `params` as the user's preset `name` (default: params.name); returns the file."""
    name = name or params.name
    if not _NAME.match(name or ""):
        raise InputError(f"a preset name must be letters, digits, space, _ . - (not {name!r})")
    if name in BUILTIN:
        raise InputError(f"{name!r} is a built-in preset; save under another name")
    folder = user_preset_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the presets folder {folder}: {exc.strerror or exc}") from exc
    d = params.replace(name=name).to_dict()
    doc = {"format_version": FORMAT_VERSION, "name": name, "description": d.pop("description"),
           "params": {k: v for k, v in d.items() if k != "name"}}
    return write_json_atomic(folder / f"{name}.json", doc)


def delete_user_preset(name: str) -> None:
    if name in BUILTIN:
        raise InputError(f"{name!r} is a built-in preset and cannot be deleted")
    path = user_preset_dir() / f"{name}.json"
    if not path.is_file():
        raise InputError(f"no user preset named {name!r}")
    path.unlink()
