"""The watched region of the live view: nearest and median distance, depth share, alarm."""

import math

import numpy as np
import pytest

from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.regression import fit_inverse
from stereo_gui.files.presets import load_preset
from stereo_gui.pipeline.region import Region, region_stats


@pytest.fixture(scope="module")
def wall_result():
    from stereo_gui.sources.sim import Scene, SimRig

    rig = SimRig(seed=5)
    calib = rig.true_calibration()
    scene = Scene.wall(1500.0)
    left, right = rig.render_scene(scene, np.random.default_rng(2))
    with StereoPipeline(calib, load_preset("live")) as p:
        r = p.process(left, right)
    return r, float(rig.true_point_rectified(calib, scene, 325.0, 240.0)[2])


def test_a_wall_reads_its_distance_and_raises_the_alarm_below_it(wall_result):
    wall_result, true_z = wall_result
    box = Region(250, 180, 400, 300)
    s = region_stats(wall_result, box)
    assert s.note == "" and s.pixels > 0.9 * 150 * 120 and s.valid_fraction > 0.9
    # a wall about 1.5 m away: the view's own (unrefined, half-resolution) map, within 2 %
    assert s.median_mm == pytest.approx(true_z, rel=0.02)
    assert s.nearest_mm == pytest.approx(true_z, rel=0.03) and s.nearest_mm <= s.median_mm
    assert not s.alarm
    assert region_stats(wall_result, box, alarm_mm=2000.0).alarm
    assert not region_stats(wall_result, box, alarm_mm=1000.0).alarm


def test_a_fit_gives_the_distances_when_active(wall_result):
    wall_result, _true_z = wall_result
    calib = wall_result.calibration
    fb = calib.focal_px * calib.rectified_baseline_mm
    d = np.array([30.0, 40.0, 50.0, 60.0, 70.0])
    fit = fit_inverse(list(zip(d, 1.1 * fb / d)))  # every distance 10 % longer
    s = region_stats(wall_result, Region(250, 180, 400, 300), fit=fit)
    plain = region_stats(wall_result, Region(250, 180, 400, 300))
    assert s.median_mm == pytest.approx(1.1 * plain.median_mm, rel=0.005)


def test_regions_without_depth_say_why(wall_result):
    wall_result, _true_z = wall_result
    out = region_stats(wall_result, Region(700, 10, 800, 50))
    assert out.note == "outside the image" and math.isnan(out.nearest_mm)
    # the strip at the left edge the right camera cannot see has no depth
    edge = region_stats(wall_result, Region(0, 100, 20, 300), alarm_mm=5000.0)
    assert edge.note == "too little depth in the region" and not edge.alarm
    assert Region(50, 60, 10, 20).clipped(640, 480) == Region(10, 20, 50, 60)
