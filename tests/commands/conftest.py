"""Fixtures shared by the command-line tests."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stereo_gui.sources.sim import Scene, SimRig

WALL_MM = 1500.0


@pytest.fixture(scope="module")
def wall_files(tmp_path_factory):
    """Raw left.png / right.png of a wall at WALL_MM from the simulated rig (seed 3) in a folder of
    their own: (folder, rig, scene, the rig's true calibration)."""
    d = tmp_path_factory.mktemp("wall")
    rig = SimRig(seed=3)
    scene = Scene.wall(WALL_MM)
    left, right = rig.render_scene(scene, np.random.default_rng(0))
    cv2.imwrite(str(d / "left.png"), left)
    cv2.imwrite(str(d / "right.png"), right)
    return d, rig, scene, rig.true_calibration()
