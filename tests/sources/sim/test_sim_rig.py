"""The simulated rig: its rendering goes through OpenCV's camera model, its truth is consistent."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from corners import detect_corners, match_order

from stereo_gui.sources.sim import (
    RigConfig,
    Scene,
    SimRig,
)


def test_board_poses_are_varied_and_fully_visible(rig):
    poses = rig.board_poses(12)
    assert len(poses) == 12
    w, h = rig.config.image_size
    centres, reach = [], []
    for pose in poses:
        corners = pose.corners_left_mm(rig.config.board)
        assert 300 < corners[:, 2].mean() < 1700
        for cam in (0, 1):
            uv = rig.project(corners, cam)
            assert uv[:, 0].min() > 10 and uv[:, 1].min() > 10
            assert uv[:, 0].max() < w - 10 and uv[:, 1].max() < h - 10
            reach.append(uv)
        centres.append(rig.project(corners, 0).mean(0))
    # the poses visit the image corners (where the distortion shows): each corner's cell of a
    # 5 x 5 grid holds corners of some pose in one of the images
    pts = np.concatenate(reach)
    for cx, cy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        in_cell = ((pts[:, 0] < w / 5) if cx == 0 else (pts[:, 0] > 4 * w / 5)) & \
                  ((pts[:, 1] < h / 5) if cy == 0 else (pts[:, 1] > 4 * h / 5))
        assert in_cell.sum() >= 3, (cx, cy)
        np.testing.assert_allclose(pose.R @ pose.R.T, np.eye(3), atol=1e-9)
    centres = np.array(centres)
    # positions spread over the image, and tilts vary
    assert np.ptp(centres[:, 0]) > 0.4 * w and np.ptp(centres[:, 1]) > 0.3 * h
    tilts = [np.degrees(np.arccos(abs(p.R[2, 2]))) for p in poses]
    assert max(tilts) > 15
    # deterministic for a seed
    again = SimRig(seed=3).board_poses(12)
    np.testing.assert_allclose(again[5].t, poses[5].t)


def test_rendered_corners_agree_with_projectpoints(rig):
    """The rendering goes through the same distortion model OpenCV calibrates (< 0.1 px RMS)."""
    board = rig.config.board
    rng = np.random.default_rng(1)
    errors = []
    for pose in rig.board_poses(5):
        left, right = rig.render_board_pair(pose, rng)
        assert left.shape == (480, 640, 3) and left.dtype == np.uint8
        for cam, img in ((0, left), (1, right)):
            found = detect_corners(img, board)
            assert found is not None, "the rendered board was not detected"
            truth = rig.project(pose.corners_left_mm(board), cam)
            found = match_order(found, truth)
            errors.append(np.sum((found - truth) ** 2, 1))
    rms = float(np.sqrt(np.mean(np.concatenate(errors))))
    assert rms < 0.1, rms


@pytest.mark.slow
def test_calibration_on_rendered_pairs_recovers_the_rig():
    """A quick calibration sanity check; the real accuracy tests belong to core calibration."""
    rig = SimRig(seed=11)
    board = rig.config.board
    obj, img_l, img_r = [], [], []
    for left, right in rig.calibration_set(14):
        cl, cr = detect_corners(left, board), detect_corners(right, board)
        if cl is None or cr is None:
            continue
        if np.linalg.norm(cl[0] - cl[-1]) > 0 and np.dot(cl[-1] - cl[0], cr[-1] - cr[0]) < 0:
            cr = cr[::-1]  # same corner order in both images
        obj.append(board.object_points_mm())
        img_l.append(cl.astype(np.float32))
        img_r.append(cr.astype(np.float32))
    assert len(obj) >= 12
    size = rig.config.image_size
    _, M1, D1, _, _ = cv2.calibrateCamera(obj, img_l, size, None, None)
    _, M2, D2, _, _ = cv2.calibrateCamera(obj, img_r, size, None, None)
    rms, M1, D1, M2, D2, R, T, _, _ = cv2.stereoCalibrate(
        obj, img_l, img_r, M1, D1, M2, D2, size, flags=cv2.CALIB_FIX_INTRINSIC)
    assert rms < 0.3
    assert M1[0, 0] == pytest.approx(rig.truth.M1[0, 0], rel=0.01)
    assert M2[0, 0] == pytest.approx(rig.truth.M2[0, 0], rel=0.01)
    assert np.linalg.norm(T) == pytest.approx(110.0, rel=0.01)


def test_true_calibration_rectifies(rig):
    calib = rig.true_calibration()
    assert calib.method == "bouguet"
    assert calib.rectified_baseline_mm == pytest.approx(110.0, rel=1e-6)
    # a 3D point lands on the same rectified row in both images, at disparity f*B/Z
    X = np.array([[150.0, -80.0, 1400.0]])
    rows = []
    for cam, (M, D, Rr, P) in enumerate(((calib.M1, calib.D1, calib.R1, calib.P1),
                                         (calib.M2, calib.D2, calib.R2, calib.P2))):
        raw = rig.project(X, cam).reshape(-1, 1, 2)
        rows.append(cv2.undistortPoints(raw, M, D, R=Rr, P=P,
                                        criteria=(3, 50, 1e-12)).reshape(2))
    assert rows[0][1] == pytest.approx(rows[1][1], abs=1e-4)
    z_rect = (calib.R1 @ X[0])[2]
    assert rows[0][0] - rows[1][0] == pytest.approx(calib.focal_px * 110.0 / z_rect, rel=1e-4)
    # E and F agree with the geometry: x_r^T F x_l = 0
    xl = np.append(rig.project(X, 0)[0], 1.0)
    xr = np.append(rig.project(X, 1)[0], 1.0)
    # F relates undistorted pixels: undistort first
    ul = cv2.undistortPoints(xl[:2].reshape(1, 1, 2), calib.M1, calib.D1, P=calib.M1).reshape(2)
    ur = cv2.undistortPoints(xr[:2].reshape(1, 1, 2), calib.M2, calib.D2, P=calib.M2).reshape(2)
    assert abs(np.append(ur, 1) @ calib.F @ np.append(ul, 1)) < 1e-3


def test_true_point_rectified_is_on_the_scene(rig):
    calib = rig.true_calibration()
    wall = Scene.wall(1500)
    for x, y in ((320, 240), (30, 20), (600, 450)):
        p = rig.true_point_rectified(calib, wall, x, y)
        assert p is not None
        p_left = calib.R1.T @ p
        assert p_left[2] == pytest.approx(1500.0)
        # projects back to the same rectified pixel
        q = calib.P1[:, :3] @ p
        assert q[:2] / q[2] == pytest.approx([x, y], abs=1e-6)
    assert rig.true_point_rectified(calib, Scene(()), 320, 240) is None


def test_scene_stereo_is_consistent_with_truth(rig):
    """Block matching on the rectified rendering finds the disparity the truth predicts."""
    calib = rig.true_calibration()
    maps = calib.rectify_maps()
    for dist in (800.0, 2500.0):
        left, right = rig.render_scene(Scene.wall(dist), np.random.default_rng(2))
        assert cv2.cvtColor(left, cv2.COLOR_BGR2GRAY).std() > 15  # textured, not flat
        rl = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
        rr = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
        sgbm = cv2.StereoSGBM.create(minDisparity=0, numDisparities=128, blockSize=5,
                                     P1=8 * 3 * 25, P2=32 * 3 * 25, uniquenessRatio=10)
        disp = sgbm.compute(cv2.cvtColor(rl, cv2.COLOR_BGR2GRAY),
                            cv2.cvtColor(rr, cv2.COLOR_BGR2GRAY)).astype(np.float32) / 16
        y, x = 240, 360
        patch = disp[y - 10:y + 10, x - 10:x + 10]
        assert (patch > 0).mean() > 0.9
        z = rig.true_point_rectified(calib, Scene.wall(dist), x, y)[2]
        expected = calib.focal_px * calib.rectified_baseline_mm / z
        assert np.median(patch) == pytest.approx(expected, abs=0.5)


def test_gain_noise_and_determinism(rig):
    pose = rig.board_poses(1)[0]
    a_left, a_right = rig.render_board_pair(pose, np.random.default_rng(5))
    b_left, _ = rig.render_board_pair(pose, np.random.default_rng(5))
    c_left, _ = rig.render_board_pair(pose, np.random.default_rng(6))
    np.testing.assert_array_equal(a_left, b_left)
    diff = a_left.astype(float) - c_left.astype(float)
    assert 1.5 < diff.std() / np.sqrt(2) < 2.5  # sensor noise of about 2 grey levels
    # the right camera is darker by its gain (compare the plain background)
    assert a_right[:30, :30].mean() / a_left[:30, :30].mean() == pytest.approx(0.93, abs=0.02)
    quiet = SimRig(RigConfig(noise_sigma=0.0, supersample=2))
    l1, _ = quiet.render_board_pair(pose, np.random.default_rng(1))
    l2, _ = quiet.render_board_pair(pose, np.random.default_rng(2))
    np.testing.assert_array_equal(l1, l2)


def test_board_in_front_of_a_scene_is_depth_tested():
    rig = SimRig(RigConfig(noise_sigma=0.0, supersample=1))
    pose = rig.board_poses(1)[0]
    corner_px = rig.project(pose.corners_left_mm(rig.config.board)[:1], 0)[0]
    # a wall in front of the board hides it; a wall behind it does not
    near = Scene.wall(float(pose.t[2]) * 0.5)
    far = Scene.wall(float(pose.t[2]) * 3.0)
    hidden, _ = rig.render_board_pair(pose, scene=near)
    shown, _ = rig.render_board_pair(pose, scene=far)
    only_wall, _ = rig.render_scene(near)
    np.testing.assert_array_equal(hidden, only_wall)
    assert detect_corners(shown, rig.config.board) is not None
    assert corner_px is not None


def test_scene_rendering_has_no_disparity_bias(rig):
    """Shifting the rectified right image by the true disparity aligns it with the left best:
    the rendering itself puts the texture where the geometry says, to a few hundredths of a px.
    (Block matchers add their own sub-pixel bias on top; that is theirs to handle.)"""
    quiet = SimRig(RigConfig(noise_sigma=0.0), seed=3)  # same cameras, cached ray maps
    calib = quiet.true_calibration()
    maps = calib.rectify_maps()
    wall = Scene.wall(2000.0)
    left, right = quiet.render_scene(wall)
    gray = [cv2.cvtColor(cv2.remap(img, mx, my, cv2.INTER_CUBIC), cv2.COLOR_BGR2GRAY).astype(np.float32)
            for img, mx, my in ((left, maps.left_x, maps.left_y), (right, maps.right_x, maps.right_y))]
    y0, y1, x0, x1 = 180, 300, 300, 420
    ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float32)
    z = quiet.true_point_rectified(calib, wall, (x0 + x1) / 2, (y0 + y1) / 2)[2]
    disparity = calib.focal_px * calib.rectified_baseline_mm / z
    offsets = np.arange(-0.3, 0.301, 0.05)
    ssd = [float(np.mean((cv2.remap(gray[1], xs - np.float32(disparity + o), ys, cv2.INTER_CUBIC)
                          - gray[0][y0:y1, x0:x1]) ** 2)) for o in offsets]
    assert abs(offsets[int(np.argmin(ssd))]) < 0.06
