"""The Capture tab's frame processor without Qt: the board in both images of a simulated frame."""

import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.pipeline.capture import CaptureOutput, display_rgb, make_capture_processor
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource


def test_board_found_in_both_images_with_rgb_views():
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="board", paced=False, seed=1,
                    frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    try:
        outs = [proc(src.read()) for _ in range(12)]
    finally:
        src.close()
    found = [o for o in outs if o.detection.found]
    assert found, "the simulated rig never showed the board to both cameras"
    o = found[0]
    assert isinstance(o, CaptureOutput) and o.pose is not None
    assert o.detection.left.corners.reshape(-1, 2).shape == (BoardSpec().cols * BoardSpec().rows, 2)
    assert o.left_rgb.flags.c_contiguous and o.left_rgb.shape == (480, 640, 3)


def test_display_rgb_swaps_channels_and_expands_gray():
    bgr = np.zeros((2, 3, 3), np.uint8)
    bgr[..., 0] = 10  # blue
    assert (display_rgb(bgr)[..., 2] == 10).all() and display_rgb(bgr).flags.c_contiguous
    gray = np.full((2, 3), 7, np.uint8)
    assert display_rgb(gray).shape == (2, 3, 3) and (display_rgb(gray) == 7).all()
