"""Joint refinement of a stereo calibration over every observed point, and its covariance.

One Levenberg-Marquardt solve over both cameras' intrinsics and distortion, the relative pose
(R_right_left as a Rodrigues vector, T_right_left in mm) and every view's board pose in the left
camera, minimising the reprojection error of every point each camera saw. Unlike
cv2.stereoCalibrate it needs no point to be seen by both cameras, so the corners of a partly
visible ChArUco board that only one camera saw still shape that camera's lens model; and it works
the same way for every lens model (core.lens gives the projections and their Jacobians).

The covariance of the camera parameters is sigma^2 (J^T J)^-1 at the solution (the board poses
marginalised out), with sigma the residual standard deviation per coordinate: the 1-sigma
uncertainty of the calibration if the corner errors are independent, the assumption this module
rests on (scripts/bench_uncertainty.py checks it against the truth of the simulated rig).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike

from stereo_gui.core.errors import CalibrationError
from stereo_gui.core.lens import distortion_names, project_points

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class View:
    """One calibration view: the board points each camera saw (mm, on the board) and where
    (px). Either side may be empty (no points), not both."""

    obj_left: np.ndarray  # (N, 3)
    img_left: np.ndarray  # (N, 2)
    obj_right: np.ndarray  # (K, 3)
    img_right: np.ndarray  # (K, 2)


@dataclass(frozen=True, eq=False)
class BundleResult:
    """The refined calibration, per-view errors and the camera parameters' covariance.

    `names` label the covariance's rows: "left.fx" ... "left.k1" ..., "right.fx" ...,
    "rvec.x/y/z" (R_right_left, rad), "T.x/y/z" (mm). Fixed parameters are not among them.
    """

    M1: np.ndarray
    D1: np.ndarray
    M2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray  # 3x1 mm
    rvecs: tuple[np.ndarray, ...]  # board pose of each view in the left camera
    tvecs: tuple[np.ndarray, ...]
    errors: tuple[tuple[float, float], ...]  # per view RMS px (left, right); NaN without points
    rms: float  # RMS over every point of both cameras, px
    sigma_px: float  # residual standard deviation per coordinate, px
    names: tuple[str, ...]
    covariance: np.ndarray  # (len(names), len(names))
    iterations: int


def _camera_names(side: str, model: str, nd: int) -> list[str]:
    return [f"{side}.{n}" for n in ("fx", "fy", "cx", "cy")] + \
        [f"{side}.{n}" for n in distortion_names(model, nd)]


def _unpack_camera(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    M = np.array([[x[0], 0.0, x[2]], [0.0, x[1], x[3]], [0.0, 0.0, 1.0]])
    return M, x[4:].copy()


# The rational model's numerator and denominator (k1..k3 and k4..k6) can grow together and
# describe the same lens: its cost has a flat valley along which the solve drifts wherever
# rounding leads it (the same detections can give principal points most of a pixel apart).
# A weak prior at zero (1 sigma = RATIONAL_PRIOR, costing what PRIOR_PX of image error would)
# makes the minimum unique without moving the lens it describes.
RATIONAL_PRIOR = 1.0
PRIOR_PX = 0.1


def refine_stereo(views: Sequence[View], model: str, M1: np.ndarray, D1: np.ndarray,
                  M2: np.ndarray, D2: np.ndarray, R: np.ndarray, T: np.ndarray,
                  rvecs: Sequence[np.ndarray], tvecs: Sequence[np.ndarray],
                  fixed: Sequence[str] = (), max_iterations: int = 60,
                  tolerance: float = 1e-10) -> BundleResult:
    """Refine everything jointly from the given starting point; see the module docstring.

    `fixed` names distortion coefficients (e.g. "k3") held at their starting values in both
    cameras. Raises CalibrationError when the problem is singular.
    """
    D1 = np.asarray(D1, np.float64).reshape(-1)
    D2 = np.asarray(D2, np.float64).reshape(-1)
    start: list[ArrayLike] = [
        [M1[0, 0], M1[1, 1], M1[0, 2], M1[1, 2]], D1,
        [M2[0, 0], M2[1, 1], M2[0, 2], M2[1, 2]], D2,
        cv2.Rodrigues(np.asarray(R, np.float64))[0].reshape(3), np.asarray(T, np.float64).reshape(3)]
    start += [np.concatenate([np.asarray(r, np.float64).reshape(3),
                              np.asarray(t, np.float64).reshape(3)])
              for r, t in zip(rvecs, tvecs)]
    x0 = np.concatenate(start)
    problem = _Problem.of(list(views), model, D1.size, fixed)
    x, r, J, it = _levenberg_marquardt(problem, x0, max_iterations, tolerance)
    cov, names, sigma2 = _camera_covariance(problem, r, J)

    nc, n_cam, nv = problem.nc, problem.n_cam, len(problem.views)
    M1n, D1n = _unpack_camera(x[:nc])
    M2n, D2n = _unpack_camera(x[nc:2 * nc])
    Rn = cv2.Rodrigues(x[2 * nc:2 * nc + 3].reshape(3, 1))[0]
    Tn = x[2 * nc + 3:2 * nc + 6].reshape(3, 1)
    obs = r[:problem.m_obs]
    rms = float(np.sqrt(float(obs @ obs) / (problem.m_obs / 2)))
    rv = tuple(x[n_cam + 6 * k:n_cam + 6 * k + 3].copy() for k in range(nv))
    tv = tuple(x[n_cam + 6 * k + 3:n_cam + 6 * k + 6].copy() for k in range(nv))
    log.debug("stereo refinement: %d iterations, rms %.4f px", it, rms)
    return BundleResult(M1n, D1n.reshape(1, -1), M2n, D2n.reshape(1, -1), Rn, Tn, rv, tv,
                        _view_errors(problem.views, r), rms, float(np.sqrt(sigma2)), names, cov,
                        it)


@dataclass(frozen=True, eq=False)
class _Problem:
    """The solve's layout: the parameter vector is both cameras' (fx, fy, cx, cy, distortion;
    `nc` each), R_right_left's Rodrigues vector and T_right_left (the first `n_cam`), then each
    view's board pose (rvec, tvec). `free` marks the parameters solved for; the residuals are
    every observed coordinate (`m_obs`), then one prior row per column of `prior_cols`."""

    views: list[View]
    model: str
    nd: int
    nc: int
    n_cam: int
    free: np.ndarray
    prior_cols: list[int]
    m_obs: int

    @classmethod
    def of(cls, views: list[View], model: str, nd: int, fixed: Sequence[str]) -> _Problem:
        nc = 4 + nd
        dist_names = distortion_names(model, nd)
        cam_free = np.ones(nc, bool)
        for name in fixed:
            if name in dist_names:
                cam_free[4 + dist_names.index(name)] = False
        free = np.concatenate([cam_free, cam_free, np.ones(6 + 6 * len(views), bool)])
        m_obs = sum(2 * (len(v.img_left) + len(v.img_right)) for v in views)
        # prior rows: the rational model's k1..k6 of both cameras (see RATIONAL_PRIOR)
        prior_cols = []
        if model == "rational":
            for cam in (0, 1):
                for name in ("k1", "k2", "k3", "k4", "k5", "k6"):
                    col = cam * nc + 4 + dist_names.index(name)
                    if free[col]:
                        prior_cols.append(col)
        p = int(free.sum())
        if m_obs <= p:
            raise CalibrationError(f"too few points ({m_obs // 2}) for the {p} parameters of "
                                   "the stereo calibration")
        return cls(views, model, nd, nc, 2 * nc + 6, free, prior_cols, m_obs)

    @property
    def m(self) -> int:
        return self.m_obs + len(self.prior_cols)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """The residuals at `x`: px, then the prior rows."""
        return self._evaluate(x, False)[0]

    def with_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residuals at `x` and their Jacobian."""
        return self._evaluate(x, True)

    def normal_equations(self, J: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """J^T J and J^T r over the free parameters, from the Jacobian's structure: a view's
        rows touch only the cameras' and the rig's parameters and its own board pose, so J^T J
        is the sum of each view's small product (57 views: 366 parameters by 12,000 rows as a
        dense product took most of a solve's time)."""
        n = J.shape[1]
        A = np.zeros((n, n))
        row = 0
        for k, v in enumerate(self.views):
            rows = 2 * (len(v.img_left) + len(v.img_right))
            cols = np.r_[0:self.n_cam, self.n_cam + 6 * k:self.n_cam + 6 * k + 6]
            block = J[row:row + rows][:, cols]
            A[np.ix_(cols, cols)] += block.T @ block
            row += rows
        prior = J[row:]
        if prior.size:
            A += prior.T @ prior
        free = self.free
        return A[np.ix_(free, free)], (J.T @ r)[free]

    def _evaluate(self, x: np.ndarray, want_j: bool) -> tuple[np.ndarray, np.ndarray]:
        """The residuals and, if `want_j`, their Jacobian (else an empty array)."""
        nc, n_cam, model = self.nc, self.n_cam, self.model
        Ml, Dl = _unpack_camera(x[:nc])
        Mr, Dr = _unpack_camera(x[nc:2 * nc])
        rRL, tRL = x[2 * nc:2 * nc + 3], x[2 * nc + 3:2 * nc + 6]
        res = np.empty(self.m)
        J = np.zeros((self.m, x.size) if want_j else (0, 0))
        row = 0
        for k, v in enumerate(self.views):
            o = n_cam + 6 * k
            rv, tv = x[o:o + 3], x[o + 3:o + 6]
            if len(v.img_left):
                n2 = 2 * len(v.img_left)
                if want_j:
                    uv, jj = project_points(model, v.obj_left, rv, tv, Ml, Dl, True)
                    J[row:row + n2, o:o + 6] = jj[:, 0:6]
                    J[row:row + n2, 0:nc] = jj[:, 6:]
                else:
                    uv = project_points(model, v.obj_left, rv, tv, Ml, Dl)
                res[row:row + n2] = (uv - v.img_left).reshape(-1)
                row += n2
            if len(v.img_right):
                n2 = 2 * len(v.img_right)
                (r3, t3, dr3dr1, dr3dt1, dr3dr2, dr3dt2, dt3dr1, dt3dt1, dt3dr2,
                 dt3dt2) = cv2.composeRT(rv.reshape(3, 1), tv.reshape(3, 1),
                                         rRL.reshape(3, 1), tRL.reshape(3, 1))
                if want_j:
                    uv, jj = project_points(model, v.obj_right, r3, t3, Mr, Dr, True)
                    jr, jt = jj[:, 0:3], jj[:, 3:6]
                    J[row:row + n2, o:o + 3] = jr @ dr3dr1 + jt @ dt3dr1
                    J[row:row + n2, o + 3:o + 6] = jr @ dr3dt1 + jt @ dt3dt1
                    J[row:row + n2, 2 * nc:2 * nc + 3] = jr @ dr3dr2 + jt @ dt3dr2
                    J[row:row + n2, 2 * nc + 3:2 * nc + 6] = jr @ dr3dt2 + jt @ dt3dt2
                    J[row:row + n2, nc:2 * nc] = jj[:, 6:]
                else:
                    uv = project_points(model, v.obj_right, r3, t3, Mr, Dr)
                res[row:row + n2] = (uv - v.img_right).reshape(-1)
                row += n2
        w = PRIOR_PX / RATIONAL_PRIOR
        for col in self.prior_cols:
            res[row] = w * x[col]
            if want_j:
                J[row, col] = w
            row += 1
        return res, J


def _levenberg_marquardt(problem: _Problem, x0: np.ndarray, max_iterations: int,
                         tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Levenberg-Marquardt from `x0` over the free parameters: (x, residuals, Jacobian,
    iterations) at the solution."""
    free = problem.free
    x = x0.copy()
    r, J = problem.with_jacobian(x)
    cost = float(r @ r)
    lam = 1e-3
    it = 0
    for it in range(1, max_iterations + 1):
        A, g = problem.normal_equations(J, r)
        diag = np.diag(A).copy()
        diag[diag <= 0] = 1.0
        improved = False
        for _ in range(12):
            try:
                step = np.linalg.solve(A + lam * np.diag(diag), -g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = x.copy()
            xn[free] += step
            rn = problem.residuals(xn)
            cn = float(rn @ rn)
            if np.isfinite(cn) and cn < cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
        rel = (cost - cn) / max(cost, 1e-300)
        x, cost = xn, cn
        r, J = problem.with_jacobian(x)
        lam = max(lam / 10.0, 1e-12)
        if rel < tolerance:
            break
    return x, r, J, it


def _camera_covariance(problem: _Problem, r: np.ndarray, J: np.ndarray
                       ) -> tuple[np.ndarray, tuple[str, ...], float]:
    """The camera parameters' covariance sigma^2 (J^T J)^-1 (the board poses marginalised out),
    the names of its rows, and sigma^2."""
    free = problem.free
    A, _ = problem.normal_equations(J, r)
    dof = problem.m_obs - int(free.sum())
    sigma2 = float(r[:problem.m_obs] @ r[:problem.m_obs]) / dof
    try:
        cov_free = np.linalg.inv(A) * sigma2
    except np.linalg.LinAlgError as exc:
        raise CalibrationError("the stereo calibration is singular: the views do not determine "
                               "the cameras (more varied board poses are needed)") from exc
    idx_free = np.flatnonzero(free)
    cam_idx = [i for i, f in enumerate(idx_free) if f < problem.n_cam]
    cov = cov_free[np.ix_(cam_idx, cam_idx)]
    names_all = (_camera_names("left", problem.model, problem.nd)
                 + _camera_names("right", problem.model, problem.nd)
                 + ["rvec.x", "rvec.y", "rvec.z", "T.x", "T.y", "T.z"])
    names = tuple(names_all[i] for i in idx_free[cam_idx])
    return cov, names, sigma2


def _view_errors(views: list[View], r: np.ndarray) -> tuple[tuple[float, float], ...]:
    """Each view's RMS reprojection error (left, right), px; NaN for a side without points."""
    errors = []
    row = 0
    for v in views:
        e = []
        for pts in (v.img_left, v.img_right):
            n2 = 2 * len(pts)
            if n2 == 0:
                e.append(float("nan"))
                continue
            d = r[row:row + n2].reshape(-1, 2)
            e.append(float(np.sqrt(np.mean(np.sum(d * d, axis=1)))))
            row += n2
        errors.append((e[0], e[1]))
    return tuple(errors)
