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
import functools
import logging
import math
import threading
import time
import types
from collections.abc import Mapping
from dataclasses import dataclass, field

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.core.params import Param, check_all, from_json, param, params_of
from stereo_gui.core.shading import undo_shading
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.util import to_gray

log = logging.getLogger(__name__)

DISP_SCALE = 16  # OpenCV stereo matchers return disparity x16 (4 fractional bits)

MODES: dict[str, int] = {
    "sgbm": cv2.StereoSGBM_MODE_SGBM,
    "3way": cv2.StereoSGBM_MODE_SGBM_3WAY,
    "hh": cv2.StereoSGBM_MODE_HH,
    "hh4": cv2.StereoSGBM_MODE_HH4,
}

COLORMAPS: dict[str, int] = {
    name[len("COLORMAP_"):].lower(): getattr(cv2, name)
    for name in dir(cv2)
    if name.startswith("COLORMAP_")
}

COLOR_RANGES = ("minmax", "fixed", "view")
# colours of pixels without depth in every view and export: no match (dark red), and the strip
# the right camera cannot see (magenta); neither occurs in the colour maps' ramps near them
NO_MATCH_BGR = (20, 20, 110)
NOT_SEEN_BGR = (180, 40, 180)

INTERPOLATIONS: dict[str, int] = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC,
                                  "lanczos4": cv2.INTER_LANCZOS4}

# the reference loop's / OpenCV's names for some parameters, accepted when reading presets
ALIASES = {"window_size": "block_size", "minDisparity": "min_disparity",
           "numDisparities": "num_disparities", "uniquenessRatio": "uniqueness_ratio",
           "speckleWindowSize": "speckle_window_size", "speckleRange": "speckle_range",
           "disp12MaxDiff": "disp12_max_diff", "P1": "p1", "P2": "p2", "lmbda": "wls_lambda"}


def _multiple_of_16(v) -> bool:
    return v % 16 == 0


def _fill_scale(v) -> bool:
    return v == 0 or 0.25 <= v <= 0.5


def fill_mode_names(fill_modes: str) -> list[str]:
    """The SGBM modes of a `fill_modes` text, one per size the fill tries ("3way,hh")."""
    return [m.strip() for m in fill_modes.split(",")]


def _fill_modes(v) -> bool:
    modes = fill_mode_names(v)
    return 1 <= len(modes) <= 3 and all(m in MODES for m in modes)


def _normalize_window(v) -> bool:
    return v == 0 or (v >= 3 and v % 2 == 1)


