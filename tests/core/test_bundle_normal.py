"""The joint refinement's normal equations, formed from the Jacobian's block structure."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.bundle import View, _Problem


@pytest.mark.parametrize("model, fixed", [("pinhole", ()), ("pinhole", ("k3",)),
                                          ("rational", ("k5", "k6"))])
def test_the_normal_equations_are_the_dense_ones(model, fixed):
    """J^T J and J^T r summed view by view over the free parameters equal the dense products
    (the rational model's prior rows and held terms included); views with one side missing
    too."""
    rng = np.random.default_rng(1)
    obj = BoardSpec(cols=5, rows=4, square_mm=25.0).object_points_mm().astype(np.float64)
    nd = 8 if model == "rational" else 5
    views = []
    for k in range(6):
        img_l = rng.uniform(0, 640, (len(obj), 2))
        img_r = rng.uniform(0, 640, (len(obj), 2))
        views.append(View(obj, img_l, obj if k != 2 else obj[:0],
                          img_r if k != 2 else img_r[:0]))
    problem = _Problem.of(views, model, nd, fixed)
    cam = np.r_[600.0, 600.0, 320.0, 240.0, rng.normal(0, 0.01, nd)]
    rig = np.r_[0.01, -0.02, 0.005, -110.0, 0.5, 1.0]
    poses = np.concatenate([np.r_[rng.normal(0, 0.2, 3), rng.normal(0, 50, 2), 600.0]
                            for _ in views])
    x = np.r_[cam, cam, rig, poses]
    r, J = problem.with_jacobian(x)
    A, g = problem.normal_equations(J, r)
    Jf = J[:, problem.free]
    np.testing.assert_allclose(A, Jf.T @ Jf, rtol=1e-10, atol=1e-6)
    np.testing.assert_allclose(g, Jf.T @ r, rtol=1e-10, atol=1e-6)
    assert A.shape == (int(problem.free.sum()),) * 2
