"""How well a calibration is determined, what that means for a reading, and what to warn about.

All uncertainties here are 1 sigma (one standard deviation) and say so wherever they are shown.

- `CalibrationUncertainty`: the covariance of the camera parameters from the joint refinement
  (core.bundle), with the standard deviation of every intrinsic and distortion parameter, of the
  baseline and of the relative rotation. The Jacobian's covariance is used rather than a
  bootstrap over the pairs: on the simulated rig both give the same sigmas, which hold the truth
  within 3 sigma, and the bootstrap costs about 20 times more (scripts/bench_uncertainty.py;
  figures in docs/guide.md). They are the joint solve's, not calibrateCameraExtended's
  per-camera ones, which describe each camera calibrated alone and come out larger
  (tests/core/test_uncertainty.py compares them).
- `depth_sigma_mm`: the calibration's part of a reading's error. The parameter covariance is
  propagated, linearised by central differences one parameter at a time, through rectification
  and triangulation: the raw pixels where the two cameras saw the point stay fixed, each
  perturbed calibration rectifies and triangulates them again, and the depth error is measured
  in that calibration's own rectified frame, against the point the nominal calibration read.
  A reading near a corner the board never covered inherits the large uncertainty of the
  extrapolated lens model there.
- `calibration_warnings`: swapped cameras, poorly determined parameters (with what to do: fix k3,
  or capture the named regions), image regions the board never reached.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NotRequired, Protocol, TypedDict, overload

import cv2
import numpy as np

from stereo_gui.core.bundle import BundleResult
from stereo_gui.core.coverage import CORNERS, FAR_SIDE, regions_in_words
from stereo_gui.core.errors import CalibrationValueError
from stereo_gui.core.lens import (
    HIGHER_TERMS,
    LENS_MODELS,
    LensModel,
    check_model,
    distortion_names,
    project_points,
    stereo_rectify,
    undistort_points,
)

SIDES = ("left", "right")
Z95 = 1.959964  # two-sided 95 % quantile of the normal distribution
MAX_DIST_COUNT = 14  # the most distortion coefficients a camera of OpenCV has
INTRINSICS = ("fx", "fy", "cx", "cy")
# a parameter is poorly determined when its 1-sigma uncertainty exceeds these
FOCAL_SHARE = 0.01  # of the focal length
CENTRE_SHARE = 0.01  # of the image width / height
CORNER_SIGMA_PX = 0.5  # the lens model's 1-sigma uncertainty at the image corners
BASELINE_SHARE = 0.01
ROTATION_DEG = 0.1


class CameraSigmas(TypedDict):
    """1 sigma of one camera's intrinsics (px), of each distortion coefficient (None where not
    identifiable) and, in `calibrate --json`, of where a ray lands at the image corners (px)."""

    fx: float
    fy: float
    cx: float
    cy: float
    dist: list[float | None]
    corner_px: NotRequired[float]


class Lenses(Protocol):
    """A rectified pair's matrices: a calibration's, or those of one perturbed."""

    @property
    def M1(self) -> np.ndarray: ...
    @property
    def D1(self) -> np.ndarray: ...
    @property
    def M2(self) -> np.ndarray: ...
    @property
    def D2(self) -> np.ndarray: ...
    @property
    def R1(self) -> np.ndarray: ...
    @property
    def R2(self) -> np.ndarray: ...
    @property
    def P1(self) -> np.ndarray: ...
    @property
    def P2(self) -> np.ndarray: ...
    @property
    def Q(self) -> np.ndarray: ...


class Rig(Lenses, Protocol):
    """What this module reads of a calibration (core.stereo_calibration.StereoCalibration, which
    carries a CalibrationUncertainty and so imports this module)."""

    @property
    def R(self) -> np.ndarray: ...
    @property
    def T(self) -> np.ndarray: ...
    @property
    def model(self) -> str: ...
    @property
    def method(self) -> str: ...
    @property
    def image_size(self) -> tuple[int, int]: ...
    @property
    def alpha(self) -> float: ...
    @property
    def uncertainty(self) -> CalibrationUncertainty | None: ...
    @property
    def metric(self) -> bool: ...
    @property
    def baseline_mm(self) -> float: ...
    @property
    def relative_rotation_deg(self) -> float: ...


@dataclass(frozen=True)
class CalibrationWarning:
    """Something about a calibration a person should know: `code` is stable for scripts
    ("swapped", "poorly_determined", "uncovered"), `message` says it in words, `proposal` names
    the remedy the window offers ("swap", "fix_k3", "capture" or "")."""

    code: str
    message: str
    proposal: str = ""

    def to_json(self) -> dict[str, str]:
        out = {"code": self.code, "message": self.message}
        if self.proposal:
            out["proposal"] = self.proposal
        return out


@dataclass(frozen=True, eq=False)
class CalibrationUncertainty:
    """The 1-sigma covariance of a calibration's camera parameters.

    `names` label the rows: "left.fx" ... "left.k1" ..., "right...", "rvec.x/y/z" (R_right_left
    as a Rodrigues vector, rad), "T.x/y/z" (T_right_left, mm); a parameter held fixed is absent
    (its sigma is 0). `sigma_px` is the corner error (px, per coordinate) the covariance is
    scaled to; `method` says how it was found.
    """

    names: tuple[str, ...]
    covariance: np.ndarray
    sigma_px: float
    method: str = "jacobian"
    model: LensModel = "pinhole"

    def __post_init__(self) -> None:
        names = tuple(self.names)
        n = len(names)
        c = np.array(self.covariance, np.float64)
        if c.shape != (n, n) or not np.all(np.isfinite(c)):
            got = "x".join(map(str, c.shape)) or "a scalar"
            raise CalibrationValueError(f"the uncertainty's covariance should be a finite {n}x{n} "
                                        f"matrix (one row and column per name), found {got}")
        if self.model not in LENS_MODELS:
            raise CalibrationValueError(f"the uncertainty is of an unknown lens model "
                                        f"{self.model!r}")
        c.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "covariance", c)
        self.check_parameters(None)

    def check_parameters(self, n_dist: int | None) -> None:
        """Raise CalibrationValueError unless every name is a parameter, once, of a calibration
        of this lens model with `n_dist` distortion coefficients per camera (None: as many as
        the model has); a distance's uncertainty is computed by moving each."""
        known = parameter_names(self.model, n_dist if n_dist is not None
                                else len(distortion_names(self.model, MAX_DIST_COUNT)))
        for name in self.names:
            if name not in known:
                whose = (f"a calibration with {self.model} lenses" if n_dist is None else
                         f"this calibration ({self.model} lenses, {n_dist} distortion "
                         f"coefficients: {', '.join(known[:2])}, ..., {known[-1]})")
                raise CalibrationValueError(f"the uncertainty holds {name!r}, which is not a "
                                            f"parameter of {whose}")
        if len(set(self.names)) != len(self.names):
            twice = sorted({n for n in self.names if self.names.count(n) > 1})
            raise CalibrationValueError(f"the uncertainty holds {', '.join(twice)} twice")

    def index(self, name: str) -> int | None:
        try:
            return self.names.index(name)
        except ValueError:
            return None

    def sigma(self, name: str) -> float:
        """1 sigma of one parameter (0 for a fixed one)."""
        i = self.index(name)
        return 0.0 if i is None else float(math.sqrt(max(self.covariance[i, i], 0.0)))

    @property
    def distortion_identifiable(self) -> bool:
        """False for the rational model: its numerator and denominator coefficients trade off
        against each other (k1 with k4, ...), so that very different coefficients describe the
        same lens, and a sigma per coefficient would mean nothing (on the simulated rig the
        estimates lie tens of stated sigmas from the truth while the lens they describe is
        right). Its uncertainty is stated where it means something: at the image corners."""
        return self.model != "rational"

    def distortion_sigma(self, side: str, name: str) -> float | None:
        """1 sigma of a distortion coefficient, or None where it is not identifiable."""
        return self.sigma(f"{side}.{name}") if self.distortion_identifiable else None

    def camera(self, side: str, n_dist: int) -> CameraSigmas:
        """{fx, fy, cx, cy: sigma px, dist: [sigma of each coefficient, None where not
        identifiable]} of one camera."""
        return CameraSigmas(
            fx=self.sigma(f"{side}.fx"), fy=self.sigma(f"{side}.fy"),
            cx=self.sigma(f"{side}.cx"), cy=self.sigma(f"{side}.cy"),
            dist=[self.distortion_sigma(side, k) for k in distortion_names(self.model, n_dist)])

    def _sub(self, names: Sequence[str]) -> tuple[np.ndarray, list[int]]:
        idx = [self.index(n) for n in names]
        keep = [k for k, i in enumerate(idx) if i is not None]
        ii = [i for i in idx if i is not None]
        return self.covariance[np.ix_(ii, ii)], keep

    def baseline_sigma_mm(self, T: np.ndarray) -> float:
        """1 sigma of |T|, mm."""
        t = np.asarray(T, np.float64).reshape(3)
        C, keep = self._sub(("T.x", "T.y", "T.z"))
        g = (t / max(float(np.linalg.norm(t)), 1e-12))[keep]
        return float(math.sqrt(max(g @ C @ g, 0.0)))

    def rotation_sigma_deg(self, R: np.ndarray) -> float:
        """1 sigma of the angle of R_right_left, degrees."""
        rv = cv2.Rodrigues(np.asarray(R, np.float64))[0].reshape(3)
        C, keep = self._sub(("rvec.x", "rvec.y", "rvec.z"))
        n = np.linalg.norm(rv)
        if n < 1e-9:  # no rotation: the angle's spread is that of the vector's length
            return float(math.degrees(math.sqrt(max(np.trace(C) / 3.0, 0.0))))
        g = (rv / n)[keep]
        return float(math.degrees(math.sqrt(max(g @ C @ g, 0.0))))

    def rotation_axes_sigma_deg(self) -> list[float]:
        """1 sigma of each component of R_right_left's rotation vector, degrees."""
        return [math.degrees(self.sigma(f"rvec.{a}")) for a in "xyz"]

    def scaled(self, s: float) -> CalibrationUncertainty:
        """For images resized by `s` (StereoCalibration.scaled_to): pixel parameters scale."""
        k = np.array([s if n.split(".")[-1] in INTRINSICS else 1.0 for n in self.names])
        return CalibrationUncertainty(self.names, self.covariance * np.outer(k, k),
                                      self.sigma_px * s, self.method, self.model)

    def to_json(self, calib: Rig) -> dict[str, object]:
        """The `uncertainty` object of `calibrate --json` (all 1 sigma)."""
        nd = np.asarray(calib.D1).size
        left, right = self.camera("left", nd), self.camera("right", nd)
        left["corner_px"] = corner_sigma_px(calib, "left")
        right["corner_px"] = corner_sigma_px(calib, "right")
        return {"level": "1 sigma", "method": self.method, "left": left, "right": right,
                "baseline_mm": self.baseline_sigma_mm(calib.T),
                "rotation_deg": self.rotation_sigma_deg(calib.R),
                "rotation_axes_deg": self.rotation_axes_sigma_deg(),
                "corner_error_px": self.sigma_px}