@dataclass(frozen=True)
class MatcherParams:
    """Everything that decides how a frame becomes a disparity map. Sizes in px of the matched
    image unless said otherwise. Each field's range, unit and meaning are declared with it (its
    `Param`); building an object checks them once (InputError), nothing checks them per frame.

    Disparity range: `min_disparity`/`num_disparities` are full-resolution pixels; when
    `z_min_mm` is set the range is derived from the working distances instead (d = f*B/Z).
    """

    block_size: int = param(
        3, lo=1, hi=51, odd=True, unit="px", label="window_size", panel=(1, 21, 1),
        help="SGBM blockSize, odd (the reference loop: window_size = 3)")
    min_disparity: int = param(
        2, lo=-1024, hi=1024, unit="px", label="min_disp (px)", panel=(0, 64, 1),
        help="smallest disparity searched, full-resolution px")
    num_disparities: int = param(
        128, lo=16, hi=2048, unit="px", label="num_disp (px)", panel=(16, 256, 16),
        check=_multiple_of_16, check_text="a multiple of 16 from 16 to 2048",
        help="how many disparities are searched, full-resolution px")
    z_min_mm: float | None = param(
        None, lo=1.0, hi=1e6, unit="mm", label="nearest Z", panel=(50, 50000, 50),
        help="nearest working distance: sets the largest disparity (None: min_disp/num_disp)")
    z_max_mm: float | None = param(
        None, lo=1.0, hi=1e7, unit="mm", label="farthest Z", panel=(0, 100000, 500),
        help="farthest working distance: sets the smallest disparity (None: infinity)")
    uniqueness_ratio: int = param(10, lo=0, hi=100, unit="%", label="uniquenessRatio",
                                  panel=(0, 50, 1),
                                  help="how much the best match must beat the second, %")
    speckle_window_size: int = param(100, lo=0, hi=10_000, unit="px", label="speckleWindowSize",
                                     panel=(0, 300, 1),
                                     help="largest blob of disparities removed as speckle")
    speckle_range: int = param(32, lo=0, hi=1000, label="speckleRange", panel=(0, 64, 1),
                               help="disparity variation within a connected blob, x16 px")
    disp12_max_diff: int = param(5, lo=-1, hi=1000, unit="px", label="disp12MaxDiff",
                                 panel=(-1, 50, 1),
                                 help="left-right check tolerance (-1: no check)")
    p1: int | None = param(None, lo=0, hi=10_000_000, label="P1", panel=(0, 100000, 1),
                           help="small smoothness penalty (None: 8*3*w^2 as the reference loop)")
    p2: int | None = param(None, lo=0, hi=10_000_000, label="P2", panel=(0, 400000, 1),
                           help="large smoothness penalty (None: 32*3*w^2)")
    pre_filter_cap: int = param(63, lo=0, hi=63, label="preFilterCap", panel=(0, 63, 1),
                                help="clip of the prefiltered image (0: OpenCV's default, 15, "
                                     "as the reference loop left it)")
    mode: str = param("sgbm", choices=tuple(MODES), label="mode",
                      help="SGBM's mode: sgbm, 3way, hh or hh4")
    # two windows fail in different places (the small one on weak texture, the large one at
    # depth edges), so a wrong match rarely survives both
    check_block_size: int = param(
        0, lo=0, hi=51, odd=True, zero_off=True, unit="px",
        help="a second SGBM with this window checks the first: the final map keeps a pixel "
             "only where both found a match that agree within agree_px, and holds their mean "
             "(0: no second window; the final map is the WLS output, or the closed map)")
    agree_px: float = param(1.0, lo=0.0, hi=64.0, unit="px",
                            help="how far the two windows' matches may differ (matched image)")
    # a blank wall far away matches "at infinity" as well as anywhere
    range_end_px: float = param(
        0.0, lo=0.0, hi=64.0, unit="px",
        help="matches within this of either end of the searched range are dropped: the cost's "
             "minimum lay at the range's edge, so the surface may lie beyond it")
    # a rig with a long focal length or a wide baseline has hundreds of pixels of disparity
    # before its nearest working distance, far more than its scenes hold
    range_from_scene: bool = param(
        False, label="search only as far as the scene needs",
        help="with working distances (z_min_mm): search each frame only up to the "
             "nearest surface a quick match of shrunk images over the whole range finds, "
             "with a margin (core.scene_range); the whole range where it finds nothing")
    # the cameras' own gain, black level and darker corners, and the slow shading of a smooth
    # wall, should not decide a match
    normalize_window: int = param(
        0, lo=0, hi=255, unit="px", check=_normalize_window,
        check_text="an odd whole number from 3 to 255 (or 0: none)",
        help="match both images after a local contrast normalisation over this window: each "
             "pixel's difference from the window's mean in units of its spread (0: as they are)")
    # the same two windows on smaller images cover more of the scene: on a smooth wall whose
    # texture is too faint for the small windows they still find the surface
    fill_scale: float = param(
        0.0, lo=0.0, hi=0.5, check=_fill_scale,
        check_text="0 (off) or a number from 0.25 to 0.5",
        help="with a second window: the final map's holes (beyond fill_depth_px of any value) "
             "take the two windows' agreement found on images made smaller by this, where it "
             "passes the same checks (0: off)")
    # a hole the first smaller size leaves may lie on texture fainter still; eight directions
    # (hh) carry a surface's match across weak texture that three passes lose, and cost little
    # on small images
    fill_modes: str = param(
        "3way", check=_fill_modes, check_text="one to three of SGBM's modes (sgbm, 3way, hh, "
                                               "hh4), separated by commas",
        help="SGBM's mode at each size the fill tries, finest first, each size fill_scale "
             "times the one before: each fills only what the ones before left")
    # SGBM leaves the first minDisparity + numDisparities columns empty otherwise
    full_frame: bool = param(
        True, help="search the whole disparity range at every column (images padded for the "
                   "matchers); False keeps the reference loop's dead band at the left edge")
    remap_interpolation: str = param("linear", choices=tuple(INTERPOLATIONS),
                                     help="interpolation of the rectifying remap")
    closing_kernel: int = param(3, lo=0, hi=51, unit="px", label="kernel (px)", panel=(0, 15, 1),
                                help="side of the square closing kernel, px (the reference loop: "
                                     "3); 0 = off")
    wls: bool = param(True, label="WLS filter",
                      help="right matcher + cv2.ximgproc.createDisparityWLSFilter, as the "
                           "reference loop")
    wls_lambda: float = param(80000.0, lo=0.0, hi=1e7, label="lmbda", panel=(0, 1e6, 1000),
                              help="WLS smoothness (the reference loop's lmbda)")
    wls_sigma: float = param(1.8, lo=0.0, hi=100.0, label="sigma", panel=(0.0, 10.0, 0.1),
                             help="WLS sensitivity to the guide image's edges")
    wls_full_resolution: bool = param(
        True, help="filter against the full-resolution left image (False: at the matched "
                   "resolution, then enlarged; 4x fewer pixels for a half-resolution preset)")
    # elsewhere (no match, occlusions, failed consistency) the filter invents values from the
    # neighbours
    wls_confident_only: bool = param(
        True, help="keep the WLS output only where its left-right confidence is above zero")
    wls_disables_checks: bool = param(
        False, help="OpenCV's WLS filter turns off the matcher's uniqueness, speckle and "
                    "left-right checks when made from it; True reproduces that")
    # an eighth of the work at 0.5: half the width, height and range
    check_scale: float = param(
        1.0, lo=0.25, hi=1.0,
        help="the right matcher (the left-right check behind the WLS confidence) runs on images "
             "made smaller by this, its map enlarged back (1.0: at the matched resolution, as "
             "OpenCV's samples do)")
    bilateral: bool = param(False, help="bilateral filter on the rectified images before matching")
    bilateral_d: int = param(5, lo=0, hi=50, unit="px", help="bilateral filter's diameter")
    bilateral_sigma_color: float = param(25.0, lo=0.0, hi=1000.0,
                                         help="bilateral filter's sigma in grey levels")
    bilateral_sigma_space: float = param(5.0, lo=0.0, hi=1000.0, unit="px",
                                         help="bilateral filter's sigma in space")
    scale: float = param(1.0, lo=0.1, hi=1.0, label="match at scale",
                         help="1.0 = full resolution; 0.5 = match on INTER_AREA-halved images")
    # so that a preset keeps its speed at 1280x720
    max_match_width: int | None = param(
        None, lo=64, hi=100_000, unit="px",
        help="match on images at most this wide: a larger camera frame lowers the scale further "
             "(None: scale alone)")

    def __post_init__(self) -> None:
        check_all(self, "matcher parameters")
        if self.z_max_mm is not None and (self.z_min_mm is None or self.z_max_mm <= self.z_min_mm):
            raise InputError("matcher parameters: z_max_mm needs z_min_mm and must be larger "
                             "than it")

    # ---- derived -------------------------------------------------------------------------
    @property
    def p1_value(self) -> int:
        return int(self.p1) if self.p1 is not None else 8 * 3 * self.block_size**2

    @property
    def p2_value(self) -> int:
        return int(self.p2) if self.p2 is not None else 32 * 3 * self.block_size**2

    def effective_scale(self, width_px: int) -> float:
        """The scale frames `width_px` wide are matched at (`scale`, lowered to keep the matched
        image at most `max_match_width` px wide)."""
        if self.max_match_width is None or width_px <= 0:
            return self.scale
        return min(self.scale, max(0.1, self.max_match_width / float(width_px)))

    def disparity_limits(self, calibration: StereoCalibration) -> tuple[float, float]:
        """(smallest, largest) disparity the preset must find, full-resolution px."""
        if self.z_min_mm is None:
            return float(self.min_disparity), float(self.min_disparity + self.num_disparities - 1)
        fb = calibration.focal_px * calibration.rectified_baseline_mm
        doffs = calibration.disparity_offset_px  # d = f B / Z - doffs
        d_min = fb / self.z_max_mm - doffs if self.z_max_mm else -doffs  # (infinity)
        return d_min, fb / self.z_min_mm - doffs

    def matcher_range(self, calibration: StereoCalibration, scale: float | None = None,
                      top_px: float | None = None) -> tuple[int, int]:
        """(minDisparity, numDisparities) for SGBM on images at `scale` (default self.scale);
        `top_px`: search no further than this disparity (full-resolution px) if it is below the
        preset's own largest."""
        s = self.scale if scale is None else scale
        d_min, d_max = self.disparity_limits(calibration)
        if top_px is not None:
            d_max = max(d_min, min(d_max, top_px))
        lo = max(0, int(math.floor(d_min * s))) if self.z_min_mm is not None else int(math.floor(d_min * s))
        num = int(math.ceil((d_max * s - lo + 1) / 16.0)) * 16
        return lo, max(16, num)

    def disparity_range(self, calibration: StereoCalibration) -> tuple[int, int]:
        """(min_disparity, num_disparities) in full-resolution px for this calibration."""
        return self.matcher_range(calibration, 1.0)

    def replace(self, **changes) -> MatcherParams:
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class DisplayParams:
    """How a disparity map is coloured for the views and exports."""

    colormap: str = param("ocean", choices=tuple(sorted(COLORMAPS)), label="colour map",
                          help="OpenCV colour map of the depth view")
    # "minmax" (the seed preset's) normalises every frame, so colours drift with the scene
    color_range: str = param("minmax", choices=COLOR_RANGES,
                             help="minmax: each frame's own range; fixed: a colour always means "
                                  "the same distance; view: a round distance range that follows "
                                  "the distances in view (near and far when nothing is in view)")
    color_z_near_mm: float = param(500.0, lo=1.0, hi=1e7, unit="mm", label="near",
                                   panel=(50, 50000, 1),
                                   help="fixed colour range: this distance gets the top colour "
                                        "(and the range that follows the view, while nothing "
                                        "is in view)")
    color_z_far_mm: float = param(3000.0, lo=1.0, hi=1e7, unit="mm", label="far",
                                  panel=(100, 100000, 1),
                                  help="fixed colour range: this distance gets the bottom colour "
                                       "(and the range that follows the view, while nothing "
                                       "is in view)")

    def __post_init__(self) -> None:
        check_all(self, "display parameters")
        if self.color_z_far_mm <= self.color_z_near_mm:
            raise InputError("display parameters: color_z_far_mm must be larger than "
                             "color_z_near_mm")


