"""A plain OpenCV program, set up with care: the second reference of `stereo-gui bench`'s speed,
beside the reference loop (core.reference_loop).

What a competent engineer writes in a few lines for a 640x480 pair, one frame after the other in
one thread, OpenCV's thread count left as it is: both colour pictures remapped through
fixed-point maps (CV_16SC2, bilinear), converted to grey, halved with INTER_AREA, StereoSGBM in
3-way mode (window 3, 64 disparities from 0, P1 8*9, P2 32*9, uniqueness 10, speckle window 100
and range 2, left-right check 1 px), its right matcher (ximgproc.createRightMatcher) and the
DisparityWLSFilter, the filtered map coloured with applyColorMap. Nothing of ours is used but the
calibration's rectification maps, so the ratio of a preset to it says what our pipeline costs
beyond what anyone would do.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.stereo_calibration import StereoCalibration

WINDOW_SIZE = 3
NUM_DISP = 64  # of the halved images: 128 px of the full-size ones
SCALE = 0.5


def plain_matcher() -> cv2.StereoSGBM:
    """The plain program's left matcher."""
    w = WINDOW_SIZE
    return cv2.StereoSGBM.create(minDisparity=0, numDisparities=NUM_DISP, blockSize=w,
                                 P1=8 * w * w, P2=32 * w * w, disp12MaxDiff=1,
                                 uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)


@dataclass(frozen=True, eq=False)
class PlainFrame:
    """What one pass computes: the filtered disparity of the halved images (x16 fixed point)
    and its colour picture (BGR uint8, halved size)."""

    filtered16: np.ndarray
    color: np.ndarray

    @property
    def disparity_px(self) -> np.ndarray:
        """The filtered disparity, on the halved grid in px of the full-size images, NaN where
        it has none."""
        d = self.filtered16.astype(np.float32) / (16.0 * SCALE)
        d[self.filtered16 <= 0] = np.nan
        return d


class PlainLoop:
    """The plain program's per-frame processing for one calibration."""

    def __init__(self, calibration: StereoCalibration) -> None:
        size = calibration.image_size
        self._maps = calibration.rectify_maps()  # fixed-point (CV_16SC2), as a careful program
        self._half = (max(1, round(size[0] * SCALE)), max(1, round(size[1] * SCALE)))
        self._left = plain_matcher()
        self._right = cv2.ximgproc.createRightMatcher(self._left)
        self._wls = cv2.ximgproc.createDisparityWLSFilter(matcher_left=self._left)

    def process(self, frame_left: np.ndarray, frame_right: np.ndarray) -> PlainFrame:
        m = self._maps
        rl = cv2.remap(frame_left, m.left_x, m.left_y, cv2.INTER_LINEAR)
        rr = cv2.remap(frame_right, m.right_x, m.right_y, cv2.INTER_LINEAR)
        gl = cv2.resize(cv2.cvtColor(rl, cv2.COLOR_BGR2GRAY), self._half,
                        interpolation=cv2.INTER_AREA)
        gr = cv2.resize(cv2.cvtColor(rr, cv2.COLOR_BGR2GRAY), self._half,
                        interpolation=cv2.INTER_AREA)
        dl = self._left.compute(gl, gr)
        dr = self._right.compute(gr, gl)
        filtered16 = self._wls.filter(dl, gl, None, dr)
        levels = cv2.convertScaleAbs(filtered16, alpha=255.0 / (16 * NUM_DISP))
        return PlainFrame(filtered16, cv2.applyColorMap(levels, cv2.COLORMAP_OCEAN))
