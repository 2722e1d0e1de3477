"""The type checker passes: mypy over the whole package, strict on core/, files/ and pipeline/
(its settings are in pyproject.toml)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_mypy_finds_no_type_errors(tmp_path):
    exe = shutil.which("mypy") or str(Path(sys.executable).parent / "mypy")
    if not Path(exe).exists():
        pytest.fail("mypy is part of the test extras but was not found")
    # (a cache of its own: a stale one in the checkout could hide an error)
    proc = subprocess.run([exe, "--cache-dir", str(tmp_path / "cache")], cwd=REPO,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_core_files_and_pipeline_are_checked_strictly():
    """The strict override names the three layers whose types everything else relies on."""
    import tomllib

    mypy = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["mypy"]
    strict = [o for o in mypy["overrides"] if o.get("strict")]
    assert strict and set(strict[0]["module"]) >= {
        "stereo_gui.core.*", "stereo_gui.files.*", "stereo_gui.pipeline.*"}
