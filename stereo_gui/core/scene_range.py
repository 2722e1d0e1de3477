"""The disparities a scene holds, found by a quick look before the frame is matched.

A preset's working distances start at a fixed nearest distance (0.45 m). For a rig with a long
focal length or a wide baseline that is hundreds of pixels of disparity (a car's stereo camera:
863 px of a 1241 px wide image; Middlebury's: 353 px where its scenes hold 70): the matcher
searches far more than the scene holds, slower and with more chances of a wrong match, and most of
the image's left part is counted as not seen. The look matches shrunk images over the preset's
whole range (so that a near object is always looked for), and the frame is then matched up to a
margin beyond the nearest surface found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_gui.core.disparity import compute_padded

# the look's images: at most this wide, and shrunk so that the range is at most LOOK_MAX_NUM px
LOOK_MAX_WIDTH = 200
LOOK_MAX_NUM = 48
LOOK_BLOCK = 5
# a blob of matches smaller than this share of the look's pixels is not a surface (speckle)
LOOK_MIN_BLOB_SHARE = 0.002
# matches nearer than the look's range's last LOOK_END_PX px may lie beyond it
LOOK_END_PX = 1.0
# the frame is matched up to the nearest surface found, times this, plus SCENE_MARGIN_PX of the
# look's pixels (a surface a little nearer in the next frame, the look's own coarseness)
SCENE_MARGIN = 1.25
SCENE_MARGIN_LOOK_PX = 3.0
# the look needs this share of its pixels matched to say anything about the scene
LOOK_MIN_VALID = 0.02
LOOK_MIN_STD = 2.0  # grey levels over the look's window: below it, a blank surface


@dataclass(frozen=True)
class SceneLook:
    """What the look found: the largest disparity of a surface in view (full-resolution px; NaN
    when too little matched to tell) and the share of the look's pixels that matched."""

    largest_px: float
    valid_share: float

    def top_px(self, preset_top_px: float, floor_px: float) -> float:
        """The largest disparity the frame should search (full-resolution px): the nearest
        surface with a margin, never above the preset's own top nor below `floor_px`; the
        preset's top when the look could not tell."""
        if not math.isfinite(self.largest_px):
            return preset_top_px
        wanted = self.largest_px * SCENE_MARGIN
        return float(min(preset_top_px, max(floor_px, wanted)))


def look_at_scene(left_gray: np.ndarray, right_gray: np.ndarray, lo_px: float, hi_px: float
                  ) -> SceneLook:
    """Match shrunk copies of two rectified gray images over disparities lo_px..hi_px
    (full-resolution px) and return the largest disparity of a surface found (a blob of
    matches, not speckle, that passed the left-right check and does not sit at the range's
    near end), with LOOK's margin for its coarseness."""
    h, w = left_gray.shape[:2]
    span = max(1.0, hi_px - min(lo_px, 0.0))
    s = min(1.0, LOOK_MAX_WIDTH / float(w), LOOK_MAX_NUM / span)
    size = (max(16, round(w * s)), max(8, round(h * s)))
    s = size[0] / float(w)
    sl = cv2.resize(left_gray, size, interpolation=cv2.INTER_AREA)
    sr = cv2.resize(right_gray, size, interpolation=cv2.INTER_AREA)
    lo = int(math.floor(lo_px * s))
    num = max(16, int(math.ceil((hi_px * s - lo + 1) / 16.0)) * 16)
    blob = max(4, round(LOOK_MIN_BLOB_SHARE * size[0] * size[1]))
    matcher = cv2.StereoSGBM.create(
        minDisparity=lo, numDisparities=num, blockSize=LOOK_BLOCK, P1=8 * LOOK_BLOCK ** 2,
        P2=32 * LOOK_BLOCK ** 2, disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=blob,
        speckleRange=2, mode=cv2.StereoSGBM_MODE_SGBM_3WAY)
    # padded at the left so that every column is searched over the whole range
    d16 = compute_padded(matcher, sl, sr, max(0, lo + num), "left")
    # a blank surface matches anywhere (often at the range's far end): only where the left image
    # holds texture beyond sensor noise does a match say where a surface is
    mean = cv2.blur(sl.astype(np.float32), (LOOK_BLOCK, LOOK_BLOCK))
    var = cv2.blur(sl.astype(np.float32) ** 2, (LOOK_BLOCK, LOOK_BLOCK)) - mean * mean
    valid = (d16 > (lo - 1) * 16) & (var >= LOOK_MIN_STD ** 2)
    share = float(valid.mean())
    if share < LOOK_MIN_VALID:
        return SceneLook(float("nan"), share)
    d = d16[valid].astype(np.float32) / np.float32(16.0)
    at_end = d >= lo + num - 1 - LOOK_END_PX
    if int(at_end.sum()) >= blob:
        # a surface at the range's near end: it may be nearer still, the whole range is needed
        return SceneLook(float(hi_px), share)
    d = d[~at_end]
    largest = float(d.max()) + SCENE_MARGIN_LOOK_PX
    return SceneLook(largest / s, share)
