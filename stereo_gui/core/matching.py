"""The frame pipeline: rectify, match (SGBM), close, WLS-filter, colourise.

The final map (what the views colour, a click reads and the exports write) is, for a preset with a
second window, the agreement of two SGBM matchers (`agreement`), without what a nearer surface
hides from the right camera (`occluded`) and what matched on a blank surface (`blank_mask`); the
WLS output is then a picture. Without a second window it is the WLS output, as in the reference
loop.

Units: every disparity this module hands out is float32 pixels of the full-resolution rectified
left image, NaN where invalid. OpenCV's matchers and the WLS filter work in x16 fixed point; that
scale is divided out in exactly one place, `fixed_to_px`.

When a preset matches at reduced resolution (`scale` < 1) the rectified images are shrunk with
INTER_AREA, the disparity range is scaled with them, and the result is brought back to full
resolution: the WLS filter does it against the full-resolution guide image, the raw and closed
maps are enlarged (nearest neighbour) and multiplied by 1/scale.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import cv2
import numpy as np

from stereo_gui.core.colouring import ColorScale, color_scale, colorize
from stereo_gui.core.disparity import (
    BLANK_HALF_PX,
    BLANK_LAG_PX,
    DISP_SCALE,
    agreement,
    blank,
    blank_mask,
    compute_padded,
    enlarge,
    fill_depth_px,
    fixed_to_px,
    local_contrast,
    nearest_source,
    occluded,
    sunk,
    unseen_columns,
    unseen_mask,
    unseen_strip,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import INTERPOLATIONS, MODES, MatcherParams, Preset, fill_mode_names
from stereo_gui.core.scene_range import look_at_scene
from stereo_gui.core.shading import undo_shading
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.util import to_gray

# per camera (left, right): the gain and offset maps that undo its lens shading (core.shading)
ShadingMaps = tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


class _Laps:
    """A frame's stage times: each call notes the time (ms) since the call before."""

    def __init__(self) -> None:
        self.ms: dict[str, float] = {}
        self._start = self._t0 = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.ms[name] = (now - self._t0) * 1000.0
        self._t0 = now

    def with_total(self) -> dict[str, float]:
        """The stages' times and the frame's total (ms)."""
        self.ms["total"] = (time.perf_counter() - self._start) * 1000.0
        return self.ms


class _Fill(NamedTuple):
    """One size the hole fill tries: its scale against the matched images, its matchers' range
    (min, num) and largest disparity, and its first and second window's matchers."""

    scale: float
    min_disparity: int
    num_disparities: int
    largest: int
    first: cv2.StereoSGBM
    second: cv2.StereoSGBM
@dataclass(frozen=True, eq=False)
class PipelineResult:
    """One processed frame. Images are full-resolution rectified (H x W); disparities float32 px.

    `disparity_px` is the raw SGBM output, `closed_px` after the closing filter, `wls_px` the WLS
    output (None without WLS), `final_px` what the preset shows. NaN marks invalid pixels;
    `valid` is the mask of `final_px`. `disparity_range_px` = (smallest, largest) disparity the
    matcher could report, full-resolution px.
    """

    rectified_left: np.ndarray
    rectified_right: np.ndarray
    disparity_px: np.ndarray
    closed_px: np.ndarray
    wls_px: np.ndarray | None
    final_px: np.ndarray
    color_bgr: np.ndarray
    valid: np.ndarray
    timings_ms: dict[str, float]
    size: tuple[int, int]  # (width, height), px
    preset: Preset = field(default_factory=lambda: Preset())
    disparity_range_px: tuple[float, float] = (0.0, 0.0)
    calibration: StereoCalibration | None = None
    color_scale: ColorScale | None = None  # how color_bgr was made from final_px
    # the WLS filter's left-right confidence (0..255, float32, H x W), None without WLS
    wls_confidence: np.ndarray | None = None
    # pixels the right camera cannot see (their match fell outside the right image, or they lie
    # in the strip at the left edge): None when the preset keeps the reference loop's dead band
    not_seen: np.ndarray | None = None
    # every pixel set in `not_seen` lies in the leftmost `not_seen_cols` columns (None: anywhere),
    # so that the views paint only those (`unseen_columns`)
    not_seen_cols: int | None = None
    match_scale: float = 1.0  # the scale the images were matched at (MatcherParams.effective_scale)
    # (gain, offset) maps (float32, H x W) of the left and right camera that undo the lens
    # shading in the rectified images (the calibration's core.shading), None when it had none
    # worth undoing
    shading_gains: ShadingMaps | None = None

    @property
    def params(self) -> MatcherParams:
        """The matcher parameters the frame was made with."""
        return self.preset.matcher

    def matched_gray(self) -> tuple[np.ndarray, np.ndarray]:
        """The rectified images in gray as the matcher saw them (the lens shading undone), at
        full resolution: what a re-match or a refinement of a reading must compare."""
        gl, gr = to_gray(self.rectified_left), to_gray(self.rectified_right)
        if self.shading_gains is not None:
            gl = undo_shading(gl, *self.shading_gains[0])
            gr = undo_shading(gr, *self.shading_gains[1])
        return gl, gr



