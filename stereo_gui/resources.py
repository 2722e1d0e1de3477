"""Where the files of resources/ (icons, presets, desktop entry) and the guide are at run time.

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


def guide_path() -> Path:
    """The technician's guide (Markdown, its pictures beside it): docs/ of a checkout, or
    `stereo_gui/_docs/` of an installed package and of the bundle."""
    installed = _HERE / "_docs" / "guide.md"
    return installed if installed.is_file() else _HERE.parent / "docs" / "guide.md"