def uncertainty_from_bundle(bundle: BundleResult, model: str, fix_k3: bool = False,
                            mono: tuple[np.ndarray | None, np.ndarray | None] | None = None
                            ) -> CalibrationUncertainty:
    """The CalibrationUncertainty of a core.bundle.BundleResult."""
    return CalibrationUncertainty(tuple(bundle.names), np.asarray(bundle.covariance),
                                  float(bundle.sigma_px), "jacobian", check_model(model))


# ---- warnings -------------------------------------------------------------------------------
def swapped(calib: Rig) -> bool:
    """True when the 'right' camera sits to the left of the 'left' one (its centre, -R^T T, has
    a negative x in the left camera's frame): the cameras are exchanged."""
    C = -np.asarray(calib.R, np.float64).T @ np.asarray(calib.T, np.float64).reshape(3)
    return bool(C[0] < 0)


def corner_sigma_px(calib: Rig, side: str) -> float:
    """How uncertain the lens model of one camera is at the image corners: 1 sigma (px) of where
    the ray through a corner lands, from the covariance of all its distortion coefficients
    together (they are strongly correlated; one alone says little). The largest of the four."""
    u = calib.uncertainty
    if u is None:
        raise ValueError("the calibration has no uncertainty")
    M, D = (calib.M1, calib.D1) if side == "left" else (calib.M2, calib.D2)
    names = distortion_names(calib.model, np.asarray(D).size)
    keep = [k for k, n in enumerate(names) if u.index(f"{side}.{n}") is not None]
    if not keep:
        return 0.0
    C, _ = u._sub([f"{side}.{names[k]}" for k in keep])
    w, h = calib.image_size
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])
    rays = undistort_points(calib.model, corners, M, D)
    pts = np.concatenate([rays, np.ones((4, 1))], axis=1)
    _, J = project_points(calib.model, pts, np.zeros(3), np.zeros(3), M, D, True)
    Jd = J[:, [10 + k for k in keep]]
    worst = 0.0
    for c in range(4):
        cov = Jd[2 * c:2 * c + 2] @ C @ Jd[2 * c:2 * c + 2].T
        worst = max(worst, float(np.sqrt(max(np.linalg.eigvalsh(cov).max(), 0.0))))
    return worst


