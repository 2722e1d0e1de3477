"""The 95 % bound of a reading: its disparity's (from the alignment's standard error, or the
patch's spread unrefined, with what neither sees; see the guide, "How sure is a reading"), that
bound as millimetres of depth, and the calibration's own uncertainty added (core.uncertainty).
`core.measure` gives a reading these."""

from __future__ import annotations

import math

from stereo_gui.core.align import Refinement
from stereo_gui.core.click_images import STDERR_SCALE
from stereo_gui.core.click_map import EDGE_SPREAD_PX
from stereo_gui.core.stereo_calibration import StereoCalibration, triangulate
from stereo_gui.core.uncertainty import Z95, depth_sigma_mm

# the parts of a reading's disparity uncertainty (1 sigma, px) that its refinement's own standard
# error does not see, measured on the simulated rig on walls and chessboards the tests and the
# benchmark do not use: a floor (interpolation in rectification and resampling), a share
# of the refinement's own correction (the rest of SGBM's bias towards whole pixels), a share of
# the disagreement between the 13 and 9 px windows (sharp, repeating or sparse texture), and,
# unrefined, SGBM's bias towards whole pixels
REFINED_FLOOR_PX = 0.02
REFINEMENT_MOVE_SHARE = 0.1
WINDOWS_SHARE = 3.0
PIXEL_LOCKING_PX = 0.19
CORRELATED_STDERR_SCALE = STDERR_SCALE  # (see core.align.CORRELATION_LAG_PX)
# the scatter about its plane of a map that matched a wall right: on the simulated rig's walls,
# whose refined readings the +- covered at 99.5-100 % without counting any scatter, a click's
# patch scatters a median 0.03-0.09 px (walls at 0.5-3 m; the matcher's 1/16 px steps and its
# noise), which the alignment averages away (its weak walls and webcams' MJPG walls: 0.11-0.17 px);
# beyond this the scatter counts (`with_map_scatter`). Judged on `bench --clicks`, the +-
# covered the truth at 90.6 % of live's readings on the 13 public scenes without it and 91.9 %
# with it (quality 91.2 and 92.3 %), for a median +- of 2.10 % of the distance instead of 1.97 %;
# on the rig's walls (`bench --accuracy`, 10 seeds) every reading stays covered, the median +-
# 0.27 -> 0.29 % of the distance; on the rig's click scenes (10 seeds) the +- covers 98.7 % of
# live's readings (97.3 % without it; the webcams' walls 96.1 %, was 92.3 %). Without the floor:
# 92.1 % and 0.32 %
MAP_SCATTER_FLOOR_PX = 0.05


def disparity_bound_px(refinement: Refinement | None, spread_px: float) -> float:
    """The 95 % bound of a reading's disparity error, px (see the guide, "How sure is a
    reading"). Refined: the alignment's own standard error, a floor for what it cannot see
    (interpolation in rectification and resampling) and a share of its own correction (the part
    of SGBM's bias towards whole pixels it leaves). Unrefined: the patch spread, with a floor
    for that bias. A patch whose disparities spread more than EDGE_SPREAD_PX straddles a depth
    edge: its spread counts too."""
    if refinement is not None:
        se = (CORRELATED_STDERR_SCALE * refinement.stderr_correlated_px
              if math.isfinite(refinement.stderr_correlated_px)
              else STDERR_SCALE * refinement.stderr_px)
        sigma = math.hypot(se, REFINED_FLOOR_PX,
                           REFINEMENT_MOVE_SHARE * refinement.moved_px,
                           WINDOWS_SHARE * refinement.windows_px)
        if spread_px > EDGE_SPREAD_PX:
            # the patch holds more than one surface (a depth edge): the reading may be either
            sigma = math.hypot(sigma, spread_px)
    else:
        sigma = math.hypot(spread_px, PIXEL_LOCKING_PX)
    return Z95 * sigma


def with_map_scatter(bound_px: float, scatter_px: float) -> float:
    """A refined reading's 95 % disparity bound (`disparity_bound_px`) with the scatter of the
    map's patch about its plane (`click_map.plane_scatter_px`, 1 sigma) beyond
    MAP_SCATTER_FLOOR_PX added in quadrature. The alignment's standard error sees only how its
    own window fits; where the matcher's values around the click scatter about one surface (a
    rough or curved surface, texture the two cameras see differently, an MJPG wall's blobs) the
    alignment errs more than its fit says. Only the bound reported: the refusals judge the
    alignment's own (`core.measure`)."""
    excess = math.sqrt(max(0.0, scatter_px * scatter_px
                           - MAP_SCATTER_FLOOR_PX * MAP_SCATTER_FLOOR_PX))
    return math.hypot(bound_px, Z95 * excess)


def depth_bound_mm(calibration: StereoCalibration, x: float, y: float, d: float,
                   bound_px: float) -> float:
    """The larger change of Z, through the calibration's triangulation, of the disparity at
    (x, y) moved by +-bound (the far side is the larger; infinite where it passes infinity).
    Through Q, not f*B/d: a rig whose rectified principal points differ (Middlebury's doffs)
    reads Z = f*B/(d + doffs), whose change is (d + doffs)/d times smaller."""
    def z_at(disp: float) -> float:
        xyz = triangulate(calibration, x, y, disp)
        return float("inf") if xyz is None else xyz[2]

    z = z_at(d)
    if not (math.isfinite(z) and math.isfinite(bound_px)):
        return float("nan")
    return max(abs(z_at(d + s * bound_px) - z) for s in (-1.0, 1.0))


def with_calibration_uncertainty(bound_mm: float, calibration: StereoCalibration, x: float,
                                 y: float, d: float) -> float:
    """A reading's 95 % bound with the calibration's own uncertainty at that pixel and disparity
    added: bound + 1.96 sigma_calibration (core.uncertainty.depth_sigma_mm). A calibration
    without an uncertainty (older files, rectified:F,B) keeps the bound as it is.

    Added, not in quadrature: the calibration's error is the same for every reading made with
    it (systematic), so a bound that must hold for the calibration at hand cannot let the
    random matching part average it away: in quadrature the bound falls short for a calibration
    whose focal lengths came out a little high, added it holds, for a bound only slightly
    wider."""
    if calibration.uncertainty is None or not math.isfinite(bound_mm):
        return bound_mm
    sigma = depth_sigma_mm(calibration, x, y, d)
    return bound_mm + Z95 * sigma if math.isfinite(sigma) else bound_mm
