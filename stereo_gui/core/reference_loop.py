"""The reference loop: the live loop of the reference program (the program of the student report
the project grew from, seed/stereo-vision-report.txt), step for step as its code does it: the
plain reference that our presets are compared with (speed in `stereo-gui bench`, accuracy in
`bench --accuracy`, and the `seed` preset, which must give the same disparity pixel for pixel).

Per frame (Main_Stereo_Vision_Prog.py): both colour frames remapped with INTER_LANCZOS4 through
CV_16SC2 maps of the calibration (constant border), converted to gray, left SGBM and the right
matcher made from it, the WLS filter (lambda 80000, sigma 1.8) on the unclosed left disparity,
its output min-max normalised to uint8; the raw disparity normalised as (d/16 - min_disp) /
num_disp, a 3x3 closing, shifted to start at 0 and scaled by 255 into uint8; both coloured with
OCEAN. Nothing here is tuned: it is kept as that program has it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.lens import rectify_map
from stereo_gui.core.stereo_calibration import StereoCalibration

# the reference loop's matcher and filter parameters
WINDOW_SIZE = 3
MIN_DISP = 2
NUM_DISP = 130 - MIN_DISP
LAMBDA = 80000
SIGMA = 1.8


def reference_matcher() -> cv2.StereoSGBM:
    """cv2.StereoSGBM exactly as the reference loop creates it (other parameters at OpenCV's
    defaults)."""
    w = WINDOW_SIZE
    return cv2.StereoSGBM.create(minDisparity=MIN_DISP, numDisparities=NUM_DISP, blockSize=w,
                                 uniquenessRatio=10, speckleWindowSize=100, speckleRange=32,
                                 disp12MaxDiff=5, P1=8 * 3 * w**2, P2=32 * 3 * w**2)


@dataclass(frozen=True, eq=False)
class ReferenceFrame:
    """What one pass of the reference loop computes. `disparity16` is the raw left SGBM output
    (x16 fixed point, invalid = (MIN_DISP - 1) * 16); the colour views are BGR uint8."""

    rectified_left: np.ndarray
    rectified_right: np.ndarray
    disparity16: np.ndarray
    filtered16: np.ndarray  # WLS output, x16
    closing: np.ndarray  # float32, the loop's normalised disparity after the closing
    filtered_color: np.ndarray
    closing_color: np.ndarray

    @property
    def disparity_px(self) -> np.ndarray:
        """The raw disparity in float px, NaN where SGBM found no match."""
        d = self.disparity16.astype(np.float32) / 16.0
        d[self.disparity16 < MIN_DISP * 16] = np.nan
        return d


class ReferenceLoop:
    """The reference loop's per-frame processing for one calibration."""

    def __init__(self, calibration: StereoCalibration) -> None:
        self.calibration = calibration
        size = calibration.image_size
        # initUndistortRectifyMap as the loop does it, for the calibration's own lens model
        self._left_map = rectify_map(calibration.model, calibration.M1, calibration.D1,
                                     calibration.R1, calibration.P1, size, cv2.CV_16SC2)
        self._right_map = rectify_map(calibration.model, calibration.M2, calibration.D2,
                                      calibration.R2, calibration.P2, size, cv2.CV_16SC2)
        self._stereo = reference_matcher()
        self._stereo_r = cv2.ximgproc.createRightMatcher(self._stereo)
        self._wls = cv2.ximgproc.createDisparityWLSFilter(matcher_left=self._stereo)
        self._wls.setLambda(LAMBDA)
        self._wls.setSigmaColor(SIGMA)
        self._kernel = np.ones((3, 3), np.uint8)

    def process(self, frame_left: np.ndarray, frame_right: np.ndarray) -> ReferenceFrame:
        left_nice = cv2.remap(frame_left, self._left_map[0], self._left_map[1],
                              cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_CONSTANT)
        right_nice = cv2.remap(frame_right, self._right_map[0], self._right_map[1],
                               cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_CONSTANT)
        gray_r = cv2.cvtColor(right_nice, cv2.COLOR_BGR2GRAY)
        gray_l = cv2.cvtColor(left_nice, cv2.COLOR_BGR2GRAY)
        disp = self._stereo.compute(gray_l, gray_r)
        disp_l = disp.astype(np.int16)
        disp_r = self._stereo_r.compute(gray_r, gray_l).astype(np.int16)
        filtered16 = self._wls.filter(disp_l, gray_l, None, disp_r)
        filtered = cv2.normalize(src=filtered16, dst=None, beta=0, alpha=255,
                                 norm_type=cv2.NORM_MINMAX)
        filtered = filtered.astype(np.uint8)
        norm = ((disp.astype(np.float32) / 16) - MIN_DISP) / NUM_DISP
        closing = cv2.morphologyEx(norm, cv2.MORPH_CLOSE, self._kernel)
        dispc = (closing - closing.min()) * 255
        disp_color = cv2.applyColorMap(dispc.astype(np.uint8), cv2.COLORMAP_OCEAN)
        filt_color = cv2.applyColorMap(filtered, cv2.COLORMAP_OCEAN)
        return ReferenceFrame(left_nice, right_nice, disp, filtered16, closing, filt_color,
                           disp_color)