def poorly_determined(calib: Rig) -> list[tuple[str, float, float, str]]:
    """[(parameter name, value, 1 sigma, why)] of the parameters the data did not determine:
    intrinsics with a sigma above FOCAL_SHARE / CENTRE_SHARE, the distortion coefficients that
    are not told apart from zero (sigma above half their value) in a camera whose lens model is
    uncertain at the image corners (CORNER_SIGMA_PX), the baseline and the rotation."""
    u = calib.uncertainty
    if u is None:
        return []
    out = []
    w, h = calib.image_size
    for side, M, D in (("left", calib.M1, calib.D1), ("right", calib.M2, calib.D2)):
        for k, (i, j), limit in (("fx", (0, 0), FOCAL_SHARE * M[0, 0]),
                                 ("fy", (1, 1), FOCAL_SHARE * M[1, 1]),
                                 ("cx", (0, 2), CENTRE_SHARE * w), ("cy", (1, 2), CENTRE_SHARE * h)):
            s = u.sigma(f"{side}.{k}")
            if s > limit:
                out.append((f"{side}.{k}", float(M[i, j]), s, f"more than {limit:.1f} px"))
        corner = corner_sigma_px(calib, side)
        if corner > CORNER_SIGMA_PX:
            d = np.asarray(D, np.float64).reshape(-1)
            why = f"the {side} image corners are uncertain by {corner:.1f} px"
            if not u.distortion_identifiable:
                out.append((f"{side}.distortion", float("nan"), corner, why))
                continue
            for n, v in zip(distortion_names(calib.model, d.size), d):
                s = u.sigma(f"{side}.{n}")
                if s > 0.5 * abs(v):
                    out.append((f"{side}.{n}", float(v), s, why))
    sb = u.baseline_sigma_mm(calib.T)
    if sb > BASELINE_SHARE * calib.baseline_mm:
        out.append(("baseline", calib.baseline_mm, sb, "more than 1 % of it"))
    sr = u.rotation_sigma_deg(calib.R)
    if sr > ROTATION_DEG:
        out.append(("rotation", calib.relative_rotation_deg, sr, f"more than {ROTATION_DEG} deg"))
    return out


