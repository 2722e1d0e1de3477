"""Scenes: depth along a ray."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.sources.sim import (
    Scene,
)


def test_scene_depth_along_ray():
    wall = Scene.wall(1000)
    assert wall.depth_along_ray([0, 0, 0], [0, 0, 1]) == pytest.approx(1000.0)
    d = np.array([0.3, 0.1, 1.0])
    assert wall.depth_along_ray([0, 0, 0], d) == pytest.approx(1000.0 * np.linalg.norm(d))
    assert wall.depth_along_ray([0, 0, 0], [0, 0, -1]) is None
    assert wall.depth_along_ray([0, 0, 0], [1, 0, 0.01]) is None  # misses the edge of the wall
    demo = Scene.demo()
    box = demo.objects[1]
    assert demo.depth_along_ray([0, 0, 0], box.center) == pytest.approx(np.linalg.norm(box.center))
    assert demo.depth_along_ray([0, 0, 0], [0.0, -0.3, 1.0]) > 2900  # the background wall