@dataclass(frozen=True)
class ThreadParams:
    """How many threads process frames: the Live tab's lanes and OpenCV's pool."""

    parallel: bool = param(False, label="use two CPU cores",
                           help="Live: two frames processed at once, one on each core; "
                                "elsewhere the left and right matchers at once")
    cv_threads: int | None = param(None, lo=0, hi=256,
                                   help="OpenCV's thread count for the process, set where the "
                                        "preset runs (pipeline.concurrency; None: leave as is)")

    def __post_init__(self) -> None:
        check_all(self, "thread parameters")


_PARTS = {"matcher": MatcherParams, "display": DisplayParams, "threads": ThreadParams}
# which part declares each flat key of a preset's parameters
_PART_OF = {key: part for part, cls in _PARTS.items() for key in params_of(cls)}
# every parameter of a preset by its flat name, with its declaration
PRESET_PARAMS: Mapping[str, Param] = types.MappingProxyType(
    {key: spec for cls in _PARTS.values() for key, spec in params_of(cls).items()})


@dataclass(frozen=True)
class Preset:
    """A named set of parameters: how to match (`matcher`), how to colour (`display`) and how
    many threads to use (`threads`). Files hold them as one flat object of the three parts'
    fields (`to_dict`/`from_dict`)."""

    name: str = "custom"
    description: str = ""
    matcher: MatcherParams = field(default_factory=MatcherParams)
    display: DisplayParams = field(default_factory=DisplayParams)
    threads: ThreadParams = field(default_factory=ThreadParams)

    def replace(self, **changes) -> Preset:
        """This preset with `changes`: name, description, whole parts, or any part's field by
        its own name (routed to the part that declares it)."""
        top = {k: changes.pop(k) for k in list(changes) if k in _PARTS or k in ("name",
                                                                                "description")}
        unknown = set(changes) - set(_PART_OF)
        if unknown:
            raise TypeError(f"no preset parameter named {', '.join(sorted(unknown))}")
        for part in _PARTS:
            mine = {k: v for k, v in changes.items() if _PART_OF[k] == part}
            if mine:
                top[part] = dataclasses.replace(top.get(part, getattr(self, part)), **mine)
        return dataclasses.replace(self, **top)

    def get(self, key: str):
        """The value of a part's field by its flat name (a key of PRESET_PARAMS)."""
        return getattr(getattr(self, _PART_OF[key]), key)

    @classmethod
    def of(cls, params: Preset | MatcherParams | None) -> Preset:
        """`params` as a preset (bare matcher parameters: with the default display and threads)."""
        if params is None:
            return cls()
        return params if isinstance(params, Preset) else cls(matcher=params)

    # ---- persistence ---------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The flat object files hold: name, description, then the matcher's, display's and
        threads' fields."""
        out = {"name": self.name, "description": self.description}
        for part in _PARTS:
            out.update(dataclasses.asdict(getattr(self, part)))
        return out

    @classmethod
    def from_dict(cls, data: dict, where: str = "preset") -> Preset:
        """Build from a flat object (the reference loop's / OpenCV's names understood); unknown
        keys are logged and skipped, bad values raise InputError naming `where`."""
        if not isinstance(data, dict):
            raise InputError(f"{where}: expected a JSON object of matcher parameters")
        flat = {}
        for key, value in data.items():
            key = ALIASES.get(key, key)
            if key not in _PART_OF and key not in ("name", "description"):
                log.warning("%s: unknown matcher parameter %r ignored", where, key)
                continue
            flat[key] = value
        top = {}
        for key in ("name", "description"):
            if key in flat:
                if not isinstance(flat[key], str):
                    raise InputError(f"{where}: {key} must be a string")
                top[key] = flat[key]
        for part, part_cls in _PARTS.items():
            kwargs = from_json(part_cls, flat, where)
            try:
                top[part] = part_cls(**kwargs)
            except InputError as exc:
                raise InputError(f"{where}: {exc}") from None
        return cls(**top)


# per camera (left, right): the gain and offset maps that undo its lens shading (core.shading)
ShadingMaps = tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


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


def fixed_to_px(disp16: np.ndarray, min_disparity: float, factor: float = 1.0) -> np.ndarray:
    """The one place where OpenCV's x16 fixed point becomes float pixels.

    Values below `min_disparity` (in the map's own pixels; OpenCV marks invalid pixels with
    (minDisparity-1)*16) become NaN. `factor` converts to full-resolution px (1/scale).
    """
    out = disp16.astype(np.float32)
    out *= np.float32(factor / DISP_SCALE)
    out[disp16 < min_disparity * DISP_SCALE] = np.nan
    return out


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

    def level(self, disparity_px: np.ndarray) -> np.ndarray:
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


@functools.lru_cache(maxsize=8)
def _nan_image(h: int, w: int) -> np.ndarray:
    img = np.full((h, w), np.nan, np.float32)
    img.setflags(write=False)
    return img


