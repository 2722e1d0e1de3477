"""How a disparity map is judged against ground truth, and the plain OpenCV baseline it is judged
beside (Middlebury's and KITTI's figures of merit).

A map is float32 px with NaN where it has no value; truth is float32 px with 0 where unknown.
"Known" pixels have truth; the error rates count among the known pixels that have a value, the
density is the share of known pixels that have one. Fewer wrong pixels bought with fewer pixels
is a trade, not a win: the two are always reported together.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import cv2
import numpy as np

BAD_THRESHOLDS_PX = (1.0, 2.0, 4.0)


@dataclass(frozen=True)
class DisparityScore:
    """Error rates (share of known pixels with a value whose error exceeds 1, 2, 4 px), density
    (share of known pixels with a value), the median absolute error of those (px), and how many
    pixels were known. Rates and density are fractions (0..1); NaN rates when nothing is valued."""

    bad1: float
    bad2: float
    bad4: float
    density: float
    median_error_px: float
    known: int

    @property
    def correct_density(self) -> float:
        """Share of known pixels with a value within 2 px of the truth."""
        return self.density * (1.0 - self.bad2) if math.isfinite(self.bad2) else 0.0

    def to_dict(self) -> dict[str, object]:
        return {**asdict(self), "correct_density": self.correct_density}


def score_disparity(disparity_px: np.ndarray, truth_px: np.ndarray) -> DisparityScore:
    """Score a map against the truth (same shape)."""
    d = np.asarray(disparity_px, np.float32)
    t = np.asarray(truth_px, np.float32)
    if d.shape != t.shape:
        raise ValueError(f"the map is {d.shape} but the truth is {t.shape}")
    known = t > 0
    n_known = int(known.sum())
    valued = known & np.isfinite(d)
    n = int(valued.sum())
    if n == 0:
        nan = float("nan")
        return DisparityScore(nan, nan, nan, 0.0, nan, n_known)
    err = np.abs(d[valued] - t[valued])
    b1, b2, b4 = (float((err > k).mean()) for k in BAD_THRESHOLDS_PX)
    return DisparityScore(b1, b2, b4, n / n_known if n_known else 0.0, float(np.median(err)),
                          n_known)


def disparity_search_range(truth_px: np.ndarray, margin: float = 1.15) -> int:
    """numDisparities covering `margin` times the largest true disparity (a multiple of 16): the
    range a careful engineer gives a matcher when the scene's depth is known."""
    top = float(np.max(truth_px)) if truth_px.size else 0.0
    return max(16, int(math.ceil(margin * top / 16.0)) * 16)


def plain_sgbm(left_bgr: np.ndarray, right_bgr: np.ndarray, num_disparities: int,
               scale: float = 1.0) -> np.ndarray:
    """What a careful engineer writes with OpenCV alone: StereoSGBM in 8-direction mode (HH) on
    the colour images, window 5, P1 = 8*3*25, P2 = 32*3*25, left-right check 1 px, uniqueness 10,
    speckle window 100 and range 2, disparities 0 .. `num_disparities` (full-resolution px).
    With `scale` < 1 it matches on INTER_AREA-shrunk images (the range shrunk with them) and the
    map is enlarged back (nearest neighbour, values / scale). Float px, NaN where no match."""
    h, w = left_bgr.shape[:2]
    num = num_disparities
    if scale < 1.0:
        size = (max(1, round(w * scale)), max(1, round(h * scale)))
        left_bgr = cv2.resize(left_bgr, size, interpolation=cv2.INTER_AREA)
        right_bgr = cv2.resize(right_bgr, size, interpolation=cv2.INTER_AREA)
        num = max(16, int(math.ceil(num_disparities * scale / 16.0)) * 16)
    block = 5
    matcher = cv2.StereoSGBM.create(
        minDisparity=0, numDisparities=num, blockSize=block, P1=8 * 3 * block**2,
        P2=32 * 3 * block**2, disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100,
        speckleRange=2, mode=cv2.STEREO_SGBM_MODE_HH)
    d16 = matcher.compute(left_bgr, right_bgr)
    d = d16.astype(np.float32) / np.float32(16.0)
    d[d16 < 0] = np.nan
    if scale < 1.0:
        d = cv2.resize(d, (w, h), interpolation=cv2.INTER_NEAREST) / np.float32(scale)
    return d
