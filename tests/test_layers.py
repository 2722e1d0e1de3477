"""The layer contracts in pyproject.toml hold: core, sources, files, pipeline and commands never
import Qt, and every package is one the build installs."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_import_linter_contracts_hold():
    exe = shutil.which("lint-imports") or str(Path(sys.executable).parent / "lint-imports")
    if not Path(exe).exists():
        pytest.fail("import-linter is part of the test extras but lint-imports was not found")
    proc = subprocess.run([exe, "--no-cache"], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_qt_free_layers_import_without_qt():
    """Import every module of the Qt-free layers in a fresh interpreter and check no Qt got loaded."""
    code = (
        "import importlib, pkgutil, sys\n"
        "import stereo_gui.core, stereo_gui.sources, stereo_gui.files, stereo_gui.pipeline\n"
        "import stereo_gui.commands\n"
        "for pkg in (stereo_gui.core, stereo_gui.sources, stereo_gui.files, stereo_gui.pipeline,\n"
        "            stereo_gui.commands):\n"
        "    for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "        importlib.import_module(m.name)\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('PySide6', 'pyqtgraph', 'shiboken6')]\n"
        "assert not bad, bad\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_every_package_is_installed():
    """pyproject.toml lists the packages by name: a new sub-package left out of the list would
    work from the source tree and be missing from an installed copy."""
    import tomllib

    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {".".join(p.parent.relative_to(REPO).parts)
             for p in (REPO / "stereo_gui").rglob("__init__.py")}
    assert found - listed == set(), "packages missing from pyproject.toml"