def blank(disparity_px: np.ndarray, mask: np.ndarray, cols: int | None = None) -> None:
    """Set the pixels of a float32 H x W map where `mask` (bool or uint8) is set to NaN, in
    place (cv2.copyTo: many times faster than numpy's boolean assignment at 1280x720, the more so
    the more pixels are set). `cols`: the mask is set only in the leftmost `cols` columns (only
    those are looked at)."""
    if cols is not None and cols < disparity_px.shape[1]:
        disparity_px, mask = disparity_px[:, :max(0, cols)], mask[:, :max(0, cols)]
    if not (disparity_px.flags.c_contiguous or _rows_contiguous(disparity_px)) \
            or disparity_px.dtype != np.float32:
        disparity_px[mask.astype(bool, copy=False)] = np.nan  # (OpenCV would write a copy)
        return
    if mask.dtype == np.bool_:
        mask = mask.view(np.uint8)
    h, w = disparity_px.shape
    cv2.copyTo(_nan_image(h, w), mask, disparity_px)


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


def _rows_contiguous(a: np.ndarray) -> bool:
    """Each row of `a` contiguous and the rows evenly spaced (a column slice of a C-contiguous
    array): OpenCV then writes into it in place."""
    return a.ndim == 2 and a.strides[1] == a.itemsize and a.strides[0] >= a.shape[1] * a.itemsize


# range_from_scene: a range a frame could narrow is narrowed after this many frames in a row asked
# for it (a nearer surface widens it at once); the range is never narrower than this (matched px)
SCENE_SHRINK_FRAMES = 15
SCENE_MIN_RANGE_PX = 16


