"""Distance-from-disparity regressions: the reference program's cubic, done properly, and the
physical model.

Samples are (disparity px, true distance mm). Two models:
- "cubic": Z = a3 x^3 + a2 x^2 + a1 x + a0 with x the disparity normalised as the reference loop
  (core.reference_loop) does its disparity map: x = (d - min_disp) / num_disp, min_disp = 2 and
  num_disp = 128 (its Code 7, `((disp/16) - min_disp) / num_disp`). The reference program's own
  coefficients gave centimetres; ours give millimetres (`reference_cubic()` converts its formula
  for comparison).
- "inverse": Z = a / (d - d0), the triangulation law Z = f*B / d with a disparity offset d0 that
  absorbs a principal-point or rectification offset; a is f*B in px*mm.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np

from stereo_gui.core.errors import InputError

FORMAT_VERSION = 1
REFERENCE_MIN_DISP = 2.0
REFERENCE_NUM_DISP = 128.0
MODELS = ("cubic", "inverse")


# (disparity px, true distance mm) pairs, as numbers or what float() takes
Samples = Iterable[tuple[float, float]]

@dataclass(frozen=True)
class FitResult:
    """A fitted model. Distances in mm, disparities in px of the full-resolution rectified image."""

    model: str  # "cubic" | "inverse"
    coefficients: tuple[float, ...]  # cubic: (a3, a2, a1, a0); inverse: (a, d0)
    r2: float
    residuals_mm: tuple[float, ...]  # true - predicted, per sample, in sample order
    samples: tuple[tuple[float, float], ...]  # (disparity_px, true_mm)
    # cubic only: x = (d - norm_offset_px) / norm_span_px
    norm_offset_px: float = REFERENCE_MIN_DISP
    norm_span_px: float = REFERENCE_NUM_DISP
    note: str = field(default="", compare=False)

    @overload
    def predict(self, disparity_px: float) -> float: ...

    @overload
    def predict(self, disparity_px: np.ndarray) -> np.ndarray: ...

    def predict(self, disparity_px: float | np.ndarray) -> float | np.ndarray:
        """Distance in mm for a disparity in px (float or ndarray); NaN where the model has none."""
        d = np.asarray(disparity_px, np.float64)
        if self.model == "cubic":
            x = (d - self.norm_offset_px) / self.norm_span_px
            z = np.polyval(np.asarray(self.coefficients, np.float64), x)
        else:
            a, d0 = self.coefficients
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(d > d0, a / (d - d0), np.nan)
        return float(z) if np.ndim(z) == 0 else z

    def formula(self) -> str:
        c = self.coefficients
        if self.model == "cubic":
            return (f"Z = {c[0]:.6g} x^3 + {c[1]:+.6g} x^2 + {c[2]:+.6g} x + {c[3]:+.6g} mm, "
                    f"x = (d - {self.norm_offset_px:g}) / {self.norm_span_px:g}").replace("+ -", "- ").replace("+ +", "+ ")
        d0 = float(c[1])
        # "d - -0.2254" reads badly: a negative offset is written as an addition
        sign = "+" if d0 < 0 else "-"
        return f"Z = {c[0]:.6g} / (d {sign} {abs(d0):.4g}) mm"

    @property
    def disparity_span(self) -> tuple[float, float]:
        """(smallest, largest) sample disparity, px: the range where the fit is supported."""
        if not self.samples:
            return (-math.inf, math.inf)
        ds = [s[0] for s in self.samples]
        return (min(ds), max(ds))

    @property
    def exactly_determined(self) -> bool:
        """True when there are no more samples than parameters: the curve passes through every
        sample, so R^2 and the residuals say nothing about the model yet."""
        return len(self.samples) <= len(self.coefficients)

    @property
    def rms_mm(self) -> float:
        r = np.asarray(self.residuals_mm, np.float64)
        return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")


def _samples(samples: Samples, need: int, model: str
             ) -> tuple[np.ndarray, np.ndarray, tuple[tuple[float, float], ...]]:
    try:
        arr = np.asarray([(float(d), float(z)) for d, z in samples], np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"samples must be (disparity px, distance mm) pairs: {exc}") from exc
    if arr.ndim != 2 or len(arr) < need:
        raise InputError(f"the {model} fit needs at least {need} samples, got {len(arr)}")
    if not np.all(np.isfinite(arr)):
        raise InputError("samples must be finite numbers")
    if np.any(arr[:, 1] <= 0):
        raise InputError("true distances must be positive (mm)")
    if len(np.unique(arr[:, 0])) < need:
        raise InputError(f"the {model} fit needs at least {need} different disparities")
    # readings at fewer true distances than parameters fit exactly whatever the model: R^2 1
    # and RMS 0 would say nothing about it
    distinct = len(np.unique(arr[:, 1]))
    if distinct < need:
        raise InputError(f"the {model} fit needs true distances at {need} or more different "
                         f"distances, got {distinct}")
    return arr[:, 0], arr[:, 1], tuple((float(d), float(z)) for d, z in arr)


def _r2(z: np.ndarray, pred: np.ndarray) -> tuple[float, tuple[float, ...]]:
    res = z - pred
    ss_tot = float(np.sum((z - z.mean()) ** 2))
    r2 = 1.0 - float(np.sum(res**2)) / ss_tot if ss_tot > 0 else float("nan")
    return r2, tuple(float(r) for r in res)


def fit_cubic(samples: Samples, norm_offset_px: float = REFERENCE_MIN_DISP,
              norm_span_px: float = REFERENCE_NUM_DISP) -> FitResult:
    """Least-squares cubic in the normalised disparity (as the reference program's, fitted in
    Excel)."""
    d, z, s = _samples(samples, 4, "cubic")
    x = (d - norm_offset_px) / norm_span_px
    coef = np.polyfit(x, z, 3)
    r2, res = _r2(z, np.polyval(coef, x))
    return _plausible(FitResult("cubic", tuple(float(c) for c in coef), r2, res, s,
                                float(norm_offset_px), float(norm_span_px)))


def fit_inverse(samples: Samples, iterations: int = 50) -> FitResult:
    """Z = a / (d - d0) minimising the distance residuals (mm).

    Start: 1/Z is linear in d (1/Z = d/a - d0/a); then Gauss-Newton on the mm residuals, because
    the linearised fit over-weights far samples.
    """
    d, z, s = _samples(samples, 2, "inverse")
    slope, icpt = np.polyfit(d, 1.0 / z, 1)
    if slope <= 0:
        raise InputError("the inverse fit needs distances that shrink as disparity grows")
    a, d0 = 1.0 / slope, -icpt / slope
    for _ in range(iterations):
        den = d - d0
        if np.any(den <= 0):
            break
        pred = a / den
        J = np.column_stack([1.0 / den, a / den**2])
        step, *_ = np.linalg.lstsq(J, z - pred, rcond=None)
        if not np.all(np.isfinite(step)):
            break
        a, d0 = a + step[0], d0 + step[1]
        if abs(step[0]) <= 1e-12 * abs(a) and abs(step[1]) <= 1e-12:
            break
    pred = np.where(d > d0, a / (d - d0), np.nan)
    if not np.all(np.isfinite(pred)):
        raise InputError("the inverse fit failed: a sample lies at or below the fitted offset d0")
    r2, res = _r2(z, pred)
    return _plausible(FitResult("inverse", (float(a), float(d0)), r2, res, s))


def _plausible(f: FitResult) -> FitResult:
    """`f`, or InputError when it is no usable distance model (see `implausibility`): a fit
    that could not be saved and loaded again is not offered either."""
    why = implausibility(f)
    if why:
        raise InputError(f"the {f.model} fit is not usable: {why}")
    return f


def fit(model: str, samples: Samples) -> FitResult:
    if model == "cubic":
        return fit_cubic(samples)
    if model == "inverse":
        return fit_inverse(samples)
    raise InputError(f"unknown model {model!r}; use cubic or inverse")


def reference_cubic() -> FitResult:
    """The reference program's hand-fitted cubic (-593.97 x^3 + 1506.8 x^2 - 1373.1 x + 522.06
    cm), in mm."""
    coef = tuple(10.0 * c for c in (-593.97, 1506.8, -1373.1, 522.06))
    return FitResult("cubic", coef, float("nan"), (), (), note="the reference program's formula")


# a fit's distance at one of its own samples may differ from the sample by this share of it at
# most: a fit that misses its samples by more does not describe them (a damaged file)
SAMPLE_MISS_SHARE = 0.5


def implausibility(f: FitResult) -> str | None:
    """Why `f` cannot turn disparities into distances over the disparities it is used at (those
    of its samples: see `disparity_span`), or None when it can: its distance must be positive
    there and fall as the disparity grows (two disparities with one distance would make a
    reading ambiguous); a cubic without samples has no such range. Its residuals, when given,
    must be what it predicts at its samples."""
    if f.model == "inverse":
        a, d0 = f.coefficients
        if not a > 0:
            return f"coefficient a (f*B) is {a:g}; it must be positive"
        lo = f.disparity_span[0]
        if f.samples and not d0 < lo:
            return (f"its offset d0 = {d0:g} px is not below its smallest sample disparity "
                    f"{lo:g} px: it gives no distance there")
    elif not f.samples:
        return "a cubic fit without samples has no range of disparities where it holds"
    else:
        lo, hi = f.disparity_span
        coef = np.asarray(f.coefficients, np.float64)
        x_lo, x_hi = ((v - f.norm_offset_px) / f.norm_span_px for v in (lo, hi))
        slope = np.polyder(coef)
        turns = [float(r.real) for r in np.roots(slope)
                 if abs(r.imag) < 1e-12 and x_lo < r.real < x_hi]
        if turns or (hi > lo and not np.polyval(slope, 0.5 * (x_lo + x_hi)) < 0):
            at = f" (it turns at {turns[0] * f.norm_span_px + f.norm_offset_px:.4g} px)" \
                if turns else ""
            return (f"its distance does not fall steadily as the disparity grows from {lo:g} to "
                    f"{hi:g} px{at}")
        z_far = float(np.polyval(coef, x_hi))
        if not z_far > 0:
            return f"its distance at {hi:g} px is {z_far:g} mm; distances must be positive"
    if f.samples:
        d = np.array([s[0] for s in f.samples], np.float64)
        z = np.array([s[1] for s in f.samples], np.float64)
        with np.errstate(all="ignore"):
            pred = np.asarray(f.predict(d), np.float64)
        miss = np.abs(z - pred)
        if not np.all(np.isfinite(pred)) or np.any(miss > SAMPLE_MISS_SHARE * z):
            i = int(np.argmax(np.where(np.isfinite(miss), miss / z, np.inf)))
            return (f"it gives {pred[i]:.6g} mm at sample {i + 1} ({d[i]:g} px), which is "
                    f"{z[i]:g} mm: it does not describe its samples")
        if f.residuals_mm:
            r = np.asarray(f.residuals_mm, np.float64)
            off = np.abs(z - pred - r)
            if np.any(off > 1e-3 + 1e-6 * np.abs(z)):
                i = int(np.argmax(off))
                return (f"residual {i + 1} is {r[i]:g} mm but the fit misses sample {i + 1} by "
                        f"{z[i] - pred[i]:g} mm: its coefficients or samples were changed")
    return None


# ---- to and from JSON documents (files.fit_file reads and writes the files) ----------------------
def fit_to_dict(f: FitResult) -> dict[str, object]:
    doc: dict[str, object] = {"format_version": FORMAT_VERSION, "model": f.model,
           "coefficients": list(f.coefficients), "r2": f.r2 if math.isfinite(f.r2) else None,
           "residuals_mm": list(f.residuals_mm), "samples": [list(s) for s in f.samples],
           "formula": f.formula()}
    if f.model == "cubic":
        doc["normalisation"] = {"offset_px": f.norm_offset_px, "span_px": f.norm_span_px}
    return doc


MAX_COEFFICIENT = 1e12  # larger coefficients turn every reading into overflow: a damaged file
MAX_DISPARITY_PX = 1e5
MAX_SAMPLES = 100_000


def _finite(value: object, name: str, limit: float = MAX_COEFFICIENT) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} should be a number, not {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:  # an integer literal such as 10**400 has no float
        raise ValueError(f"{name} is an integer beyond 1e308, not a finite number up to "
                         f"{limit:g}") from None
    if not (math.isfinite(v) and abs(v) <= limit):
        raise ValueError(f"{name} is {v:g}, not a finite number up to {limit:g}")
    return v


def _list(value: object, name: str) -> list[Any]:
    if not isinstance(value, list):
        raise ValueError(f"{name} should be a list, not {type(value).__name__}")
    if len(value) > MAX_SAMPLES:
        raise ValueError(f"{name} has {len(value)} entries (at most {MAX_SAMPLES})")
    return value


def fit_from_dict(doc: object, where: str) -> FitResult:
    """The fit `doc` describes (as made by fit_to_dict); InputError naming `where` and the field
    if unusable (wrong types, values that are not finite or absurd, inconsistent lengths)."""
    try:
        if not isinstance(doc, dict):
            raise ValueError("not a JSON object")
        version = doc.get("format_version", FORMAT_VERSION)
        if isinstance(version, bool) or not isinstance(version, int) or version > FORMAT_VERSION:
            raise ValueError(f"format version {version!r} is newer than this program reads")
        model = doc["model"]
        if not isinstance(model, str) or model not in MODELS:
            raise ValueError(f"unknown model {model!r}")
        raw = _list(doc["coefficients"], "coefficients")
        if len(raw) != (4 if model == "cubic" else 2):
            raise ValueError("wrong number of coefficients or values that are not finite")
        coef = tuple(_finite(c, f"coefficient {i + 1}") for i, c in enumerate(raw))
        if model == "inverse":
            if not coef[0] > 0:
                raise ValueError(f"coefficient a (f*B) is {coef[0]:g}; it must be positive")
            _finite(coef[1], "d0", MAX_DISPARITY_PX)
        r2 = doc.get("r2")
        r2 = float("nan") if r2 is None else _finite(r2, "r2")
        if r2 > 1.0 + 1e-9:
            raise ValueError(f"r2 is {r2:g}; it cannot exceed 1")
        samples = []
        for i, s in enumerate(_list(doc.get("samples", []), "samples"), start=1):
            if not isinstance(s, list) or len(s) != 2:
                raise ValueError(f"sample {i} should be [disparity px, distance mm]")
            d = _finite(s[0], f"sample {i} disparity", MAX_DISPARITY_PX)
            z = _finite(s[1], f"sample {i} distance")
            if not z > 0:
                raise ValueError(f"sample {i} distance is {z:g}; it must be positive")
            samples.append((d, z))
        residuals = tuple(_finite(r, f"residual {i}") for i, r in
                          enumerate(_list(doc.get("residuals_mm", []), "residuals_mm"), start=1))
        if residuals and len(residuals) != len(samples):
            raise ValueError(f"{len(residuals)} residuals for {len(samples)} samples")
        norm = doc.get("normalisation") or {}
        if not isinstance(norm, dict):
            raise ValueError("normalisation should be an object")
        offset = _finite(norm.get("offset_px", REFERENCE_MIN_DISP), "normalisation offset_px",
                         MAX_DISPARITY_PX)
        span = _finite(norm.get("span_px", REFERENCE_NUM_DISP), "normalisation span_px",
                       MAX_DISPARITY_PX)
        if not span > 0:
            raise ValueError(f"normalisation span_px is {span:g}; it must be positive")
        result = FitResult(model, coef, r2, residuals, tuple(samples), offset, span)
        why = implausibility(result)
        if why:
            raise ValueError(why)
        return result
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{where} is not usable: {exc}") from exc