def calibration_warnings(calib: Rig, uncovered: dict[str, list[str]] | None = None,
                         fix_k3: bool | None = None) -> tuple[CalibrationWarning, ...]:
    """What to warn about a new calibration: swapped cameras, poorly determined parameters,
    image regions the board never covered (`uncovered`: side -> region names)."""
    out: list[CalibrationWarning] = []
    if calib.method != "hartley" and swapped(calib):
        out.append(CalibrationWarning(
            "swapped", "The cameras are swapped: the camera used as the left one sits to the "
            "right of the other (the calibration's translation puts it there). Swap the cameras "
            "and recalibrate.", "swap"))
    bad = poorly_determined(calib)
    uncovered = uncovered or {}
    if bad:
        higher = set(HIGHER_TERMS.get(calib.model, ()))
        held = fix_k3 if fix_k3 is not None else (calib.uncertainty is not None and all(
            calib.uncertainty.index(f"left.{n}") is None for n in higher))
        terms = [b for b in bad if b[0].split(".")[-1] in higher | {"distortion"}]
        listing = "; ".join(
            f"{name}: {why}" if name.endswith(".distortion") else
            f"{name} = {v:.4g} ± {s:.2g} (1 sigma, {why})" for name, v, s, why in bad)
        if terms and not held:
            names = join_names([t[0].split(".")[-1] for t in terms if not t[0].endswith(".distortion")]
                               or list(higher))
            out.append(CalibrationWarning(
                "poorly_determined", f"The pairs do not determine {names}: {listing}. Fix k3 and "
                "the higher terms (calibrate with --fix-k3, or Fix k3 and recalibrate), or capture "
                "pairs with the board in the image corners.", "fix_k3"))
        else:
            where = regions_in_words(uncovered) or "the image corners and edges"
            out.append(CalibrationWarning(
                "poorly_determined", f"Some parameters are poorly determined: {listing}. Capture "
                f"more pairs with the board in {where}, tilted and at several distances.",
                "capture"))
    if any(uncovered.values()):
        corners = any(r in CORNERS for regs in uncovered.values() for r in regs)
        far_only = all(r in FAR_SIDE[side] for side, regs in uncovered.items() for r in regs)
        remedy = (" Both cameras see the board there only when it is far away: hold it farther "
                  "off for those pairs, or use a ChArUco board, which counts when partly in view."
                  if far_only else " Capture pairs with the board there.")
        out.append(CalibrationWarning(
            "uncovered", f"The board never reached {regions_in_words(uncovered)}: the lens model "
            "is extrapolated there, so readings there are less certain"
            + (" (the corners are where the distortion is largest)" if corners else "")
            + "." + remedy, "capture"))
    return tuple(out)


