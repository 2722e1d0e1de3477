"""Fixtures of the simulated rig's tests."""

import pytest

from stereo_gui.sources.sim import SimRig


@pytest.fixture(scope="session")
def rig() -> SimRig:
    """One rig for every test of the package (building its ray maps takes a moment)."""
    return SimRig(seed=3)
