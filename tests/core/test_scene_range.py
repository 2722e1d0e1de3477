"""The range a frame is searched over, from a quick look at the scene (`core.scene_range`) and
the pipeline's use of it (`range_from_scene`)."""

import math

import cv2
import numpy as np
import pytest

from stereo_gui.core.matching import SCENE_SHRINK_FRAMES, StereoPipeline
from stereo_gui.core.preset import MatcherParams
from stereo_gui.core.scene_range import look_at_scene
from stereo_gui.core.stereo_calibration import StereoCalibration


def _pair(shift, w=480, h=240, seed=0, near=None):
    """A textured plane `shift` px apart in the two images; `near` = (x0, x1, shift) puts a
    nearer textured block in those columns."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.integers(0, 256, (h, w + 200), np.uint8), (3, 3), 0)
    left = np.ascontiguousarray(big[:, 100:100 + w])
    right = np.ascontiguousarray(big[:, 100 + shift:100 + shift + w])
    if near is not None:
        x0, x1, s = near
        block = cv2.GaussianBlur(rng.integers(0, 256, (h, x1 - x0), np.uint8), (3, 3), 0)
        left[:, x0:x1] = block
        right[:, x0 - s:x1 - s] = block
    return left, right


def test_the_look_finds_the_nearest_surface_not_the_preset_range():
    left, right = _pair(20)
    look = look_at_scene(left, right, 0.0, 300.0)
    assert 20.0 <= look.largest_px <= 20.0 + 40.0 and look.valid_share > 0.5
    assert 20.0 <= look.top_px(300.0, 16.0) <= 80.0
    near = look_at_scene(*_pair(20, near=(200, 320, 90)), 0.0, 300.0)
    assert 90.0 <= near.largest_px <= 130.0  # a nearer block sets it


def test_a_look_that_finds_nothing_or_a_surface_at_the_near_end_keeps_the_whole_range():
    flat = np.full((240, 480), 128, np.uint8)
    look = look_at_scene(flat, flat, 0.0, 300.0)
    assert math.isnan(look.largest_px) and look.top_px(300.0, 16.0) == 300.0
    at_end = look_at_scene(*_pair(64), 0.0, 63.0)
    assert at_end.top_px(63.0, 16.0) == 63.0


def _pipeline(fitted: bool) -> StereoPipeline:
    # f 800 px, 120 mm: 0.45 m is 213 px of disparity
    calib = StereoCalibration.identity((480, 240), 800.0, 120.0)
    params = MatcherParams(z_min_mm=450.0, block_size=5, check_block_size=7, agree_px=1.0,
                           range_from_scene=fitted, wls=False, closing_kernel=0)
    return StereoPipeline(calib, params)


def test_the_pipeline_searches_what_the_scene_holds_and_widens_at_once_for_a_nearer_one():
    far = _pair(20)
    assert _pipeline(False).process(*far).disparity_range_px[1] > 200.0
    pipe = _pipeline(True)
    first = pipe.process(*far)
    assert 20.0 < first.disparity_range_px[1] < 80.0
    valid = first.final_px[np.isfinite(first.final_px)]
    assert valid.size > 0.5 * first.final_px.size and abs(np.median(valid) - 20.0) < 0.5
    # a nearer object: the very frame it appears in is searched far enough
    near = pipe.process(*_pair(20, near=(200, 320, 110)))
    assert near.disparity_range_px[1] >= 110.0
    block = near.final_px[40:200, 230:300]
    assert np.nanmedian(block) == pytest.approx(110.0, abs=0.5)
    # gone again: the wider range stays a while, then narrows
    tops = [pipe.process(*far).disparity_range_px[1] for _ in range(SCENE_SHRINK_FRAMES)]
    assert all(t >= 110.0 for t in tops[:-1]) and tops[-1] < 80.0


def test_at_the_whole_range_the_look_is_taken_every_few_frames_and_narrowing_waits_as_long(
        monkeypatch):
    import stereo_gui.core.matching as matching

    looks = []  # the arguments of each look taken
    real_look = matching.look_at_scene

    def counted(*args):
        looks.append(args)
        return real_look(*args)

    monkeypatch.setattr(matching, "look_at_scene", counted)
    pipe = _pipeline(True)
    top = pipe.process(*_pair(20, near=(200, 320, 200))).disparity_range_px[1]
    assert top > 200.0 and len(looks) == 1  # a surface at the near end: the whole range
    # far frames from then on: the look is taken on every LOOK_EVERY_AT_TOP-th, each counts
    # for the frames since the one before, and the range narrows on the same frame as when
    # every frame was looked at (the SCENE_SHRINK_FRAMES-th; the first frame's range stands
    # until then, though it was the whole range)
    far = _pair(20)
    tops = [pipe.process(*far).disparity_range_px[1] for _ in range(SCENE_SHRINK_FRAMES)]
    assert all(t == top for t in tops[:-1]) and tops[-1] < 80.0
    assert len(looks) == 1 + SCENE_SHRINK_FRAMES // matching.LOOK_EVERY_AT_TOP
    # narrowed: every frame is looked at, and a nearer surface widens the range at once
    before = len(looks)
    near = pipe.process(*_pair(20, near=(200, 320, 110)))
    assert len(looks) == before + 1 and near.disparity_range_px[1] >= 110.0