def join_names(names: Sequence[str]) -> str:
    names = list(dict.fromkeys(names))
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


# ---- propagation to a reading ---------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Perturbed:
    step: float  # the parameter change, in its units
    M1: np.ndarray
    D1: np.ndarray
    M2: np.ndarray
    D2: np.ndarray
    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Q: np.ndarray


_CACHE: weakref.WeakKeyDictionary[Rig, list[tuple[_Perturbed, _Perturbed] | None]] = \
    weakref.WeakKeyDictionary()
_CACHE_LOCK = threading.Lock()


def parameter_names(model: str, n_dist: int) -> tuple[str, ...]:
    """The names a calibration's covariance may hold for lens `model` with `n_dist` distortion
    coefficients per camera: each camera's intrinsics and distortion, the rotation vector and
    the translation."""
    per_side = (*INTRINSICS, *distortion_names(model, n_dist))
    return (*(f"{side}.{n}" for side in ("left", "right") for n in per_side),
            *(f"rvec.{a}" for a in "xyz"), *(f"T.{a}" for a in "xyz"))


def _params(calib: Rig) -> dict[str, float]:
    """The calibration's parameters by the covariance's names."""
    out: dict[str, float] = {}
    for side, M, D in (("left", calib.M1, calib.D1), ("right", calib.M2, calib.D2)):
        for k, (i, j) in zip(INTRINSICS, ((0, 0), (1, 1), (0, 2), (1, 2))):
            out[f"{side}.{k}"] = float(M[i, j])
        d = np.asarray(D, np.float64).reshape(-1)
        for n, v in zip(distortion_names(calib.model, d.size), d):
            out[f"{side}.{n}"] = float(v)
    rv = cv2.Rodrigues(np.asarray(calib.R, np.float64))[0].reshape(3)
    for a, r in zip("xyz", rv):
        out[f"rvec.{a}"] = float(r)
    for a, t in zip("xyz", np.asarray(calib.T, np.float64).reshape(3)):
        out[f"T.{a}"] = float(t)
    return out


def _perturbed(calib: Rig, name: str, step: float) -> _Perturbed:
    p = _params(calib)
    p[name] += step
    nd = np.asarray(calib.D1).size
    dn = distortion_names(calib.model, nd)

    def cam(side: str) -> tuple[np.ndarray, np.ndarray]:
        M = np.array([[p[f"{side}.fx"], 0.0, p[f"{side}.cx"]], [0.0, p[f"{side}.fy"], p[f"{side}.cy"]],
                      [0.0, 0.0, 1.0]])
        return M, np.array([[p[f"{side}.{n}"] for n in dn]])

    M1, D1 = cam("left")
    M2, D2 = cam("right")
    R = cv2.Rodrigues(np.array([p["rvec.x"], p["rvec.y"], p["rvec.z"]]).reshape(3, 1))[0]
    T = np.array([[p["T.x"]], [p["T.y"]], [p["T.z"]]])
    R1, R2, P1, P2, Q = stereo_rectify(calib.model, M1, D1, M2, D2, calib.image_size, R, T,
                                       calib.alpha)
    return _Perturbed(step, M1, D1, M2, D2, R1, R2, P1, P2, Q)


