"""Test set-up shared by every test: offscreen Qt, isolated settings and application data, the
shared data folder."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Qt must never try to open a display in tests, and tests never touch the real user's settings.
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ["STEREO_GUI_CONFIG_DIR"] = str(Path(__file__).parent / ".pytest-config-never-used")
os.environ["STEREO_GUI_DATA_DIR"] = str(Path(__file__).parent / ".pytest-data-never-used")

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(autouse=True)
def _isolated_config(tmp_path_factory, monkeypatch):
    """Point the application's settings folder at a fresh temporary folder for every test."""
    cfg = tmp_path_factory.mktemp("config")
    monkeypatch.setenv("STEREO_GUI_CONFIG_DIR", str(cfg))
    # the measurement log kept between runs lives in the application's data folder
    monkeypatch.setenv("STEREO_GUI_DATA_DIR", str(tmp_path_factory.mktemp("data")))
    yield cfg


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared folder of real images; tests that need it skip cleanly where it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is not present")
    return SHARED_DATA
