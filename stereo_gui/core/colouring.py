"""Colouring a disparity map: the colour scale (a fixed distance range, one that follows the
distances in view, or each frame's min-max), the legend's caption, and the colour view itself,
with the colours of pixels without depth.

Disparities are float32 px, NaN where invalid; colour levels run 0..255, 255 near.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike

from stereo_gui.core.preset import COLORMAPS, DisplayParams
from stereo_gui.core.stereo_calibration import StereoCalibration

# colours of pixels without depth in every view and export: no match (dark red), and the strip
# the right camera cannot see (magenta); neither occurs in the colour maps' ramps near them
NO_MATCH_BGR = (20, 20, 110)
NOT_SEEN_BGR = (180, 40, 180)


@dataclass(frozen=True)
class ColorScale:
    """How the colour view turns disparity into colour levels 0..255 (255: near, top of the map).

    kind "distance": linear in distance from `far` (level 0) to `near` (level 255), both in mm,
    so that the middle of the map is the middle of the range (not crowded at the far end as a
    disparity ramp would be).
    kind "disparity": linear in disparity from `far` to `near`, both in px (the reference loop's
    per-frame min-max normalisation, and the range that follows the view: over a range of
    distances ten times apart, a surface near gets as many colours as one far away).
    `fb_mm_px` = f*B and `doffs_px` convert between the two: Z = f B / (d + doffs).
    `mode` is the DisplayParams.color_range that chose the range: "fixed" (a colour always means
    the same distance), "view" (a round range that follows the distances in view, `view_range`)
    or "minmax" (not given: "fixed" for a distance scale, "minmax" for a disparity one); the
    legend says which (`color_scale_caption`).
    """

    kind: str
    far: float
    near: float
    fb_mm_px: float
    doffs_px: float = 0.0
    mode: str = ""

    def __post_init__(self) -> None:
        if not self.mode:
            object.__setattr__(self, "mode", "fixed" if self.kind == "distance" else "minmax")

    def level(self, disparity_px: ArrayLike) -> np.ndarray:
        """Colour level (float, not clipped; NaN where the disparity is NaN)."""
        d = np.asarray(disparity_px, np.float32)
        if self.kind == "distance":
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.float32(self.fb_mm_px) / (d + np.float32(self.doffs_px))
            return (np.float32(self.far) - z) * np.float32(255.0 / (self.far - self.near))
        return (d - np.float32(self.far)) * np.float32(255.0 / max(self.near - self.far, 1e-6))

    def level_of_distance(self, z_mm: float) -> float:
        """Colour level of a distance in mm."""
        return float(self.level(np.float32(self.fb_mm_px / z_mm - self.doffs_px)))

    def distance_range_mm(self) -> tuple[float, float]:
        """(near, far) mm of the range: far is inf for a disparity of 0 or less (NaN without a
        metric f*B)."""
        if self.kind == "distance":
            return self.near, self.far

        def z(d: float) -> float:
            d += self.doffs_px
            return self.fb_mm_px / d if d > 0 else math.inf

        return z(self.near), z(self.far)


# the "view" colour range: its ends are these percentiles of the valid pixels' distances (a few
# stray matches do not stretch it) ...
VIEW_PERCENTILES = (2.0, 98.0)
# ... rounded outwards to these numbers (times a power of ten, mm) ...
READABLE_STEPS = (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 10.0)
# ... and it moves only when the view passes one of its ends by more than this ratio, or fills
# less than VIEW_MIN_FILL of it and the new range would be at most VIEW_SHRINK as wide: colours
# do not flicker with the noise of the percentiles from frame to frame
VIEW_MARGIN = 1.2
VIEW_MIN_FILL = 0.4
VIEW_SHRINK = 0.6
VIEW_SAMPLES = 40_000  # about this many pixels are looked at (a regular grid of the map)
VIEW_MIN_SAMPLES = 20  # fewer valid ones than this: nothing in view


def readable_mm(z_mm: float, up: bool) -> float:
    """The nearest READABLE_STEPS number (mm) at or above (`up`) or at or below `z_mm` (> 0)."""
    power = 10.0 ** math.floor(math.log10(z_mm))
    steps = [s * power for s in READABLE_STEPS] + [s * power / 10 for s in READABLE_STEPS]
    # (a relative tolerance: 3000.0000001 is 3 m, not the step above)
    if up:
        return min(s for s in steps if s >= z_mm * (1 - 1e-9))
    return max(s for s in steps if s <= z_mm * (1 + 1e-9))


def readable_range(near_mm: float, far_mm: float) -> tuple[float, float]:
    """(near, far) mm rounded outwards to READABLE_STEPS numbers, far at least a step beyond
    near (a flat wall still gets a ramp)."""
    near = readable_mm(max(near_mm, 1.0), up=False)
    far = readable_mm(max(far_mm, near), up=True)
    if far <= near:
        far = readable_mm(near * 1.01, up=True)
    return near, far


def view_distances(disparity_px: np.ndarray, fb_mm_px: float, doffs_px: float = 0.0
                   ) -> tuple[float, float] | None:
    """(near, far) mm: the VIEW_PERCENTILES of the distances of the valid pixels of a map (px,
    NaN invalid), from a regular grid of about VIEW_SAMPLES of them; None when fewer than
    VIEW_MIN_SAMPLES are valid."""
    h, w = disparity_px.shape[:2]
    step = max(1, int(math.sqrt(h * w / VIEW_SAMPLES)))
    d = disparity_px[::step, ::step].astype(np.float64).ravel() + doffs_px
    d = d[d > 0]  # (NaN compares False: the invalid pixels go too)
    if d.size < VIEW_MIN_SAMPLES:
        return None
    # distance falls as disparity grows: the near end is the large disparities' percentile
    lo_pct, hi_pct = VIEW_PERCENTILES
    d_far, d_near = np.percentile(d, (100.0 - hi_pct, 100.0 - lo_pct))
    return fb_mm_px / float(d_near), fb_mm_px / float(d_far)


def view_range(seen: tuple[float, float] | None, fallback: tuple[float, float],
               previous: tuple[float, float] | None = None) -> tuple[float, float]:
    """(near, far) mm of the "view" colour range: `seen` (the (near, far) distances in view, mm,
    None when nothing is) rounded to readable numbers, or `previous` (the range of the frame
    before) while the view stays in it (see VIEW_MARGIN). Nothing in view: `previous`, else
    `fallback` (the preset's near and far)."""
    if seen is None:
        return previous if previous is not None else fallback
    near, far = seen
    candidate = readable_range(near, far)
    if previous is None:
        return candidate
    p_near, p_far = previous
    if near < p_near / VIEW_MARGIN or far > p_far * VIEW_MARGIN:
        return candidate  # the view left the range

    def span(a: float, b: float) -> float:  # (the colours are linear in disparity, 1/Z)
        return 1.0 / a - 1.0 / b

    fill = max(0.0, span(max(near, p_near), min(far, p_far))) / span(p_near, p_far)
    if fill < VIEW_MIN_FILL and span(*candidate) <= VIEW_SHRINK * span(p_near, p_far):
        return candidate  # the view fills little of the range, and a narrower one fits it
    return previous


def color_scale(disparity_px: np.ndarray, params: DisplayParams,
                calibration: StereoCalibration | None,
                previous: ColorScale | None = None) -> ColorScale:
    """The colour scale of a frame: the preset's fixed distance range, a range that follows the
    distances in view ("view": `previous`, the scale of the frame before, keeps it steady), or
    the frame's min-max (also without a calibration)."""
    fb = (calibration.focal_px * calibration.rectified_baseline_mm
          if calibration is not None else float("nan"))
    if params.color_range in ("fixed", "view") and calibration is not None:
        doffs = calibration.disparity_offset_px
        near, far = params.color_z_near_mm, params.color_z_far_mm
        if params.color_range == "view":
            before = None
            if (previous is not None and previous.mode == "view"
                    and previous.fb_mm_px == fb and previous.doffs_px == doffs):
                before = previous.distance_range_mm()
            near, far = view_range(view_distances(disparity_px, fb, doffs), (near, far), before)
            return ColorScale("disparity", fb / far - doffs, fb / near - doffs, fb, doffs, "view")
        return ColorScale("distance", far, near, fb, doffs, "fixed")
    valid = cv2.compare(disparity_px, disparity_px, cv2.CMP_EQ)  # 255 where not NaN
    lo, hi = cv2.minMaxLoc(disparity_px, mask=valid)[:2] if cv2.countNonZero(valid) else (0.0, 1.0)
    doffs = calibration.disparity_offset_px if calibration is not None else 0.0
    return ColorScale("disparity", float(lo), float(max(hi, lo + 1e-6)), fb, doffs, "minmax")


COLOR_RANGE_WORDS = {"view": "colours follow the view", "fixed": "fixed colours",
                     "minmax": "colours stretched to each frame"}


def color_scale_caption(scale: ColorScale) -> str:
    """What the legend says of a scale: its kind and its range, e.g. "colours follow the view:
    6-100 m" or "fixed colours: 0.5-3 m" (metres, as the colour bar's ticks)."""
    words = COLOR_RANGE_WORDS.get(scale.mode, scale.mode)
    near, far = scale.distance_range_mm()
    if not (math.isfinite(near) and near > 0):
        return words

    def m(z: float) -> str:
        return "∞" if math.isinf(z) else f"{z / 1000:.3g}"

    return f"{words}: {m(near)}–{m(far)} m"


def colorize(disparity_px: np.ndarray, scale: ColorScale, colormap: str,
             not_seen: np.ndarray | None = None, not_seen_cols: int | None = None
             ) -> np.ndarray:
    """Colour view of a disparity map (BGR uint8) on `scale`; near bright. Invalid pixels get
    NO_MATCH_BGR (black is the far end of OCEAN), pixels the right camera cannot see (`not_seen`
    mask, set only in the leftmost `not_seen_cols` columns if given) NOT_SEEN_BGR.

    The levels are those of `ColorScale.level`, computed with OpenCV's saturating arithmetic
    (a few times faster than numpy here, and this runs on every frame).
    """
    valid = cv2.compare(disparity_px, disparity_px, cv2.CMP_EQ)  # 255 where not NaN
    far, near = float(scale.far), float(scale.near)
    if scale.kind == "distance":
        # level = (far - fb/d) * k; with inv = 1/d held at <= far/fb (beyond far: level 0) the
        # value is >= 0, so convertScaleAbs's absolute value changes nothing
        k = 255.0 / (far - near)
        fb = float(scale.fb_mm_px)
        shifted = (cv2.add(disparity_px, float(scale.doffs_px)) if scale.doffs_px
                   else disparity_px)
        inv = cv2.pow(shifted, -1.0)
        np.minimum(inv, np.float32(far / fb), out=inv)  # (cv2.min takes a float for a Scalar)
        u8 = cv2.convertScaleAbs(inv, alpha=-k * fb, beta=far * k)
    else:
        k = 255.0 / max(near - far, 1e-6)
        u8 = cv2.convertScaleAbs(np.maximum(disparity_px, np.float32(far)), alpha=k, beta=-far * k)
    color = cv2.applyColorMap(u8, COLORMAPS[colormap])
    paint(color, cv2.bitwise_not(valid), NO_MATCH_BGR)
    if not_seen is not None:
        paint(color, not_seen, NOT_SEEN_BGR, not_seen_cols)
    return color


@functools.lru_cache(maxsize=16)
def _solid(h: int, w: int, channels: int, value: tuple[int, ...]) -> np.ndarray:
    img = np.empty((h, w, channels), np.uint8)
    img[:] = value
    img.setflags(write=False)
    return img


def paint(image: np.ndarray, mask: np.ndarray, value: tuple[int, ...],
          cols: int | None = None) -> None:
    """Set the pixels of a uint8 H x W x C `image` where `mask` (bool or uint8, H x W) is set to
    `value`, in place (cv2.copyTo: many times faster than numpy's boolean assignment). `cols`:
    as for `blank`."""
    if cols is not None and cols < image.shape[1]:
        image, mask = image[:, :max(0, cols)], mask[:, :max(0, cols)]
    if mask.dtype == np.bool_:
        mask = mask.view(np.uint8)
    h, w = image.shape[:2]
    cv2.copyTo(_solid(h, w, image.shape[2], tuple(value)), mask, image)