class StereoPipeline:
    """Turns raw stereo frames into `PipelineResult`s for one calibration and preset.

    Runs a frame's stages one after the other in the calling thread (frames in flight are the
    parallelism, pipeline.concurrency), so it is not for use by several threads at once;
    `set_params` may be called from any thread and takes effect with the next frame. `close()`
    (or the end of a `with` block) releases its rectification maps and matchers and ends its
    use: a closed pipeline refuses to rectify or process.
    """

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
        self._closed = True
        self._maps = None
        self._left = self._second = self._right = self._wls = None
        self._shading_full = self._shading_gains = None

    def __enter__(self) -> StereoPipeline:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _build(self) -> None:
        p = self._params
        s = self._scale = p.effective_scale(self.calibration.width)
        fitted = p.range_from_scene and p.z_min_mm is not None
        self._min_s, self._num_s = p.matcher_range(self.calibration, s,
                                                   self._scene_top_px if fitted else None)
        self._range_full = (self._min_s / s, (self._min_s + self._num_s - 1) / s)
        def sgbm(lo=self._min_s, num=self._num_s, block=p.block_size, q=p):
            area = (block / q.block_size) ** 2  # the penalties grow with the window's area
            return cv2.StereoSGBM_create(
                minDisparity=lo, numDisparities=num, blockSize=block,
                P1=round(q.p1_value * area), P2=round(q.p2_value * area),
                disp12MaxDiff=q.disp12_max_diff,
                preFilterCap=q.pre_filter_cap, uniquenessRatio=q.uniqueness_ratio,
                speckleWindowSize=q.speckle_window_size, speckleRange=q.speckle_range,
                mode=MODES[q.mode])

        self._left = sgbm()
        self._second = sgbm(block=p.check_block_size) if p.check_block_size else None
        self._check: tuple[float, int, int] | None = None  # (scale, min, num) of a smaller check
        if p.wls and p.check_scale < 1.0:
            cs = p.check_scale
            lo = int(math.floor(self._min_s * cs))
            top = (self._min_s + self._num_s - 1) * cs
            num = max(16, int(math.ceil((top - lo + 1) / 16.0)) * 16)
            self._check = (cs, lo, num)
            # its window shrinks with the images (at least 3 px, odd), so that it covers about
            # as much of the scene and reaches nearer the right edge: points near the edge keep
            # their reading
            block = max(3, math.ceil(p.block_size * cs) | 1)
            self._right = cv2.ximgproc.createRightMatcher(sgbm(lo, num, block))
        else:
            self._right = cv2.ximgproc.createRightMatcher(self._left) if p.wls else None
        # how far right of an empty pixel the occlusion test looks for a nearer surface: the
        # larger window's half
        self._reach = max(p.block_size, p.check_block_size) // 2 + 1
        # (scale, min, num, largest disparity, first and second window's matchers) of each size
        # the fill tries, finest first
        self._fills: list[tuple] = []
        if self._second is not None and p.fill_scale > 0:
            for level, mode in enumerate(fill_mode_names(p.fill_modes), start=1):
                fill_p = dataclasses.replace(p, mode=mode)
                fs = p.fill_scale ** level
                lo = int(math.floor(self._min_s * fs))
                # (searched no nearer than the matched images are: the largest disparity of
                # theirs, at this size, rounded down)
                top = math.floor((self._min_s + self._num_s - 1) * fs)
                num = max(16, int(math.ceil((top - lo + 1) / 16.0)) * 16)
                self._fills.append((fs, lo, num, top, sgbm(lo, num, p.block_size, fill_p),
                                    sgbm(lo, num, p.check_block_size, fill_p)))
        self._wls = None
        if p.wls:
            # createDisparityWLSFilter switches off the uniqueness, speckle and left-right checks
            # of the matcher it is given: unless the preset asks for that (the seed preset
            # reproduces the reference loop's map, made so), it gets a copy of the matcher to
            # configure itself from
            self._wls = cv2.ximgproc.createDisparityWLSFilter(
                self._left if p.wls_disables_checks else sgbm())
            self._wls.setLambda(float(p.wls_lambda))
            self._wls.setSigmaColor(float(p.wls_sigma))
        self._kernel = (np.ones((p.closing_kernel, p.closing_kernel), np.uint8)
                        if p.closing_kernel > 1 else None)
        self._shading_full = self._shading_maps()
        self._shading_gains = self._shading_full
        if self._shading_full is not None and s < 1.0:
            w, h = self.calibration.image_size
            size_s = (max(1, round(w * s)), max(1, round(h * s)))
            self._shading_gains = tuple(  # the full-size maps, shrunk as the images are
                tuple(cv2.resize(m, size_s, interpolation=cv2.INTER_AREA) for m in maps)
                for maps in self._shading_full)

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

    def _fit_range(self, ml: np.ndarray, mr: np.ndarray) -> None:
        """Search up to the nearest surface in view (`core.scene_range`), matched images `ml`,
        `mr`: a nearer surface widens the range at once, a range wider than needed narrows after
        SCENE_SHRINK_FRAMES frames in a row have asked for it (the first frame sets it)."""
        from stereo_gui.core.scene_range import look_at_scene

        p, s = self._params, self._scale
        d_min, d_max = p.disparity_limits(self.calibration)
        look = look_at_scene(ml, mr, d_min * s, d_max * s)
        top = look.top_px(d_max * s, d_min * s + SCENE_MIN_RANGE_PX) / s
        lo, num = p.matcher_range(self.calibration, s, top)
        if (lo, num) == (self._min_s, self._num_s):
            self._shrink_votes = 0
            return
        first = self._scene_top_px is None
        if num < self._num_s and not first:
            self._shrink_votes += 1
            if self._shrink_votes < SCENE_SHRINK_FRAMES:
                return
        self._shrink_votes = 0
        self._scene_top_px = top
        self._build()

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

    def _fill_holes(self, fill: tuple, agreed: np.ndarray, nl: np.ndarray, nr: np.ndarray,
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
        fs, lo, num, largest, first, second = fill
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
        small = coarse * np.float32(1.0 / fs)  # the map's px, at the fill's size
        coarse = enlarge(coarse, (w, h), tol) * np.float32(1.0 / fs)
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
        # (tested at the fill's size, fewer pixels: the map there holds the nearest value of
        # each pixel's block, so that no edge of an object is lost)
        nearest = cv2.dilate(mapped, np.ones((math.ceil(1 / fs),) * 2, np.uint8), anchor=(0, 0))
        nearest = cv2.resize(nearest, small.shape[::-1], interpolation=cv2.INTER_NEAREST)
        nearest[np.isneginf(nearest)] = np.nan
        # (only the fill-size pixels that a pixel still to be filled takes its value from, as
        # `enlarge` picks them, are tested)
        ys, xs = np.nonzero(take)
        ys = _nearest_source(h, small.shape[0])[ys]
        xs = _nearest_source(w, small.shape[1])[xs]
        asked = np.full_like(small, np.nan)
        asked[ys, xs] = small[ys, xs]
        take[take] = ~_sunk(asked, nearest, p.agree_px)[ys, xs]
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

    def _match_right(self, matcher, mr: np.ndarray, ml: np.ndarray, pad: int, side: str
                     ) -> np.ndarray:
        """The right matcher's map for the left-right check, computed on images made smaller by
        `check_scale` and enlarged back to the matched size (values scaled; "no match" kept as
        the value a right matcher at the matched resolution gives it)."""
        cs, lo, num = self._check
        h, w = mr.shape[:2]
        size = (max(1, round(w * cs)), max(1, round(h * cs)))
        small = [cv2.resize(img, size, interpolation=cv2.INTER_AREA) for img in (mr, ml)]
        d = compute_padded(matcher, *small, lo + num if pad else 0, side)
        # values scaled at the small size, then enlarged: nearest-neighbour enlargement only
        # picks pixels, so this is the same as scaling after it, on a quarter of the pixels
        scaled = np.clip(np.rint(d.astype(np.float32) / cs), -32768, 32767).astype(np.int16)
        none = d == (-(lo + num - 1) - 1) * DISP_SCALE  # the right matcher's "no match"
        scaled[none] = (-(self._min_s + self._num_s - 1) - 1) * DISP_SCALE
        return cv2.resize(scaled, (w, h), interpolation=cv2.INTER_NEAREST)

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
        p = self._params
        t = {}
        t0 = time.perf_counter()

        def lap(name: str) -> None:
            nonlocal t0
            now = time.perf_counter()
            t[name] = (now - t0) * 1000.0
            t0 = now

        start = t0
        rl, rr = self.rectify(left_bgr, right_bgr, right_colour)
        gl, gr = to_gray(rl), to_gray(rr)
        lap("rectify")
        if p.bilateral:
            gl = cv2.bilateralFilter(gl, p.bilateral_d, p.bilateral_sigma_color, p.bilateral_sigma_space)
            gr = cv2.bilateralFilter(gr, p.bilateral_d, p.bilateral_sigma_color, p.bilateral_sigma_space)
            lap("bilateral")
        h, w = gl.shape[:2]
        scale = self._scale
        if scale < 1.0:
            size_s = (max(1, round(w * scale)), max(1, round(h * scale)))
            ml = cv2.resize(gl, size_s, interpolation=cv2.INTER_AREA)
            mr = cv2.resize(gr, size_s, interpolation=cv2.INTER_AREA)
            lap("resize")
        else:
            ml, mr = gl, gr
        if self._shading_gains is not None:
            ml = undo_shading(ml, *self._shading_gains[0])
            mr = undo_shading(mr, *self._shading_gains[1])
            lap("shading")
        if p.range_from_scene and p.z_min_mm is not None:
            self._fit_range(ml, mr)
            p = self._params
            lap("look")
        mw = ml.shape[1]
        if not p.full_frame and mw - (self._min_s + self._num_s) <= p.block_size // 2:
            raise InputError(
                f"the images ({w}x{h}, matched at {mw} px wide) are too narrow for disparities up to "
                f"{self._range_full[1]:.0f} px; narrow the disparity range or the working distances")
        run_wls = self._wls is not None and (wls or self._second is None)
        if p.normalize_window:
            nl, nr = (local_contrast(m, p.normalize_window) for m in (ml, mr))
            lap("normalize")
        else:
            nl, nr = ml, mr
        d16, d16_second, d16_right = self._match(nl, nr, right=run_wls)
        lap("match")
        closed16 = (cv2.morphologyEx(d16, cv2.MORPH_CLOSE, self._kernel)
                    if self._kernel is not None else d16)
        lap("closing")
        factor = 1.0 / scale
        raw = fixed_to_px(d16, self._min_s, factor)
        closed = fixed_to_px(closed16, self._min_s, factor) if closed16 is not d16 else raw
        if scale < 1.0:
            raw = cv2.resize(raw, (w, h), interpolation=cv2.INTER_NEAREST)
            closed = (cv2.resize(closed, (w, h), interpolation=cv2.INTER_NEAREST)
                      if closed16 is not d16 else raw)
        agreed = None
        fill_top = 0.0
        if d16_second is not None:
            agreed = agreement(d16, d16_second, self._min_s, p.agree_px,
                               (self._min_s + p.range_end_px,
                                self._min_s + self._num_s - 1 - p.range_end_px))
            blank(agreed, occluded(agreed, p.agree_px, self._reach))
            # what matched on a blank surface matched noise, however well the windows agree
            blank(agreed, blank_mask(ml, max(4, round(BLANK_HALF_PX * scale)),
                                     max(1, round(BLANK_LAG_PX * scale))))
            lap("agreement")
            if self._fills:
                for fill in self._fills:  # each size fills what the ones before left
                    fill_top = max(fill_top, self._fill_holes(fill, agreed, nl, nr, ml))
                lap("fill")
            if scale < 1.0:
                agreed = enlarge(agreed, (w, h), p.agree_px) * np.float32(factor)
                lap("enlarge")
        edge = self.edge_margin_px
        # what the right camera cannot see lies in the leftmost `band` columns, found from the
        # largest disparity of the maps (at the matched resolution: the enlargements take or
        # average their values; a closing never exceeds its input's largest value, being an
        # erosion of a dilation); the masks are made and applied there only
        band = None
        if p.full_frame:
            top16 = int(d16.max()) if d16_second is None else max(int(d16.max()),
                                                                   int(d16_second.max()))
            band = unseen_columns(max(top16 * factor / DISP_SCALE, fill_top), edge, w)
            into_padding = unseen_mask(raw, edge, band)
            blank(raw, into_padding, band)
            if closed is not raw:
                blank(closed, unseen_mask(closed, edge, band), band)
            if agreed is not None:
                blank(agreed, unseen_mask(agreed, edge, band), band)
        lap("convert")
        wls_px = confidence = None
        if run_wls:
            # the filter takes the unclosed left disparity (as the seed preset must, to be the
            # reference loop's); a low-resolution map is enlarged by the filter itself (values
            # scaled) against the full-resolution guide
            guide = gl if p.wls_full_resolution else ml
            if p.full_frame:
                f16 = self._wls.filter(d16, guide, None, d16_right, (0, 0, mw, ml.shape[0]))
            else:
                f16 = self._wls.filter(d16, guide, None, d16_right)
            if guide is gl:
                wls_px = fixed_to_px(f16, self._min_s * factor)
            else:  # filtered at the matched resolution (4x fewer pixels), then enlarged
                wls_px = cv2.resize(fixed_to_px(f16, self._min_s, factor), (w, h),
                                    interpolation=cv2.INTER_LINEAR)
            # outside the filter's region of interest (without full_frame: the band at the left
            # edge that the matcher cannot see, in matched-image px) the output is not a measurement
            x, y, rw, rh = self._wls.getROI()
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
                band = max(band, unseen_columns(top, edge, w))
                blank(wls_px, unseen_mask(wls_px, edge, band), band)
            confidence = self._wls.getConfidenceMap()
            if confidence.shape != wls_px.shape:
                confidence = cv2.resize(confidence, (w, h), interpolation=cv2.INTER_NEAREST)
            lap("wls")
        not_seen = None
        if agreed is not None:
            final = agreed
        elif wls_px is None:
            final = closed
        elif p.wls_confident_only:
            final = wls_px.copy()
            # (the confidence is never NaN: a map of 255 * min(...) >= 0)
            blank(final, cv2.compare(confidence, 0.0, cv2.CMP_LE))
        else:
            final = wls_px
        if p.full_frame:
            # the strip is known only once the final map has found where the surface at the edge
            # is; whatever the matcher put there is a match the right camera cannot have made
            not_seen = unseen_strip(final, edge, band)
            np.logical_or(not_seen[:, :band], into_padding[:, :band], out=not_seen[:, :band])
            for m in {id(a): a for a in (raw, closed, wls_px, final) if a is not None}.values():
                blank(m, not_seen, band)
        valid = np.isfinite(final)
        display = self._preset.display
        colours = color_scale(final, display, self.calibration, previous_scale)
        color = colorize(final, colours, display.colormap, not_seen, band)
        lap("colormap")
        t["total"] = (time.perf_counter() - start) * 1000.0
        return PipelineResult(
            rectified_left=rl, rectified_right=rr, disparity_px=raw, closed_px=closed,
            wls_px=wls_px, final_px=final, color_bgr=color, valid=valid, timings_ms=t,
            size=(w, h), preset=self._preset, disparity_range_px=self._range_full,
            calibration=self.calibration, color_scale=colours, wls_confidence=confidence,
            not_seen=not_seen, not_seen_cols=band, match_scale=scale,
            shading_gains=self._shading_full)


# `fill_scale` fills only the pixels of a hole at least this far from the final map's values
# (full-resolution px): at a hole's rim the larger windows carry a nearer surface past its edge.
# `stereo-gui bench --scenes` (13 scenes), quality with fill_scale 0.5: filling every hole
# raised the mean bad-2 from 8.7 % to 11.7 % and left 7 scenes outside their margins (2
# before); from 3 px in, 9.3 % at 1.2 points more density, every scene's verdict unchanged.
# That is for a fill on images at half the full resolution; on smaller ones the windows cover
# more of the scene and carry a surface as much farther past its edge (`fill_depth_px`)
FILL_DEPTH_PX = 3.0


def fill_depth_px(total_scale: float) -> float:
    """How far inside a hole (full-resolution px) a fill on images at `total_scale` of the full
    resolution may write: FILL_DEPTH_PX at a half, twice that at a quarter."""
    return FILL_DEPTH_PX * max(1.0, 0.5 / total_scale)

# a window is blank (nothing but sensor noise) when its pixels correlate with their neighbours
# BLANK_LAG_PX away by less than BLANK_MIN_CORRELATION, over windows of BLANK_HALF_PX (full-
# resolution px; both shrink with a preset's scale, the lag to no less than 1). On 49 x 49
# windows that is 7 standard deviations of what noise alone gives (3 with the correlation the
# rectification's interpolation leaves between neighbours)
BLANK_HALF_PX = 24
BLANK_LAG_PX = 2
BLANK_MIN_CORRELATION = 0.15
BLANK_NOISE_RATIO = 3.0  # ... and whose spread is at most this many times the noise level
SENSOR_NOISE_MAX = 4.0  # grey levels


def sensor_noise(gray: np.ndarray) -> float:
    """The image's noise level, grey levels (1 sigma): Immerkaer's estimate from a second-
    difference kernel's response, its robust median so that texture and edges (a minority of a
    frame) do not count. Resampled images (rectified, shrunk) come out lower than the sensor's:
    their noise is smoothed."""
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    if gray.dtype == np.uint8 and min(gray.shape[:2]) > 2:
        # a uint8 image's response is a whole number within +-4080: its median from a count of
        # each value (a fifth of np.median's time on a frame, the same value)
        response = cv2.filter2D(gray, cv2.CV_16S, kernel)[1:-1, 1:-1]
        counts = np.cumsum(np.bincount(np.abs(response).ravel()))
        n = int(counts[-1])
        ranks = np.array([(n - 1) // 2, n // 2]) + 1  # the middle one or two, counted from 1
        median = float(np.searchsorted(counts, ranks).mean())
    else:
        response = cv2.filter2D(gray.astype(np.float32), -1, kernel)[1:-1, 1:-1]
        median = float(np.median(np.abs(response)))
    return 1.4826 * median / 6.0  # (6: the kernel's norm)


def blank_mask(gray: np.ndarray, half: int, lag: int = BLANK_LAG_PX,
               min_correlation: float = BLANK_MIN_CORRELATION) -> np.ndarray:
    """Pixels whose window (of `half` around them) holds nothing but sensor noise: a grey-level
    spread within BLANK_NOISE_RATIO of the image's noise level (`sensor_noise`), and pixels
    that correlate with their neighbours `lag` px away (right and below) by less than
    `min_correlation`: texture at any contrast is smoother than noise, and a texture as fine as
    noise but stronger shows in the spread. Bool mask, the size of `gray`."""
    f = gray.astype(np.float32)
    k = (2 * half + 1, 2 * half + 1)
    h, w = f.shape
    mean = cv2.boxFilter(f, -1, k)
    spread2 = cv2.boxFilter(f * f, -1, k) - mean * mean
    # (a frame covered by a texture as fine as noise would give that texture's spread: no
    # camera's noise is larger than SENSOR_NOISE_MAX)
    limit = BLANK_NOISE_RATIO * min(max(sensor_noise(gray), 0.25), SENSOR_NOISE_MAX)
    weak = spread2 < np.float32(limit * limit)
    if not weak.any():
        return weak
    corr = np.zeros((h, w), np.float32)
    for a, b in ((f[:, :-lag], f[:, lag:]), (f[:-lag, :], f[lag:, :])):
        ma, mb = cv2.boxFilter(a, -1, k), cv2.boxFilter(b, -1, k)
        cov = cv2.boxFilter(a * b, -1, k) - ma * mb
        va = cv2.boxFilter(a * a, -1, k) - ma * ma
        vb = cv2.boxFilter(b * b, -1, k) - mb * mb
        r = cov / np.sqrt(np.maximum(va * vb, np.float32(1e-6)))
        corr[:r.shape[0], :r.shape[1]] += np.float32(0.5) * r
    return weak & (corr < np.float32(min_correlation))


NORMALIZED_SPREAD = 32.0  # grey levels one local standard deviation becomes
NORMALIZE_FLOOR = 16.0  # grey levels added to the local spread: a blank window stays flat


def local_contrast(gray: np.ndarray, window: int) -> np.ndarray:
    """A uint8 image's local contrast normalisation: 128 + NORMALIZED_SPREAD * (I - mean) /
    (spread + NORMALIZE_FLOOR), mean and spread over `window` x `window` (box filters),
    clipped to uint8. Gain, offset and any shading slower than the window leave it unchanged."""
    f = gray.astype(np.float32)
    k = (window, window)
    mean = cv2.boxFilter(f, -1, k)
    dev = cv2.subtract(f, mean)
    spread = cv2.sqrt(cv2.boxFilter(cv2.multiply(dev, dev), -1, k))
    out = cv2.divide(dev, cv2.add(spread, NORMALIZE_FLOOR), scale=NORMALIZED_SPREAD)
    return np.clip(out + np.float32(128.0), 0, 255).astype(np.uint8)


def agreement(d16: np.ndarray, d16_second: np.ndarray, min_disparity: int, agree_px: float,
              keep_px: tuple[float, float]) -> np.ndarray:
    """The final map of two windows' SGBM maps (x16 fixed point, same size, both searched from
    `min_disparity`): their mean in float px of those maps where both found a match, they agree
    within `agree_px` and the mean lies within `keep_px` = (smallest, largest) disparity kept;
    NaN elsewhere (a map's "no match" is NaN already, and the mean keeps it)."""
    a = fixed_to_px(d16, min_disparity)
    b = fixed_to_px(d16_second, min_disparity)
    out = cv2.addWeighted(a, 0.5, b, 0.5, 0.0)
    lo, hi = keep_px
    with np.errstate(invalid="ignore"):
        bad = (np.abs(a - b) > np.float32(agree_px)) | (out < np.float32(lo)) | \
            (out > np.float32(hi))
    blank(out, bad)
    return out


def occluded(disparity_px: np.ndarray, tolerance_px: float = 1.0, reach_px: int = 0
             ) -> np.ndarray:
    """Pixels of a left disparity map (px, NaN invalid) whose match in the right image is taken
    by a nearer surface: the right camera sees at column u = x - d only the nearest surface
    there, so a pixel is hidden from it when a pixel further right in the same row, more than
    `tolerance_px` nearer, matches at u or left of it (within half a pixel). SGBM's own
    left-right check compares only the winners of one cost volume, so a wrong far match just
    left of a surface can pass it. Bool mask.

    A surface is taken to go on under the `reach_px` pixels without a value left of it (the
    matching window's half and the edge margin leave them empty although they are the same
    surface), so that it hides what it would hide there.

    Pixels of one surface (disparities within the tolerance) cannot trigger this beyond the
    next `skip` - 1 columns (their matches move right with them), so the test looks at the
    columns from x + skip on: one running minimum of u from the right."""
    h, w = disparity_px.shape
    skip = int(math.floor(tolerance_px + 0.5)) + 1
    out = np.zeros((h, w), np.bool_)
    if w <= skip:
        return out
    cols = np.arange(w, dtype=np.float32)[None, :]
    d = disparity_px
    if reach_px > 0:
        # each empty pixel takes the disparity of the next valued pixel to its right, if that
        # lies within reach
        valued = ~np.isnan(d)
        nxt = _next_valued_column(valued)
        near = (~valued) & (nxt - np.arange(w)[None, :] <= reach_px) & (nxt < w)
        rows = np.nonzero(near)
        d = d.copy()
        d[rows] = disparity_px[rows[0], nxt[rows]]
    u = cols - d
    u[np.isnan(u)] = np.inf
    right_min = np.minimum.accumulate(u[:, ::-1], axis=1)[:, ::-1]
    out[:, :-skip] = u[:, :-skip] + np.float32(0.5) >= right_min[:, skip:]
    return out


def enlarge(disparity: np.ndarray, size: tuple[int, int], smooth_px: float) -> np.ndarray:
    """A float map (NaN invalid) enlarged to `size` (w, h) without inventing values: linear
    interpolation where the four source pixels around a target pixel are all valid and the
    interpolated value stays within `smooth_px` of the nearest one (one surface), the nearest
    source pixel elsewhere (edges keep their step; a hole stays a hole). Values unchanged
    (multiply by the scale for full-resolution disparities)."""
    valid = cv2.compare(disparity, disparity, cv2.CMP_EQ)  # 255 where not NaN
    nearest = cv2.resize(disparity, size, interpolation=cv2.INTER_NEAREST)
    filled = disparity.copy()
    cv2.copyTo(np.zeros_like(disparity), cv2.bitwise_not(valid), filled)  # NaN -> 0 to interpolate
    linear = cv2.resize(filled, size, interpolation=cv2.INTER_LINEAR)
    support = cv2.resize(cv2.divide(valid, 255, dtype=cv2.CV_32F), size,
                         interpolation=cv2.INTER_LINEAR)  # 1 where all four are valid
    # (OpenCV's element-wise operations, not numpy's: half the time on a frame; a comparison
    # with NaN is false in both)
    use = cv2.bitwise_and(
        cv2.compare(support, float(np.float32(0.999)), cv2.CMP_GT),
        cv2.compare(cv2.absdiff(linear, nearest), float(np.float32(smooth_px)), cv2.CMP_LE))
    cv2.copyTo(linear, use, nearest)
    return nearest


def compute_padded(matcher, reference: np.ndarray, other: np.ndarray, pad: int, side: str
                   ) -> np.ndarray:
    """`matcher.compute(reference, other)` with both images widened by `pad` black columns on
    `side` ("left" for a left matcher, "right" for a right matcher) and the result cropped back
    to the images' width (x16 fixed point, C-contiguous)."""
    if pad <= 0:
        return matcher.compute(reference, other)
    w = reference.shape[1]
    left, right = (pad, 0) if side == "left" else (0, pad)
    border = (0, 0, left, right, cv2.BORDER_CONSTANT)
    d = matcher.compute(cv2.copyMakeBorder(reference, *border, value=0),
                        cv2.copyMakeBorder(other, *border, value=0))
    return np.ascontiguousarray(d[:, left:left + w])


def _next_valued_column(valued: np.ndarray) -> np.ndarray:
    """Each pixel's column of the nearest valued pixel at or right of it in its row (the row's
    width where there is none)."""
    w = valued.shape[1]
    nxt = np.where(valued, np.arange(w, dtype=np.int32)[None, :], np.int32(w))
    return np.minimum.accumulate(nxt[:, ::-1], axis=1)[:, ::-1]


def _nearest_value_after(disparity_px: np.ndarray) -> np.ndarray:
    """Each pixel's nearest value at or right of it in its row (NaN where there is none)."""
    d = np.ascontiguousarray(disparity_px)
    h, w = d.shape
    nxt = _next_valued_column(~np.isnan(d))
    flat = np.minimum(nxt, w - 1) + (np.arange(h, dtype=np.int32) * w)[:, None]
    out = d.ravel()[flat.ravel()].reshape(h, w)
    out[nxt == w] = np.nan
    return out


def _nearest_source(size: int, source_size: int) -> np.ndarray:
    """For each of `size` pixels along an axis, the pixel of `source_size` that a nearest-
    neighbour resize (cv2.INTER_NEAREST) takes it from."""
    index = np.arange(source_size, dtype=np.float32)[None, :]
    return cv2.resize(index, (size, 1), interpolation=cv2.INTER_NEAREST)[0].astype(np.intp)


def _sunk(values: np.ndarray, disparity_px: np.ndarray, tolerance_px: float) -> np.ndarray:
    """Where `values` lie farther (smaller) by more than `tolerance_px` than the nearest values of
    the map `disparity_px` (NaN holes) on both sides: left and right in the row, or above and
    below in the column. Bool mask."""
    def along_rows(v: np.ndarray, m: np.ndarray) -> np.ndarray:
        out = np.zeros(v.shape, np.bool_)
        rows = np.flatnonzero((~np.isnan(v)).any(axis=1))  # (only the rows with a value to test)
        if len(rows):
            v, m = v[rows], m[rows]
            before = _nearest_value_after(m[:, ::-1])[:, ::-1]
            after = _nearest_value_after(m)
            out[rows] = (before - v > tolerance_px) & (after - v > tolerance_px)
        return out

    with np.errstate(invalid="ignore"):  # (NaN compares False: no value on a side)
        return along_rows(values, disparity_px) | along_rows(values.T, disparity_px.T).T


def unseen_columns(largest_disparity_px: float, margin_px: float, width: int) -> int:
    """How many columns from the left edge `unseen_mask` and `unseen_strip` can mark in a map
    whose disparities are at most `largest_disparity_px` (full-resolution px): a pixel the right
    camera cannot see has x < d + margin. (Two columns more than that, for rounding.)"""
    return int(min(width, max(0, math.floor(largest_disparity_px + margin_px) + 2)))


def unseen_strip(disparity_px: np.ndarray, margin_px: float = 0.0, cols: int | None = None
                 ) -> np.ndarray:
    """The strip at the left edge that the right camera cannot see, row by row: left of each
    row's first valid pixel, the columns x < d + margin with d that pixel's disparity (the
    surface there continues into the strip; nearer surfaces would only widen it).

    `cols` (`unseen_columns` of the map's largest disparity) limits the search to the columns
    where the strip can be; the mask returned is the same."""
    h, w = disparity_px.shape
    c = w if cols is None else max(0, min(w, cols))
    out = np.zeros((h, w), np.bool_)
    if c == 0:
        return out
    finite = np.isfinite(disparity_px[:, :c])
    first = np.argmax(finite, axis=1)  # 0 where a row has none in the band
    rows = np.arange(h)
    has = finite[rows, first]
    d = np.where(has, disparity_px[rows, first], 0.0)
    later = np.flatnonzero(~has) if c < w else ()
    if len(later):  # the row's first valid pixel lies right of the band: it sets the strip
        rest = np.isfinite(disparity_px[later, c:])
        at = np.argmax(rest, axis=1)
        found = rest[np.arange(len(later)), at]
        rows_f, at_f = later[found], at[found] + c
        first[rows_f], has[rows_f], d[rows_f] = at_f, True, disparity_px[rows_f, at_f]
    limit = np.minimum(first, np.ceil(d + margin_px - 0.5)).astype(np.int64)
    limit[~has] = 0
    out[:, :c] = np.arange(c)[None, :] < np.minimum(limit, c)[:, None]
    return out


def unseen_mask(disparity_px: np.ndarray, margin_px: float = 0.0, cols: int | None = None
                ) -> np.ndarray:
    """Pixels whose match x - d lies left of the right image (the right camera cannot see them),
    or within `margin_px` of its edge, where the matching block overlaps the padding and the
    image's border itself is what matches (full-resolution px). `cols`: as for `unseen_strip`
    (only those columns are computed; the rest cannot be set)."""
    h, w = disparity_px.shape
    if cols is not None and cols < w:
        out = np.zeros((h, w), np.bool_)
        out[:, :max(0, cols)] = unseen_mask(disparity_px[:, :max(0, cols)], margin_px)
        return out
    cols_x = np.arange(w, dtype=np.float32)[None, :]
    with np.errstate(invalid="ignore"):
        return (cols_x - disparity_px) < np.float32(margin_px - 0.5)
