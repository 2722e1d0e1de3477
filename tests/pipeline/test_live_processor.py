"""The Live tab's frame processor without Qt: displayable views, no-match colour, scaling."""

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.preset import MatcherParams, Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.pipeline.live import NO_MATCH_RGB, NOT_SEEN_RGB, LiveOutput, LiveProcessor
from stereo_gui.sources.base import StereoFrame

W, H, SHIFT = 240, 160, 12  # px: an already rectified plane at constant disparity SHIFT


def _frame(w=W, h=H, shift=SHIFT, seed=3) -> StereoFrame:
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.random((h, w + shift)).astype(np.float32), (0, 0), 1.0)
    big = cv2.normalize(big, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    left = cv2.cvtColor(np.ascontiguousarray(big[:, :w]), cv2.COLOR_GRAY2BGR)
    right = cv2.cvtColor(np.ascontiguousarray(big[:, shift:shift + w]), cv2.COLOR_GRAY2BGR)
    return StereoFrame(left, right, 0.0, 0.0, 0)


def _processor() -> LiveProcessor:
    calib = StereoCalibration.identity((W, H), 300.0, 100.0)
    return LiveProcessor(calib, MatcherParams(num_disparities=32, block_size=5))


def test_every_view_is_displayable_and_no_match_has_its_colour():
    proc = _processor()
    try:
        out = proc(_frame())
    finally:
        proc.close()
    assert isinstance(out, LiveOutput) and out.scale_note == ""
    for key in ("left", "right", "raw", "closed", "depth", "wls"):
        img = out.images[key]
        assert img.dtype == np.uint8 and img.shape == (H, W, 3), key
    r = out.result
    assert np.nanmedian(r.final_px[r.valid]) == pytest.approx(SHIFT, abs=0.5)
    # the strip at the left edge the right camera cannot see is magenta, other invalid pixels
    # dark red, in the colour view and the gray ones alike
    assert r.not_seen is not None and r.not_seen[:, :SHIFT - 1].all()
    invalid = ~r.valid & ~r.not_seen
    for key, m in (("depth", r.final_px), ("raw", r.disparity_px), ("closed", r.closed_px),
                   ("wls", r.wls_px)):
        assert (out.images[key][r.not_seen] == NOT_SEEN_RGB).all(), key
        no_match = np.isnan(m) & ~r.not_seen
        assert (out.images[key][no_match] == NO_MATCH_RGB).all(), key
    assert invalid.any()


def test_the_not_seen_colour_is_no_colour_of_depth_in_any_view():
    """The grey views (Raw, Closed: r = g = b) and the presets' colour maps never draw depth in
    the "not seen" colour, nor in anything close to it; it is no "no match" either (the legend
    said grey while Raw and Closed are grey scale)."""
    from stereo_gui.core.preset import COLORMAPS
    from stereo_gui.files.presets import load_preset

    seen = np.asarray(NOT_SEEN_RGB, float)
    greys = np.repeat(np.arange(256, dtype=float)[:, None], 3, 1)
    assert np.linalg.norm(greys - seen, axis=1).min() > 80
    assert np.linalg.norm(seen - np.asarray(NO_MATCH_RGB, float)) > 80
    ramp = np.arange(256, dtype=np.uint8).reshape(256, 1)
    for name in ("live", "quality", "seed"):
        cmap = load_preset(name).display.colormap
        lut = cv2.applyColorMap(ramp, COLORMAPS[cmap]).reshape(256, 3)[:, ::-1].astype(float)
        assert np.linalg.norm(lut - seen, axis=1).min() > 80, (name, cmap)


def test_a_frame_of_another_size_scales_the_calibration_and_says_so():
    proc = _processor()
    try:
        out = proc(_frame(w=W // 2, h=H // 2, shift=SHIFT // 2))
        assert out.images["left"].shape == (H // 2, W // 2, 3)
        assert "scaled" in out.scale_note and f"{W}x{H}" in out.scale_note
        with pytest.raises(CalibrationError, match="aspect"):
            proc(_frame(w=W, h=W))
    finally:
        proc.close()


def test_new_parameters_apply_to_the_next_frame():
    proc = _processor()
    try:
        assert proc(_frame()).result.params.block_size == 5
        proc.set_params(MatcherParams(num_disparities=32, block_size=7))
        assert proc(_frame()).result.params.block_size == 7
    finally:
        proc.close()


def test_only_the_views_shown_are_made_and_the_right_image_is_gray_unless_shown():
    proc = _processor()
    try:
        proc.set_views(["left", "wls"])
        out = proc(_frame())
        assert set(out.images) == {"left", "wls"}
        assert out.result.rectified_right.ndim == 2  # the matcher needs no colour
        proc.set_views(["right", "raw", "nonsense"])
        out = proc(_frame())
        assert set(out.images) == {"right", "raw"}
        assert out.result.rectified_right.ndim == 3
        assert out.images["right"].shape == (H, W, 3)
    finally:
        proc.close()


def test_lanes_follow_the_parallel_setting_and_the_cpus():
    from stereo_gui.pipeline.concurrency import MAX_LANES
    from stereo_gui.pipeline.live import frame_lanes

    on, off = Preset().replace(parallel=True), Preset()
    assert frame_lanes(on, cpus=2) == 2 and frame_lanes(on, cpus=8) == MAX_LANES
    assert frame_lanes(on, cpus=1) == 1 and frame_lanes(off, cpus=8) == 1
    calib = StereoCalibration.identity((W, H), 300.0, 100.0)
    params = Preset(matcher=MatcherParams(num_disparities=32, block_size=5))
    proc = LiveProcessor(calib, params)
    try:
        assert proc.lanes == 1
        proc.set_params(params.replace(parallel=True))
        assert proc.lanes == frame_lanes(on)
    finally:
        proc.close()


def test_two_frames_at_once_each_get_a_pipeline_and_the_result_of_one_at_a_time():
    """Two lanes calling at once (as the frame worker's do) use a pipeline each, every one built
    to run a frame's stages in turn, and get what a call alone gets; a change of parameters
    reaches the idle pipelines too."""
    import threading

    from stereo_gui.pipeline import live

    calib = StereoCalibration.identity((W, H), 300.0, 100.0)
    params = Preset(matcher=MatcherParams(num_disparities=32, block_size=5)).replace(
        parallel=True)
    alone = LiveProcessor(calib, params)
    proc = LiveProcessor(calib, params)
    frame = _frame()
    inside = threading.Barrier(2, timeout=30)
    used = []
    real = live.StereoPipeline.process

    def meeting(self, *a, **k):  # both calls inside a pipeline at the same time
        used.append(self)
        inside.wait()
        return real(self, *a, **k)

    def two_at_once() -> list:
        outs = [None, None]
        live.StereoPipeline.process = meeting
        try:
            threads = [threading.Thread(target=lambda i=i: outs.__setitem__(i, proc(frame)))
                       for i in range(2)]
            for t in threads:
                t.start()
            for t in threads:
                t.join(60)
        finally:
            live.StereoPipeline.process = real
        return outs

    try:
        expected = alone(frame).result.final_px
        outs = two_at_once()
        assert len(used) == 2 and used[0] is not used[1]
        for out in outs:
            np.testing.assert_array_equal(out.result.final_px, expected)
        first = set(used)
        proc.set_params(params.replace(block_size=7))
        used.clear()
        outs = two_at_once()  # the same two pipelines, changed while they were idle
        assert set(used) == first
        assert all(out.result.params.block_size == 7 for out in outs)
    finally:
        alone.close()
        proc.close()


def test_the_wls_picture_is_made_only_when_its_view_is_shown():
    """With a second window the depth is the windows' agreement and WLS only a picture: hidden,
    it is not computed (nor the right matcher it needs); shown, it is, and the depth is the same."""
    calib = StereoCalibration.identity((W, H), 300.0, 100.0)
    params = MatcherParams(num_disparities=32, block_size=3, check_block_size=5, p1=72, p2=288)
    proc = LiveProcessor(calib, params)
    try:
        proc.set_views(["left", "depth"])
        hidden = proc(_frame()).result
        proc.set_views(["left", "depth", "wls"])
        shown = proc(_frame())
    finally:
        proc.close()
    assert hidden.wls_px is None and "wls" not in hidden.timings_ms
    assert shown.result.wls_px is not None and "wls" in shown.images
    np.testing.assert_array_equal(hidden.final_px, shown.result.final_px)
    assert np.nanmedian(hidden.final_px) == pytest.approx(SHIFT, abs=0.5)


def test_the_view_colour_range_is_kept_from_frame_to_frame():
    """The processor keeps the colour scale of the frame before (the hysteresis of a range that
    follows the view lives with the frames, not in a widget): a plane a little nearer keeps the
    range (a fresh processor would round it elsewhere), one much nearer moves it."""
    from stereo_gui.core.preset import DisplayParams

    calib = StereoCalibration.identity((W, H), 300.0, 100.0)  # f*B = 30000 mm px
    preset = Preset(matcher=MatcherParams(num_disparities=32, block_size=5),
                    display=DisplayParams(color_range="view"))

    def ranges(proc, shifts):
        return [proc(_frame(shift=s)).result.color_scale.distance_range_mm() for s in shifts]

    proc, fresh = LiveProcessor(calib, preset), LiveProcessor(calib, preset)
    try:
        # 2.5 m, 2.31 m, 1.5 m
        kept = ranges(proc, (12, 13, 20))
        alone = ranges(fresh, (13,))
    finally:
        proc.close()
        fresh.close()
    assert kept[0] == pytest.approx((2500.0, 3000.0))
    assert kept[1] == pytest.approx((2500.0, 3000.0)) and alone[0] == pytest.approx((2000.0, 2500.0))
    assert kept[2] == pytest.approx((1500.0, 2000.0))
