"""Where the files of resources/ (icons, presets, desktop entry) are at run time.

In a checkout they are in the repository's `resources/` folder; an installed package and the
PyInstaller bundle carry them as `stereo_gui/_resources/`.
"""

from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent


def resource_dir() -> Path:
    installed = _HERE / "_resources"
    if installed.is_dir():
        return installed
    return _HERE.parent / "resources"


def resource_path(*parts: str) -> Path:
    """Path of a file shipped in resources/, e.g. resource_path("presets", "live.json")."""
    return resource_dir().joinpath(*parts)