# range_from_scene: a range a frame could narrow is narrowed after this many frames in a row asked
# for it (a nearer surface widens it at once); the range is never narrower than this (matched px)
SCENE_SHRINK_FRAMES = 15
SCENE_MIN_RANGE_PX = 16
# while a frame searches the preset's whole range, a look can only ask to narrow it, which waits
# for SCENE_SHRINK_FRAMES frames anyway: the look is then taken on every this-many-th frame, each
# look speaking for the frames since the one before (a narrowed range is looked at every frame,
# so that a nearer surface widens it at once)
LOOK_EVERY_AT_TOP = 5  # (SCENE_SHRINK_FRAMES a multiple of it: a still scene narrows as soon)


class StereoPipeline:
    """Turns raw stereo frames into `PipelineResult`s for one calibration and preset.

    Runs a frame's stages one after the other in the calling thread (frames in flight are the
    parallelism, pipeline.concurrency), so it is not for use by several threads at once;
    `set_params` may be called from any thread and takes effect with the next frame. `close()`
    (or the end of a `with` block) releases its rectification maps and matchers and ends its
    use: a closed pipeline refuses to rectify or process.
    """

    # the lens shading's (gain, offset) maps per camera at full size and at the matched size
    _shading_full: ShadingMaps | None
    _shading_gains: ShadingMaps | None

    def __init__(self, calibration: StereoCalibration,
                 params: Preset | MatcherParams | None = None):
        self.calibration = calibration
        self._lock = threading.Lock()
        self._pending: Preset | None = None
        self._preset = Preset.of(params)
        self._params = self._preset.matcher
        self._maps = None if calibration.method == "identity" else calibration.rectify_maps()
        # the largest disparity the matchers search when the scene sets it (range_from_scene;
        # None: the preset's), and how many frames in a row have asked for less
        self._scene_top_px: float | None = None
        self._shrink_votes = 0
        # frames matched since the last look (the first frame is always looked at)
        self._unlooked = LOOK_EVERY_AT_TOP - 1
        self._closed = False
        self._build()

    # ---- configuration -------------------------------------------------------------------
    @property
    def params(self) -> Preset:
        """The preset the next frame runs with (bare matcher parameters given: as a preset)."""
        return self._preset

    def set_params(self, params: Preset | MatcherParams) -> None:
        """Use `params` from the next frame on."""
        with self._lock:
            self._pending = Preset.of(params)

    def close(self) -> None:
        """Release the rectification maps, matchers and shading maps (tens of MB at 1280x720)
        now rather than when the last reference goes, and refuse any later frame (the maps gone,
        a frame would otherwise pass unrectified). May be called more than once."""
        if self._closed:
            return
        self._closed = True
        self._maps = None
        del self._left, self._second, self._right, self._wls, self._fills
        self._shading_full = self._shading_gains = None

    def __enter__(self) -> StereoPipeline:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _build(self) -> None:
        p = self._params
        s = self._scale = p.effective_scale(*self.calibration.image_size)
        fitted = p.range_from_scene and p.z_min_mm is not None
        self._min_s, self._num_s = p.matcher_range(self.calibration, s,
                                                   self._scene_top_px if fitted else None)
        self._at_top = (self._min_s, self._num_s) == p.matcher_range(self.calibration, s)
        self._range_full = (self._min_s / s, (self._min_s + self._num_s - 1) / s)
        self._left: cv2.StereoSGBM = self._sgbm(self._min_s, self._num_s, p.block_size, p)
        self._second: cv2.StereoSGBM | None = (
            self._sgbm(self._min_s, self._num_s, p.check_block_size, p)
            if p.check_block_size else None)
        # (scale, min, num) of a smaller check, and the right matcher
        self._check, self._right = self._right_matcher()
        # how far right of an empty pixel the occlusion test looks for a nearer surface: the
        # larger window's half
        self._reach = max(p.block_size, p.check_block_size) // 2 + 1
        self._fills = self._fill_matchers()
        self._wls = self._wls_filter()
        self._kernel = (np.ones((p.closing_kernel, p.closing_kernel), np.uint8)
                        if p.closing_kernel > 1 else None)
        self._shading_full = self._shading_maps()
        self._shading_gains = self._shading_full
        if self._shading_full is not None and s < 1.0:
            w, h = self.calibration.image_size
            size_s = (max(1, round(w * s)), max(1, round(h * s)))

            def shrunk(maps: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
                gain, offset = maps  # the full-size maps, shrunk as the images are
                return (cv2.resize(gain, size_s, interpolation=cv2.INTER_AREA),
                        cv2.resize(offset, size_s, interpolation=cv2.INTER_AREA))

            self._shading_gains = (shrunk(self._shading_full[0]), shrunk(self._shading_full[1]))

    def _sgbm(self, lo: int, num: int, block: int, q: MatcherParams) -> cv2.StereoSGBM:
        """An SGBM matcher of disparities lo..lo+num-1 with a `block` px window, configured by
        `q` (its penalties grown with the window's area against q's own block size)."""
        area = (block / q.block_size) ** 2
        return cv2.StereoSGBM.create(
            minDisparity=lo, numDisparities=num, blockSize=block,
            P1=round(q.p1_value * area), P2=round(q.p2_value * area),
            disp12MaxDiff=q.disp12_max_diff,
            preFilterCap=q.pre_filter_cap, uniquenessRatio=q.uniqueness_ratio,
            speckleWindowSize=q.speckle_window_size, speckleRange=q.speckle_range,
            mode=MODES[q.mode])

    def _right_matcher(self) -> tuple[tuple[float, int, int] | None, cv2.StereoMatcher | None]:
        """The right matcher WLS needs (None without WLS), and with a `check_scale` below 1 the
        (scale, min, num) of the smaller images it matches."""
        p = self._params
        if not p.wls:
            return None, None
        if p.check_scale >= 1.0:
            return None, cv2.ximgproc.createRightMatcher(self._left)
        cs = p.check_scale
        lo = int(math.floor(self._min_s * cs))
        top = (self._min_s + self._num_s - 1) * cs
        num = max(16, int(math.ceil((top - lo + 1) / 16.0)) * 16)
        # its window shrinks with the images (at least 3 px, odd), so that it covers about as
        # much of the scene and reaches nearer the right edge: points near the edge keep their
        # reading
        block = max(3, math.ceil(p.block_size * cs) | 1)
        return (cs, lo, num), cv2.ximgproc.createRightMatcher(self._sgbm(lo, num, block, p))

    def _fill_matchers(self) -> list[_Fill]:
        """Each size the hole fill tries, finest first (none without a second window or a
        `fill_scale`)."""
        p = self._params
        fills: list[_Fill] = []
        if self._second is None or p.fill_scale <= 0:
            return fills
        for level, mode in enumerate(fill_mode_names(p.fill_modes), start=1):
            fill_p = dataclasses.replace(p, mode=mode)
            fs = p.fill_scale ** level
            lo = int(math.floor(self._min_s * fs))
            # (searched no nearer than the matched images are: the largest disparity of theirs,
            # at this size, rounded down)
            top = math.floor((self._min_s + self._num_s - 1) * fs)
            num = max(16, int(math.ceil((top - lo + 1) / 16.0)) * 16)
            fills.append(_Fill(fs, lo, num, top, self._sgbm(lo, num, p.block_size, fill_p),
                               self._sgbm(lo, num, p.check_block_size, fill_p)))
        return fills

    def _wls_filter(self) -> cv2.ximgproc.DisparityWLSFilter | None:
        """The preset's WLS filter (None without one)."""
        p = self._params
        if not p.wls:
            return None
        # createDisparityWLSFilter switches off the uniqueness, speckle and left-right checks of
        # the matcher it is given: unless the preset asks for that (the seed preset reproduces
        # the reference loop's map, made so), it gets a copy of the matcher to configure itself
        # from
        wls = cv2.ximgproc.createDisparityWLSFilter(
            self._left if p.wls_disables_checks
            else self._sgbm(self._min_s, self._num_s, p.block_size, p))
        wls.setLambda(float(p.wls_lambda))
        wls.setSigmaColor(float(p.wls_sigma))
        return wls

    def _shading_maps(self) -> ShadingMaps | None:
        """(gain, offset) per camera that undo its lens shading (core.shading) in the full-size
        rectified images, or None when the calibration has none worth undoing."""
        shading = self.calibration.lens_shading
        if shading is None or shading.negligible:
            return None
        m = self._maps
        out = []
        for lens, maps in ((shading.left, None if m is None else (m.left_x, m.left_y)),
                           (shading.right, None if m is None else (m.right_x, m.right_y))):
            g = lens.gain_map(self.calibration.image_size)
            if maps is not None:  # a rectified pixel shows the raw pixel its map points at
                g = cv2.remap(g, maps[0], maps[1], cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
            out.append((g, lens.offset_map(g)))
        return out[0], out[1]

    @property
    def edge_margin_px(self) -> float:
        """Matches closer than this to the right image's left edge are not trusted (the matching
        block reaches into the padding), full-resolution px."""
        return (self._params.block_size // 2 + 1) / self._scale

    def _apply_pending(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, None
        if pending is not None and pending != self._preset:
            self._preset, self._params = pending, pending.matcher
            self._build()

    def _fit_range(self, ml: np.ndarray, mr: np.ndarray) -> bool:
        """Search up to the nearest surface in view (`core.scene_range`), matched images `ml`,
        `mr`: a nearer surface widens the range at once, a range wider than needed narrows after
        SCENE_SHRINK_FRAMES frames in a row have asked for it (the first frame sets it). At the
        preset's whole range only every LOOK_EVERY_AT_TOP-th frame is looked at. Whether this
        frame was."""
        frames = self._unlooked + 1  # the frames this look speaks for
        if self._at_top and frames < LOOK_EVERY_AT_TOP:
            self._unlooked = frames
            return False
        self._unlooked = 0
        p, s = self._params, self._scale
        d_min, d_max = p.disparity_limits(self.calibration)
        look = look_at_scene(ml, mr, d_min * s, d_max * s)
        top = look.top_px(d_max * s, d_min * s + SCENE_MIN_RANGE_PX) / s
        lo, num = p.matcher_range(self.calibration, s, top)
        first = self._scene_top_px is None
        if first:  # (the range a later look would narrow is the one the first frame set)
            self._scene_top_px = top
        if (lo, num) == (self._min_s, self._num_s):
            self._shrink_votes = 0
            return True
        if num < self._num_s and not first:
            self._shrink_votes += frames
            if self._shrink_votes < SCENE_SHRINK_FRAMES:
                return True
        self._shrink_votes = 0
        self._scene_top_px = top
        self._build()
        return True

    # ---- processing ----------------------------------------------------------------------
    def rectify(self, left_bgr: np.ndarray, right_bgr: np.ndarray, right_colour: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
        """Both raw images remapped into the rectified frame (identity calibrations: unchanged).
        With `right_colour` False the right one is remapped as gray (a third of the work: the
        matcher needs no more, and only a view of the right image needs its colours)."""
        if self._closed:
            raise RuntimeError("the stereo pipeline is closed")
        w, h = self.calibration.image_size
        for name, img in (("left", left_bgr), ("right", right_bgr)):
            if img is None or img.ndim not in (2, 3):
                raise InputError(f"the {name} image is not an image")
            if (img.shape[1], img.shape[0]) != (w, h):
                raise InputError(
                    f"the {name} image is {img.shape[1]}x{img.shape[0]} but the calibration is for "
                    f"{w}x{h}")
        if not right_colour:
            right_bgr = to_gray(right_bgr)
        if self._maps is None:
            return left_bgr, right_bgr
        m = self._maps
        interp = INTERPOLATIONS[self._params.remap_interpolation]
        rl = cv2.remap(left_bgr, m.left_x, m.left_y, interp)
        rr = cv2.remap(right_bgr, m.right_x, m.right_y, interp)
        return rl, rr

    def _match(self, ml: np.ndarray, mr: np.ndarray, right: bool = True
               ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Left, second-window and (for WLS, when `right`) right SGBM disparity x16 of
        matched-resolution gray images (None for a matcher the preset does not have).

        With `full_frame` the images are padded with black columns so that SGBM, which leaves
        its first minDisparity + numDisparities columns empty, searches the whole range at every
        column: at the left for the left matchers, at the right for the right matcher (whose
        empty band is on that side). Matches that land in the padding are removed afterwards
        (`unseen_mask`); black never resembles texture, so they are rare.
        """
        pad = self._min_s + self._num_s if self._params.full_frame else 0
        d16 = compute_padded(self._left, ml, mr, pad, "left")
        d16_second = (compute_padded(self._second, ml, mr, pad, "left")
                      if self._second is not None else None)
        d16_right = None
        if right and self._right is not None:
            match_right = self._match_right if self._check is not None else compute_padded
            d16_right = match_right(self._right, mr, ml, pad, "right")
        return d16, d16_second, d16_right

    def _fill_holes(self, fill: _Fill, agreed: np.ndarray, nl: np.ndarray, nr: np.ndarray,
                    ml: np.ndarray) -> float:
        """Fill `agreed` (the matched images' size and px, NaN holes; in place) where it has no
        value within `fill_depth_px`: with the agreement of the same two windows (`fill`, one of
        self._fills) on images made smaller by its scale (a window covers that much more of the
        scene), under the same checks (the left-right check, agreement within the same
        distance, the range's ends, occlusion, blank surfaces, what the right camera cannot
        see), and never farther than the map on both sides of the hole. The largest disparity
        filled in (full-resolution px; 0 for none).

        Only the inside of a hole is filled: at its rim a hole is mostly a depth edge, where a
        larger window takes the nearer surface's disparity past the edge, and the small windows
        already read what they can there."""
        fs = fill.scale
        p = self._params
        h, w = agreed.shape
        holes = cv2.compare(agreed, agreed, cv2.CMP_NE)  # 255 where NaN
        total = self._scale * fs  # the fill's images against the full-resolution ones
        depth = fill_depth_px(total) * self._scale
        inside = cv2.distanceTransform(holes, cv2.DIST_L2, 3) >= np.float32(depth)
        mapped = np.where(holes > 0, np.float32(-np.inf), agreed)
        cols = np.arange(w, dtype=np.float32)[None, :]
        margin = (p.check_block_size // 2 + 1) / fs
        # (the columns the right camera may not see, below, can only widen: with none left
        # there is nothing to fill, and the larger windows need not run, as on a textured scene)
        row_top = mapped.max(axis=1)  # each row's largest disparity of the map
        if not (inside & (cols >= (row_top + margin)[:, None])).any():
            return 0.0
        coarse = self._fill_agreement(fill, nl, nr, ml)
        small = coarse * np.float32(1.0 / fs)  # the map's px, at the fill's size
        coarse = enlarge(coarse, (w, h), p.agree_px * fs) * np.float32(1.0 / fs)
        take = inside & ~np.isnan(coarse)
        # nothing in the columns of a row that the right camera may not see: left of the row's
        # largest disparity (either map's) and the windows' margin. Weak texture in the strip
        # at the left edge matches far surfaces at random, and a row of a weak wall rarely has
        # values enough right of the strip to show that a nearer surface hides them
        top = np.maximum(np.where(take, coarse, -np.inf).max(axis=1), row_top)
        take &= cols >= (top + margin)[:, None]
        # nor a value farther than the map on both sides of the hole, along its row or its
        # column: a smooth object in front of a wall (a pole, a bar) is such a hole, and the
        # larger windows carry the wall's disparity in from around it
        take[take] = ~self._sunk_in_hole(take, small, mapped, fs)
        if not take.any():
            return 0.0
        agreed[take] = coarse[take]
        # a value filled in where the right camera sees a nearer surface of the map instead (in
        # the strip at the left edge that it cannot see, weak texture matches at random)
        hidden = np.zeros_like(take)
        rows = np.flatnonzero(take.any(axis=1))  # (the test is along rows: those filled in)
        hidden[rows] = take[rows] & occluded(agreed[rows], p.agree_px, self._reach)
        agreed[hidden] = np.nan
        take &= ~hidden
        return float(coarse[take].max()) / self._scale if take.any() else 0.0

    def _fill_agreement(self, fill: _Fill, nl: np.ndarray, nr: np.ndarray, ml: np.ndarray
                        ) -> np.ndarray:
        """The two windows' agreement (px of the fill's images) on the matched images made
        smaller by the fill's scale, under the frame's checks: the range's ends, occlusion,
        blank surfaces, matches whose window reached into the padding."""
        fs, lo, num, largest, first, second = fill
        p = self._params
        h, w = nl.shape[:2]
        total = self._scale * fs  # the fill's images against the full-resolution ones
        size = (max(1, round(w * fs)), max(1, round(h * fs)))
        sl, sr = (cv2.resize(m, size, interpolation=cv2.INTER_AREA) for m in (nl, nr))
        sm = sl if ml is nl else cv2.resize(ml, size, interpolation=cv2.INTER_AREA)
        pad = lo + num if p.full_frame else 0
        tol = p.agree_px * fs
        coarse = agreement(compute_padded(first, sl, sr, pad, "left"),
                           compute_padded(second, sl, sr, pad, "left"), lo, tol,
                           (lo + p.range_end_px, largest - p.range_end_px))
        blank(coarse, occluded(coarse, tol, self._reach))
        blank(coarse, blank_mask(sm, max(4, round(BLANK_HALF_PX * total)),
                                 max(1, round(BLANK_LAG_PX * total))))
        if p.full_frame:  # matches whose window reached into the padding
            blank(coarse, unseen_mask(coarse, p.check_block_size // 2 + 1))
        return coarse

    def _sunk_in_hole(self, take: np.ndarray, small: np.ndarray, mapped: np.ndarray, fs: float
                      ) -> np.ndarray:
        """For each pixel of `take` (the matched size), whether the fill's value it takes
        (`small`, px at the fill's size) lies farther than the map (`mapped`, -inf in holes) on
        both sides of its hole. Tested at the fill's size, fewer pixels: the map there holds the
        nearest value of each pixel's block, so that no edge of an object is lost; and only at
        the fill-size pixels that a pixel still to be filled takes its value from, as `enlarge`
        picks them."""
        h, w = take.shape
        nearest = cv2.dilate(mapped, np.ones((math.ceil(1 / fs),) * 2, np.uint8), anchor=(0, 0))
        nearest = cv2.resize(nearest, small.shape[::-1], interpolation=cv2.INTER_NEAREST)
        nearest[np.isneginf(nearest)] = np.nan
        ys, xs = np.nonzero(take)
        ys = nearest_source(h, small.shape[0])[ys]
        xs = nearest_source(w, small.shape[1])[xs]
        asked = np.full_like(small, np.nan)
        asked[ys, xs] = small[ys, xs]
        farther: np.ndarray = sunk(asked, nearest, self._params.agree_px)[ys, xs]
        return farther

    def _match_right(self, matcher: cv2.StereoMatcher, mr: np.ndarray, ml: np.ndarray, pad: int,
                     side: str) -> np.ndarray:
        """The right matcher's map for the left-right check, computed on images made smaller by
        `check_scale` and enlarged back to the matched size (values scaled; "no match" kept as
        the value a right matcher at the matched resolution gives it)."""
        assert self._check is not None  # (called only where the preset has a smaller check)
        cs, lo, num = self._check
        h, w = mr.shape[:2]
        size = (max(1, round(w * cs)), max(1, round(h * cs)))
        small = [cv2.resize(img, size, interpolation=cv2.INTER_AREA) for img in (mr, ml)]
        d = compute_padded(matcher, small[0], small[1], lo + num if pad else 0, side)
        # values scaled at the small size, then enlarged: nearest-neighbour enlargement only
        # picks pixels, so this is the same as scaling after it, on a quarter of the pixels
        scaled = np.clip(np.rint(d.astype(np.float32) / cs), -32768, 32767).astype(np.int16)
        none = d == (-(lo + num - 1) - 1) * DISP_SCALE  # the right matcher's "no match"
        scaled[none] = (-(self._min_s + self._num_s - 1) - 1) * DISP_SCALE
        enlarged: np.ndarray = cv2.resize(scaled, (w, h), interpolation=cv2.INTER_NEAREST)
        return enlarged

    def process(self, left_bgr: np.ndarray, right_bgr: np.ndarray, right_colour: bool = True,
                wls: bool = True, previous_scale: ColorScale | None = None) -> PipelineResult:
        """Run every stage on one raw stereo pair (`right_colour`: see `rectify`). With a second
        window the final map is the two windows' agreement and the WLS output only a picture:
        `wls` False skips it (and the right matcher it needs); without one, WLS is the final map
        and always runs. `previous_scale`: the colour scale of the stream's frame before (a
        "view" colour range stays put while the view stays in it, `color_scale`); the pipeline
        keeps no such state itself (its caller owns the stream)."""
        if self._closed:
            raise RuntimeError("the stereo pipeline is closed")
        self._apply_pending()
        laps = _Laps()
        rl, rr, gl, gr, ml, mr = self._prepare(left_bgr, right_bgr, right_colour, laps)
        p = self._params
        h, w = gl.shape[:2]
        run_wls = self._wls is not None and (wls or self._second is None)
        if p.normalize_window:
            nl, nr = (local_contrast(m, p.normalize_window) for m in (ml, mr))
            laps("normalize")
        else:
            nl, nr = ml, mr
        d16, d16_second, d16_right = self._match(nl, nr, right=run_wls)
        laps("match")
        raw, closed = self._raw_and_closed(d16, (w, h), laps)
        agreed, fill_top = (self._agreed(d16, d16_second, nl, nr, ml, (w, h), laps)
                            if d16_second is not None else (None, 0.0))
        band = into_padding = None
        if p.full_frame:
            top16 = int(d16.max()) if d16_second is None else max(int(d16.max()),
                                                                   int(d16_second.max()))
            band, into_padding = self._blank_padding(top16, fill_top, raw, closed, agreed, w)
        laps("convert")
        wls_px = confidence = None
        if run_wls:
            wls_px, confidence, band = self._filtered(d16, d16_right, gl, ml, (w, h), band)
            laps("wls")
        final = self._final_map(agreed, closed, wls_px, confidence)
        not_seen = None
        if p.full_frame:
            assert band is not None and into_padding is not None  # (both set for full_frame)
            not_seen = self._blank_not_seen(band, into_padding, raw, closed, wls_px, final)
        display = self._preset.display
        colours = color_scale(final, display, self.calibration, previous_scale)
        color = colorize(final, colours, display.colormap, not_seen, band)
        laps("colormap")
        return PipelineResult(
            rectified_left=rl, rectified_right=rr, disparity_px=raw, closed_px=closed,
            wls_px=wls_px, final_px=final, color_bgr=color, valid=np.isfinite(final),
            timings_ms=laps.with_total(), size=(w, h), preset=self._preset,
            disparity_range_px=self._range_full, calibration=self.calibration,
            color_scale=colours, wls_confidence=confidence, not_seen=not_seen,
            not_seen_cols=band, match_scale=self._scale, shading_gains=self._shading_full)

    def _prepare(self, left_bgr: np.ndarray, right_bgr: np.ndarray, right_colour: bool,
                 laps: _Laps) -> tuple[np.ndarray, ...]:
        """The rectified pair (colour; the right one grey without `right_colour`), its grey
        images (bilateral-filtered if the preset asks) and the grey images the matchers take
        (resized to the matched size, lens shading undone); the range fitted to the scene."""
        p = self._params
        rl, rr = self.rectify(left_bgr, right_bgr, right_colour)
        gl, gr = to_gray(rl), to_gray(rr)
        laps("rectify")
        if p.bilateral:
            gl = cv2.bilateralFilter(gl, p.bilateral_d, p.bilateral_sigma_color, p.bilateral_sigma_space)
            gr = cv2.bilateralFilter(gr, p.bilateral_d, p.bilateral_sigma_color, p.bilateral_sigma_space)
            laps("bilateral")
        h, w = gl.shape[:2]
        scale = self._scale
        if scale < 1.0:
            size_s = (max(1, round(w * scale)), max(1, round(h * scale)))
            ml = cv2.resize(gl, size_s, interpolation=cv2.INTER_AREA)
            mr = cv2.resize(gr, size_s, interpolation=cv2.INTER_AREA)
            laps("resize")
        else:
            ml, mr = gl, gr
        if self._shading_gains is not None:
            ml = undo_shading(ml, *self._shading_gains[0])
            mr = undo_shading(mr, *self._shading_gains[1])
            laps("shading")
        if p.range_from_scene and p.z_min_mm is not None:
            looked = self._fit_range(ml, mr)
            p = self._params
            if looked:
                laps("look")
        mw = ml.shape[1]
        if not p.full_frame and mw - (self._min_s + self._num_s) <= p.block_size // 2:
            raise InputError(
                f"the images ({w}x{h}, matched at {mw} px wide) are too narrow for disparities up to "
                f"{self._range_full[1]:.0f} px; narrow the disparity range or the working distances")
        return rl, rr, gl, gr, ml, mr

    def _raw_and_closed(self, d16: np.ndarray, size: tuple[int, int], laps: _Laps
                        ) -> tuple[np.ndarray, np.ndarray]:
        """The left matcher's map and its closing, in px at full size (the same array when the
        preset has no closing)."""
        closed16 = (cv2.morphologyEx(d16, cv2.MORPH_CLOSE, self._kernel)
                    if self._kernel is not None else d16)
        laps("closing")
        factor = 1.0 / self._scale
        raw = fixed_to_px(d16, self._min_s, factor)
        closed = fixed_to_px(closed16, self._min_s, factor) if closed16 is not d16 else raw
        if self._scale < 1.0:
            raw = cv2.resize(raw, size, interpolation=cv2.INTER_NEAREST)
            closed = (cv2.resize(closed, size, interpolation=cv2.INTER_NEAREST)
                      if closed16 is not d16 else raw)
        return raw, closed

    def _agreed(self, d16: np.ndarray, d16_second: np.ndarray, nl: np.ndarray, nr: np.ndarray,
                ml: np.ndarray, size: tuple[int, int], laps: _Laps) -> tuple[np.ndarray, float]:
        """The two windows' agreement in px at full size, checked (occlusion, blank surfaces),
        its holes filled at the fill's sizes; and the largest disparity filled in (full-size
        px, 0 for none)."""
        p, scale = self._params, self._scale
        agreed = agreement(d16, d16_second, self._min_s, p.agree_px,
                           (self._min_s + p.range_end_px,
                            self._min_s + self._num_s - 1 - p.range_end_px))
        blank(agreed, occluded(agreed, p.agree_px, self._reach))
        # what matched on a blank surface matched noise, however well the windows agree
        blank(agreed, blank_mask(ml, max(4, round(BLANK_HALF_PX * scale)),
                                 max(1, round(BLANK_LAG_PX * scale))))
        laps("agreement")
        fill_top = 0.0
        if self._fills:
            for fill in self._fills:  # each size fills what the ones before left
                fill_top = max(fill_top, self._fill_holes(fill, agreed, nl, nr, ml))
            laps("fill")
        if scale < 1.0:
            agreed = enlarge(agreed, size, p.agree_px) * np.float32(1.0 / scale)
            laps("enlarge")
        return agreed, fill_top

    def _blank_padding(self, top16: int, fill_top: float, raw: np.ndarray, closed: np.ndarray,
                       agreed: np.ndarray | None, w: int) -> tuple[int, np.ndarray]:
        """Blank the maps' matches that reach into the padding (full_frame), in place; the
        columns the right camera cannot see lie in the leftmost `band` (returned, with the
        padding's mask), found from the largest disparity of the maps (`top16` of the matched
        images, x16, and `fill_top`). At the matched resolution: the enlargements take or
        average their values; a closing never exceeds its input's largest value, being an
        erosion of a dilation. The masks are made and applied in the band only."""
        edge = self.edge_margin_px
        band = unseen_columns(max(top16 * (1.0 / self._scale) / DISP_SCALE, fill_top), edge, w)
        into_padding = unseen_mask(raw, edge, band)
        blank(raw, into_padding, band)
        if closed is not raw:
            blank(closed, unseen_mask(closed, edge, band), band)
        if agreed is not None:
            blank(agreed, unseen_mask(agreed, edge, band), band)
        return band, into_padding

    def _filtered(self, d16: np.ndarray, d16_right: np.ndarray | None, gl: np.ndarray,
                  ml: np.ndarray, size: tuple[int, int], band: int | None
                  ) -> tuple[np.ndarray, np.ndarray, int | None]:
        """The WLS filter's map in px at full size (NaN outside its region of interest and where
        it reaches into the padding), its confidence at that size, and the not-seen band widened
        to its values."""
        p, factor = self._params, 1.0 / self._scale
        wls_filter = self._wls
        assert wls_filter is not None  # (run only where the preset has one)
        w, h = size
        # the filter takes the unclosed left disparity (as the seed preset must, to be the
        # reference loop's); a low-resolution map is enlarged by the filter itself (values
        # scaled) against the full-resolution guide
        guide = gl if p.wls_full_resolution else ml
        if p.full_frame:
            f16 = wls_filter.filter(d16, guide, None, d16_right, (0, 0, ml.shape[1], ml.shape[0]))
        else:
            f16 = wls_filter.filter(d16, guide, None, d16_right)
        if guide is gl:
            wls_px = fixed_to_px(f16, self._min_s * factor)
        else:  # filtered at the matched resolution (4x fewer pixels), then enlarged
            wls_px = cv2.resize(fixed_to_px(f16, self._min_s, factor), size,
                                interpolation=cv2.INTER_LINEAR)
        # outside the filter's region of interest (without full_frame: the band at the left
        # edge that the matcher cannot see, in matched-image px) the output is not a measurement
        x, y, rw, rh = wls_filter.getROI()
        x0, x1 = int(x * factor), int((x + rw) * factor)
        y0, y1 = int(y * factor), int((y + rh) * factor)
        wls_px[:y0] = np.nan
        wls_px[y1:] = np.nan
        wls_px[:, :x0] = np.nan
        wls_px[:, x1:] = np.nan
        if p.full_frame:
            # (WLS may exceed its input's range: with a small lambda its few confident
            # neighbours can leave values up to int16's limit)
            top = int(f16.max()) * (1.0 if guide is gl else factor) / DISP_SCALE
            assert band is not None  # (set before for full_frame)
            edge = self.edge_margin_px
            band = max(band, unseen_columns(top, edge, w))
            blank(wls_px, unseen_mask(wls_px, edge, band), band)
        confidence = wls_filter.getConfidenceMap()
        if confidence.shape != wls_px.shape:
            confidence = cv2.resize(confidence, size, interpolation=cv2.INTER_NEAREST)
        return wls_px, confidence, band

    def _final_map(self, agreed: np.ndarray | None, closed: np.ndarray,
                   wls_px: np.ndarray | None, confidence: np.ndarray | None) -> np.ndarray:
        """The map the readings, views and exports take: the two windows' agreement, else the
        WLS map (only where it is confident, if the preset asks), else the closed map."""
        if agreed is not None:
            return agreed
        if wls_px is None:
            return closed
        if not self._params.wls_confident_only:
            return wls_px
        final = wls_px.copy()
        assert confidence is not None  # (given with wls_px)
        # (the confidence is never NaN: a map of 255 * min(...) >= 0)
        # (OpenCV's stubs refuse the number that cv2.compare takes as an operand)
        blank(final, cv2.compare(confidence, 0.0, cv2.CMP_LE))  # type: ignore[call-overload]
        return final

    def _blank_not_seen(self, band: int, into_padding: np.ndarray, raw: np.ndarray,
                        closed: np.ndarray, wls_px: np.ndarray | None, final: np.ndarray
                        ) -> np.ndarray:
        """The mask of what the right camera cannot see (in the leftmost `band` columns),
        blanked in every map, in place. The strip is known only once the final map has found
        where the surface at the edge is; whatever the matcher put there is a match the right
        camera cannot have made."""
        not_seen = unseen_strip(final, self.edge_margin_px, band)
        np.logical_or(not_seen[:, :band], into_padding[:, :band], out=not_seen[:, :band])
        for m in {id(a): a for a in (raw, closed, wls_px, final) if a is not None}.values():
            blank(m, not_seen, band)
        return not_seen
