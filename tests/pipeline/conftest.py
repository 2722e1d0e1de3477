"""Fixtures of the pipeline tests."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="session")
def sim_rig():
    from stereo_gui.sources.sim import SimRig

    return SimRig(seed=0)


@pytest.fixture(scope="session")
def sim_rig_pair(sim_rig):
    """The demo scene rectified with the rig's true calibration: (left, right)."""
    import cv2

    from stereo_gui.sources.sim import Scene

    calib = sim_rig.true_calibration()
    left, right = sim_rig.render_scene(Scene.demo(), np.random.default_rng(1))
    m = calib.rectify_maps()
    return (cv2.remap(left, m.left_x, m.left_y, cv2.INTER_LINEAR),
            cv2.remap(right, m.right_x, m.right_y, cv2.INTER_LINEAR))
