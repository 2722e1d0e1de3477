"""The test suite's own set-up: the slow tests are left out of the default run and CI runs them."""

from __future__ import annotations

import shlex
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_the_default_run_leaves_the_slow_tests_to_ci():
    ini = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    args = shlex.split(ini["addopts"])
    assert args[args.index("-m") + 1] == "not slow"
    assert any(m.startswith("slow:") for m in ini["markers"])
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    readme = (REPO / "README.md").read_text()
    test_command = next(line for line in readme.splitlines() if line.endswith("-m pytest"))
    assert any(line.endswith(test_command) for line in ci)  # the README's own command
    assert ".venv/bin/python -m pytest -m slow" in ci
    assert "`.venv/bin/python -m pytest -m slow` runs them" in readme