def _perturbations(calib: Rig) -> list[tuple[_Perturbed, _Perturbed] | None]:
    """(+, -) perturbed calibrations for every parameter of the covariance (cached)."""
    with _CACHE_LOCK:
        hit = _CACHE.get(calib)
    if hit is not None:
        return hit
    u = calib.uncertainty
    if u is None:
        return []
    out: list[tuple[_Perturbed, _Perturbed] | None] = []
    for name in u.names:
        s = u.sigma(name)
        if not s > 0:
            out.append(None)
            continue
        out.append((_perturbed(calib, name, s), _perturbed(calib, name, -s)))
    with _CACHE_LOCK:
        _CACHE[calib] = out
    return out


def _read(calib_like: Lenses, model: str, ul: np.ndarray, ur: np.ndarray) -> np.ndarray:
    """Rectify raw pixels with a calibration and triangulate: (N, 3) points in its rectified
    frame, mm."""
    a = undistort_points(model, ul, calib_like.M1, calib_like.D1, R=calib_like.R1, P=calib_like.P1)
    b = undistort_points(model, ur, calib_like.M2, calib_like.D2, R=calib_like.R2, P=calib_like.P2)
    d = a[:, 0] - b[:, 0]
    h = np.stack([a[:, 0], a[:, 1], d, np.ones_like(d)], axis=1) @ np.asarray(calib_like.Q).T
    points: np.ndarray = h[:, :3] / h[:, 3:4]
    return points


@overload
def depth_sigma_mm(calib: Rig, x: float, y: float, d: float) -> float: ...


@overload
def depth_sigma_mm(calib: Rig, x: np.ndarray, y: np.ndarray, d: np.ndarray) -> np.ndarray: ...


def depth_sigma_mm(calib: Rig, x: float | np.ndarray, y: float | np.ndarray,
                   d: float | np.ndarray) -> np.ndarray | float:
    """The calibration's part of the error of a depth read at rectified pixel (x, y) with
    disparity d px: 1 sigma in mm (NaN without an uncertainty; scalars in, a float out).

    See the module docstring for the propagation."""
    scalar = np.ndim(x) == 0
    x, y, d = (np.atleast_1d(np.asarray(v, np.float64)) for v in (x, y, d))
    u = calib.uncertainty
    if u is None or not calib.metric:
        out = np.full(x.shape, np.nan)
        return float(out[0]) if scalar else out
    # where the two cameras saw the point that the nominal calibration reads at (x, y, d)
    h = np.stack([x, y, d, np.ones_like(x)], axis=1) @ np.asarray(calib.Q, np.float64).T
    X_rect = h[:, :3] / h[:, 3:4]
    X_left = X_rect @ np.asarray(calib.R1, np.float64)  # R1^T X
    ul = project_points(calib.model, X_left, np.zeros(3), np.zeros(3), calib.M1, calib.D1)
    rv = cv2.Rodrigues(np.asarray(calib.R, np.float64))[0]
    ur = project_points(calib.model, X_left, rv, calib.T, calib.M2, calib.D2)
    grads = []
    for pm in _perturbations(calib):
        if pm is None:
            grads.append(np.zeros(x.shape))
            continue
        zs = []
        for pert in pm:
            Xp = _read(pert, calib.model, ul, ur)
            # the error in that calibration's own rectified frame, against the point read
            Xl = Xp @ pert.R1
            zs.append(((Xl - X_left) @ pert.R1.T)[:, 2])
        grads.append((zs[0] - zs[1]) / (2.0 * pm[0].step))
    G = np.stack(grads, axis=1)  # (N, p): dZ / d parameter
    var = np.einsum("ni,ij,nj->n", G, u.covariance, G)
    out = np.sqrt(np.maximum(var, 0.0))
    return float(out[0]) if scalar else out
