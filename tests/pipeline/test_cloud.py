"""The point cloud of a frame for the 3D view: where the points are, their colours, limits."""

import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.preset import MatcherParams
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.cloud import MAX_POINTS, cloud_points


def _plane(shift=10, w=160, h=120):
    rng = np.random.default_rng(1)
    big = (rng.random((h, w + shift, 3)) * 200 + 20).astype(np.uint8)
    left, right = np.ascontiguousarray(big[:, :w]), np.ascontiguousarray(big[:, shift:shift + w])
    calib = StereoCalibration.identity((w, h), 300.0, 100.0)  # Z = 30000 / d mm
    with StereoPipeline(calib, MatcherParams(num_disparities=32, block_size=5, wls=False)) as p:
        return p.process(left, right)


def test_a_plane_at_3_m_is_a_wall_of_points_ahead():
    r = _plane()
    c = cloud_points(r, "image", step=2)
    assert 0 < c.count <= (160 // 2) * (120 // 2)
    assert c.xyz_m.dtype == np.float32 and c.xyz_m.shape == (c.count, 3)
    # display coordinates: y is the depth ahead (3 m), z is up
    assert np.median(c.xyz_m[:, 1]) == pytest.approx(3.0, rel=0.01)
    assert c.z_near_m == pytest.approx(3.0, rel=0.02) and c.z_far_m == pytest.approx(3.0, rel=0.02)
    top = c.xyz_m[:, 2].max()
    assert top > 0 and c.xyz_m[:, 2].min() < 0  # image rows above the centre are up
    assert c.rgba.shape == (c.count, 4) and 0 <= c.rgba.min() and c.rgba.max() <= 1
    d = cloud_points(r, "distance")
    assert d.count >= c.count and np.all(d.rgba[:, 3] == 1.0)


def test_big_frames_are_thinned_and_bad_requests_refused():
    r = _plane(w=640, h=480)
    assert cloud_points(r, step=1).count <= MAX_POINTS
    with pytest.raises(InputError, match="colouring"):
        cloud_points(r, "rainbow")
    hartley = r.__class__(**{**r.__dict__, "calibration": None})
    with pytest.raises(InputError, match="metric"):
        cloud_points(hartley)


def test_points_coloured_by_distance_stand_out_from_their_background():
    """By distance, the farthest points are the colour map's far end (black in OCEAN): they
    were drawn on a dark grey and could not be seen. Every point's colour now stands well
    apart from the background it is drawn on, near and far, whichever colour map."""
    import dataclasses

    from stereo_gui.pipeline.cloud import IMAGE_BACKGROUND_RGB

    r = _plane()
    near = _plane(shift=30)
    for colormap in ("ocean", "jet", "turbo", "viridis", "hot"):
        for res in (r, near):
            res = dataclasses.replace(res, preset=res.preset.replace(colormap=colormap))
            c = cloud_points(res, "distance")
            bg = np.asarray(c.background_rgb, float)
            gap = np.linalg.norm(255.0 * c.rgba[:, :3] - bg, axis=1).min()
            assert gap > 80, (colormap, c.background_rgb, gap)
    assert cloud_points(r, "image").background_rgb == IMAGE_BACKGROUND_RGB


def test_points_coloured_by_distance_take_the_depth_views_colours():
    """One colour scale per frame: a point's colour by distance is its pixel's colour in the
    depth view (not a range of the cloud's own)."""
    import cv2

    from stereo_gui.core.colouring import ColorScale
    from stereo_gui.core.preset import COLORMAPS

    r = _plane()
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1),
                            COLORMAPS[r.preset.display.colormap])[:, 0, ::-1]
    for scale in (r.color_scale, ColorScale("distance", 4000.0, 2000.0, 30000.0),
                  ColorScale("disparity", 30000.0 / 50000.0, 30000.0 / 2500.0, 30000.0, 0.0,
                             "view")):
        res = r.__class__(**{**r.__dict__, "color_scale": scale})
        c = cloud_points(res, "distance", step=1)
        z_mm = 1000.0 * c.xyz_m[:, 1]
        want = lut[np.clip(np.rint([scale.level_of_distance(z) for z in z_mm]), 0, 255).astype(int)]
        got = np.rint(255.0 * c.rgba[:, :3]).astype(int)
        assert np.abs(got - want).max() <= 8, scale
