"""Saved distance fits (core.regression.FitResult) as JSON files."""

from __future__ import annotations

import os
from pathlib import Path

from stereo_gui.core.regression import FitResult, fit_from_dict, fit_to_dict
from stereo_gui.files.atomic import write_json_atomic
from stereo_gui.files.readers import read_json_object


def save_fit(fit: FitResult, path: str | os.PathLike[str]) -> Path:
    """Write the fit as JSON (atomically); returns the path."""
    return write_json_atomic(path, fit_to_dict(fit))


def load_fit(path: str | os.PathLike[str]) -> FitResult:
    """Read a fit saved by save_fit; any problem raises InputError naming the file."""
    return fit_from_dict(read_json_object(path, "fit file"), where=f"fit file {path}")
