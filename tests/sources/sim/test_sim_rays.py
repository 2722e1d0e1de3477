"""Ray maps: the inversion of OpenCV's distortion model is exact."""

from __future__ import annotations

import cv2
import numpy as np

from stereo_gui.sources.sim import (
    CameraTruth,
    ray_map,
    undistort_normalized,
)


def test_ray_map_inverts_the_distortion_model(rig):
    """Projecting the rays the rig renders with (ray_map of its cameras) with cv2.projectPoints
    gives back their sample positions."""
    c = rig.config
    for cam, (truth, M, D) in enumerate(((c.left, rig.truth.M1, rig.truth.D1),
                                         (c.right, rig.truth.M2, rig.truth.D2))):
        rays = ray_map(truth, c.image_size, c.supersample)
        s = rays.supersample
        rng = np.random.default_rng(cam)
        iy = rng.integers(0, rays.xy.shape[0], 300)
        ix = rng.integers(0, rays.xy.shape[1], 300)
        # include the far corners, where distortion is strongest
        iy = np.r_[iy, 0, 0, rays.xy.shape[0] - 1, rays.xy.shape[0] - 1]
        ix = np.r_[ix, 0, rays.xy.shape[1] - 1, 0, rays.xy.shape[1] - 1]
        xy = rays.xy[iy, ix].astype(np.float64)
        pts = np.concatenate([xy, np.ones((len(xy), 1))], 1)
        proj, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), M, D)
        expected = np.stack([(ix + 0.5) / s - 0.5, (iy + 0.5) / s - 0.5], 1)
        # float32 storage of the rays limits the round trip to about 1e-4 px
        assert np.abs(proj.reshape(-1, 2) - expected).max() < 1e-3


def test_newton_undistortion_matches_projectpoints():
    cam = CameraTruth.make(750, 748, 321, 238, k1=-0.3, k2=0.09, p1=1e-3, p2=-1e-3, k3=-0.02)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 639, 500), rng.uniform(0, 479, 500)
    x, y = undistort_normalized(u, v, cam.M, cam.D)
    proj, _ = cv2.projectPoints(np.stack([x, y, np.ones_like(x)], 1), np.zeros(3), np.zeros(3),
                                cam.M, cam.D)
    assert np.abs(proj.reshape(-1, 2) - np.stack([u, v], 1)).max() < 1e-6
