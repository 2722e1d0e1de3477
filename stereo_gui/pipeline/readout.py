"""What the Live tab says about a pixel, without Qt: the readout line for the pointer over a
view, and distances formatted for labels."""

from __future__ import annotations

import math

import numpy as np

from stereo_gui.core.matching import PipelineResult


def format_distance(mm: float) -> str:
    """A distance for a label: metres with mm resolution from 1 m on, else millimetres."""
    if not math.isfinite(mm):
        return "–"
    return f"{mm / 1000:.3f} m" if abs(mm) >= 1000 else f"{mm:.1f} mm"


def disparity_of_view(result: PipelineResult | None, key: str) -> np.ndarray | None:
    """The disparity (px, NaN invalid) view `key` shows: raw, closed, or the final one."""
    if result is None:
        return None
    r = result
    return {"raw": r.disparity_px, "closed": r.closed_px}.get(key, r.final_px)


def pointer_readout(result: PipelineResult | None, key: str, x: float, y: float, fit=None) -> str:
    """What the readout line says for the pointer at (x, y) px of view `key` of `result` (None:
    no frame yet); `fit` is the active FitResult, which live readings use instead of
    triangulation."""
    disp = disparity_of_view(result, key)
    if disp is None:
        return "no frame yet"
    h, w = disp.shape[:2]
    xi, yi = int(round(x)), int(round(y))
    if not (0 <= xi < w and 0 <= yi < h):
        return f"x {xi}  y {yi}: outside the image"
    if key == "right":
        return f"x {xi}  y {yi} (right image: measure on the left or a disparity view)"
    d = float(disp[yi, xi])
    where = f"x {xi:4d}  y {yi:4d}   "
    if not math.isfinite(d):
        return where + "invalid: no match here (occluded, textureless or filtered out)"
    from stereo_gui.core.measure import triangulate

    lo, hi = result.disparity_range_px
    txt = where + f"disparity {d:7.2f} px   "
    if d >= hi - 1.0:
        return txt + "invalid: too near for the disparity range"
    xyz = triangulate(result.calibration, x, y, d)
    if xyz is None:
        return txt + "invalid: too far"
    z, how = xyz[2], ""
    if fit is not None:
        lo_s, hi_s = fit.disparity_span
        if not lo_s <= d <= hi_s:
            return txt + f"invalid: outside the {fit.model} fit's disparity range"
        z, how = float(fit.predict(d)), f" ({fit.model} fit)"
    return txt + f"distance (Z) {format_distance(z)}{how}   valid"
