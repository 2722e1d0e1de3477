"""A preset and its declarations: the matcher's (`MatcherParams`), the colouring's
(`DisplayParams`) and the threads' (`ThreadParams`) parameters, each field declared once with its
range, unit and meaning (`core.params.param`), and the tables of OpenCV's choices they name
(SGBM modes, colour maps, remap interpolations).

Sizes and disparities are px; `MatcherParams.disparity_limits` and `matcher_range` turn working
distances into the range a matcher searches for a calibration.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import cv2

from stereo_gui.core.errors import InputError
from stereo_gui.core.params import Param, check_all, from_json, param, params_of
from stereo_gui.core.stereo_calibration import StereoCalibration

log = logging.getLogger(__name__)

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

INTERPOLATIONS: dict[str, int] = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC,
                                  "lanczos4": cv2.INTER_LANCZOS4}

# the reference loop's / OpenCV's names for some parameters, accepted when reading presets
ALIASES = {"window_size": "block_size", "minDisparity": "min_disparity",
           "numDisparities": "num_disparities", "uniquenessRatio": "uniqueness_ratio",
           "speckleWindowSize": "speckle_window_size", "speckleRange": "speckle_range",
           "disp12MaxDiff": "disp12_max_diff", "P1": "p1", "P2": "p2", "lmbda": "wls_lambda"}


def _multiple_of_16(v: int) -> bool:
    return v % 16 == 0


def _fill_scale(v: float) -> bool:
    return v == 0 or 0.25 <= v <= 0.5


def fill_mode_names(fill_modes: str) -> list[str]:
    """The SGBM modes of a `fill_modes` text, one per size the fill tries ("3way,hh")."""
    return [m.strip() for m in fill_modes.split(",")]


def _fill_modes(v: str) -> bool:
    modes = fill_mode_names(v)
    return 1 <= len(modes) <= 3 and all(m in MODES for m in modes)


def _normalize_window(v: int) -> bool:
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
    # so that a full-resolution preset keeps a few frames a second at 1280x720: a frame's work
    # grows with its pixels times its disparity range, which grows with its width
    max_match_pixels: int | None = param(
        None, lo=10_000, hi=100_000_000, unit="px",
        help="match on images of at most this many pixels: a larger camera frame is matched at "
             "half the scale (a quarter, ... until it fits; None: no limit)")

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

    def effective_scale(self, width_px: int, height_px: int = 0) -> float:
        """The scale frames `width_px` x `height_px` are matched at: `scale`, lowered to keep the
        matched image at most `max_match_width` px wide, then halved while it holds more than
        `max_match_pixels` pixels (a height of 0: the width alone decides)."""
        s = self.scale
        if self.max_match_width is not None and width_px > 0:
            s = min(s, max(0.1, self.max_match_width / float(width_px)))
        if self.max_match_pixels is not None and width_px > 0 and height_px > 0:
            while width_px * height_px * s * s > self.max_match_pixels and s > 1.0 / 64:
                s *= 0.5
        return s

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

    def replace(self, **changes: Any) -> MatcherParams:
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


# what a preset's parameter holds: a number, a word, a switch, or None for "not set"
ParamValue = bool | int | float | str | None

_PARTS: dict[str, type[MatcherParams] | type[DisplayParams] | type[ThreadParams]] = {"matcher": MatcherParams, "display": DisplayParams, "threads": ThreadParams}
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

    def replace(self, **changes: Any) -> Preset:
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

    def get(self, key: str) -> ParamValue:
        """The value of a part's field by its flat name (a key of PRESET_PARAMS)."""
        value: ParamValue = getattr(getattr(self, _PART_OF[key]), key)
        return value

    @classmethod
    def of(cls, params: Preset | MatcherParams | None) -> Preset:
        """`params` as a preset (bare matcher parameters: with the default display and threads)."""
        if params is None:
            return cls()
        return params if isinstance(params, Preset) else cls(matcher=params)

    # ---- persistence ---------------------------------------------------------------------
    def to_dict(self) -> dict[str, object]:
        """The flat object files hold: name, description, then the matcher's, display's and
        threads' fields."""
        out: dict[str, object] = {"name": self.name, "description": self.description}
        for part in _PARTS:
            out.update(dataclasses.asdict(getattr(self, part)))
        return out

    @classmethod
    def from_dict(cls, data: dict[str, object], where: str = "preset") -> Preset:
        """Build from a flat object (the reference loop's / OpenCV's names understood); unknown
        keys are logged and skipped, bad values raise InputError naming `where`."""
        if not isinstance(data, dict):
            raise InputError(f"{where}: expected a JSON object of matcher parameters")
        flat: dict[str, object] = {}
        for key, value in data.items():
            key = ALIASES.get(key, key)
            if key not in _PART_OF and key not in ("name", "description"):
                log.warning("%s: unknown matcher parameter %r ignored", where, key)
                continue
            flat[key] = value
        top: dict[str, Any] = {}  # (the parts and words from JSON, checked by the classes)
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
