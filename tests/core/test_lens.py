"""Lens models: projection Jacobians in one column order, undistortion inverts projection,
rectification maps agree with point rectification, for pinhole, rational and fisheye."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.lens import (
    distortion_names,
    model_for,
    project_points,
    rectify_map,
    stereo_rectify,
    undistort_points,
)

M = np.array([[750.0, 0, 321.0], [0, 748.0, 238.0], [0, 0, 1]])
DIST = {
    "pinhole": np.array([-0.18, 0.06, 1e-3, -6e-4, -0.012]),
    "rational": np.array([-0.18, 0.06, 1e-3, -6e-4, -0.012, 0.01, 0.02, 0.003]),
    "fisheye": np.array([0.02, -0.01, 0.004, -0.001]),
}


def _points(seed=0):
    rng = np.random.default_rng(seed)
    obj = np.zeros((12, 3))
    obj[:, :2] = rng.uniform(-150, 150, (12, 2))
    return obj, np.array([0.1, -0.2, 0.05]), np.array([10.0, 20.0, 800.0])


@pytest.mark.parametrize("model", sorted(DIST))
def test_jacobian_matches_finite_differences(model):
    obj, rvec, tvec = _points()
    D = DIST[model]
    uv, J = project_points(model, obj, rvec, tvec, M, D, jacobian=True)
    assert J.shape == (24, 10 + D.size)
    theta = np.concatenate([rvec, tvec, [M[0, 0], M[1, 1], M[0, 2], M[1, 2]], D])

    def f(t):
        K = np.array([[t[6], 0, t[8]], [0, t[7], t[9]], [0, 0, 1]])
        return project_points(model, obj, t[:3], t[3:6], K, t[10:]).reshape(-1)

    num = np.empty_like(J)
    for k in range(theta.size):
        h = 1e-6 * max(1.0, abs(theta[k]))
        e = np.zeros_like(theta)
        e[k] = h
        num[:, k] = (f(theta + e) - f(theta - e)) / (2 * h)
    np.testing.assert_allclose(J, num, atol=1e-5 * np.abs(num).max())


@pytest.mark.parametrize("model", sorted(DIST))
def test_undistortion_inverts_projection(model):
    obj, rvec, tvec = _points(1)
    uv = project_points(model, obj, rvec, tvec, M, DIST[model])
    import cv2

    cam = obj @ cv2.Rodrigues(rvec)[0].T + tvec
    xy = undistort_points(model, uv, M, DIST[model])
    np.testing.assert_allclose(xy, cam[:, :2] / cam[:, 2:], atol=1e-9)


@pytest.mark.parametrize("model", sorted(DIST))
def test_rectification_maps_agree_with_rectified_points(model):
    import cv2

    R = cv2.Rodrigues(np.array([0.006, -0.012, 0.004]))[0]
    T = np.array([[-110.0], [0.7], [-0.9]])
    D = DIST[model]
    size = (640, 480)
    R1, R2, P1, P2, Q = stereo_rectify(model, M, D, M, D, size, R, T, 0.0)
    mx, my = rectify_map(model, M, D, R1, P1, size, cv2.CV_32FC1)
    # the map sends rectified pixel (x, y) to the raw pixel; rectifying that raw pixel again
    # must give (x, y) back
    ys, xs = np.mgrid[60:420:90, 80:560:120]
    raw = np.stack([mx[ys, xs].ravel(), my[ys, xs].ravel()], 1)
    back = undistort_points(model, raw, M, D, R=R1, P=P1)
    np.testing.assert_allclose(back, np.stack([xs.ravel(), ys.ravel()], 1), atol=0.02)
    assert abs(P2[0, 3] / P2[0, 0]) == pytest.approx(np.linalg.norm(T), rel=1e-6)


def test_names_and_model_of_a_distortion_vector():
    assert distortion_names("pinhole") == ("k1", "k2", "p1", "p2", "k3")
    assert distortion_names("fisheye") == ("k1", "k2", "k3", "k4")
    assert len(distortion_names("rational")) == 8
    assert model_for("pinhole", np.zeros(8)) == "rational"
    assert model_for("fisheye", np.zeros(4)) == "fisheye"
