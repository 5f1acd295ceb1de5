"""Hand-eye refinement on the reprojection error of the board corners.

The most accurate published pipelines (Tabb & Ahmad Yousef 2017, "reprojection error"
variants; Koide & Menegatti 2019) refine X on the pixels rather than on the per-image board
poses: a board pose from one image is poorly determined along the line of sight, and a
pose-based cost weighs those errors wrongly. Here the unknowns are

- X (``cam2flange`` eye-in-hand, ``cam2base`` eye-to-hand) and the fixed board pose Y
  (``target2base`` eye-in-hand, ``target2flange`` eye-to-hand), always;
- optionally the camera intrinsics ``(fx, fy, cx, cy, k1, k2, p1, p2, k3[, k4, k5, k6])``;
- optionally a correction ``E_i`` of every reported robot pose (``flange2base_i E_i``, a
  rotation vector and a translation in the flange frame) with a zero-mean Gaussian prior of
  the given standard deviations (robot-pose noise modelled instead of ignored).

The corner model and its Jacobian are in `kinecal.calibration.handeye.reprojection`.
Residuals are predicted minus observed pixels divided by the corner noise sigma (estimated
robustly from the residuals). Robust mode: Huber loss per corner (3 sigma) and iteratively
reweighted stations (Cauchy weights on a station's RMS relative to the median station RMS);
stations whose RMS exceeds both the chi-square bound of pure corner noise and the robust
spread of the station RMS values (and three times their median, and the median + 0.25 px)
are flagged as outliers and left out of a final pass.

Every pass is kinecal's Levenberg-Marquardt (`kinecal.optimize.lm.solve_normal_equations`) on
the structured normal equations of `kinecal.calibration.handeye.bundle` (Huber's loss as
reweighted normal equations; the robot-pose corrections eliminated by the Schur complement)
with the analytic Jacobian (right Jacobians of SO(3); tested against finite differences).
The covariance of the parameters is ``s^2 (J^T J)^-1`` from the final pass (the Jacobian
scaled as scipy scales it for a robust loss: corners beyond Huber's threshold count
``eps``).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtri
from kinecal.calibration.handeye.bundle import normal_equations, robust_residuals, schur_solve
from kinecal.calibration.handeye.camera import check_camera
from kinecal.calibration.handeye.refinement import ReprojectionRefinement
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    parameter_names,
    predict_blocks,
    predict_corners,
    predict_pixels,
    unpack,
)
from kinecal.calibration.handeye.scara import AxisHeight, OneAxis
from kinecal.errors import InputError
from kinecal.optimize.lm import solve_normal_equations

Array = NDArray[np.float64]

__all__ = ["predict_corners", "refine_reprojection"]

_HUBER = 3.0
_CAUCHY = 2.5


def refine_reprojection(
    flange2base: Array,
    points: list[Array],
    pixels: list[Array],
    K: Array,
    dist: Array | None,
    X0: Array,
    Y0: Array,
    *,
    setup: str = "eye-in-hand",
    refine_intrinsics: bool = False,
    rational: bool = False,
    robot_noise: tuple[float, float] | None = None,
    robust: bool = True,
    outlier_level: float = 0.999,
    max_outer: int = 8,
    one_axis: tuple[OneAxis, AxisHeight] | None = None,
) -> ReprojectionRefinement:
    """Refine X, the board pose (and optionally intrinsics, robot poses) on the pixels.

    Parameters
    ----------
    flange2base : ndarray, shape (n, 4, 4)
        Reported robot poses (length unit L of the board), n >= 3.
    points : list of ndarray, shape (N_i, 3)
        Board coordinates of the corners detected in image i.
    pixels : list of ndarray, shape (N_i, 2)
        Their detected pixel positions.
    K, dist
        Camera matrix and OpenCV distortion coefficients.
    X0, Y0 : ndarray, shape (4, 4)
        Start (a closed form): X and the board pose (``target2base`` eye-in-hand,
        ``target2flange`` eye-to-hand).
    setup : {"eye-in-hand", "eye-to-hand"}
    refine_intrinsics : bool
        Free ``fx, fy, cx, cy, k1, k2, p1, p2, k3`` (and ``k4..k6`` with `rational`).
    rational : bool
        The camera uses the 8-coefficient rational model.
    robot_noise : (float, float), optional
        Standard deviations of the robot poses' error, rotation (rad) and translation (L),
        per axis: model a correction of every robot pose with this Gaussian prior.
    robust : bool
        Huber loss, station reweighting and outlier stations (default); False: plain least
        squares over all stations.
    outlier_level : float
        Chi-square probability of the outlier bound.
    max_outer : int
        Reweighting passes.
    one_axis : (OneAxis, AxisHeight), optional
        The robot turns about one axis only (SCARA): the pixels do not see X's translation
        along it either (`kinecal.calibration.handeye.scara`, [S3]); the solution is put
        where the height says, and the covariance is taken under that constraint.

    Returns
    -------
    ReprojectionRefinement
    """
    t0 = time.perf_counter()
    K, d8, F, counts = _check_inputs(flange2base, points, pixels, K, dist, setup, robot_noise)
    n = len(F)
    sid = np.repeat(np.arange(n), counts).astype(np.intp)
    P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in points])
    uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in pixels])
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    pr = ReprojectionProblem(F, P, uv, sid, setup == "eye-in-hand", K, d8, np.asarray(X0, float),
                             np.asarray(Y0, float), n_int, robot_noise)
    fit = _Fit(pr, counts)
    p = np.zeros(pr.n_params)
    history: list[float] = []
    r, srms = fit.residual_stats(p)
    inlier = np.ones(n, bool)
    if robust:
        p, r, srms, sigma = _reweighted_passes(fit, p, r, max_outer, history)
        inlier = ~_outlier_stations(srms, counts, sigma, outlier_level)
        if inlier.sum() < 3:
            inlier = np.ones(n, bool)
        sigma = fit.sigma_of(r, inlier)
    else:
        sigma = max(float(np.sqrt(np.mean(r**2))), 1e-6)
    # final pass: inliers, unit weights; sigma from their residuals
    p, cost, A_cov, raw = fit.solve(p, inlier.astype(float), sigma,
                                    "huber" if robust else "linear", final=True)
    history.append(cost)
    r, srms = fit.residual_stats(p)
    if not robust:
        sigma = max(float(np.sqrt(np.sum(r**2) / max(r.size - pr.n_params, 1))), 1e-12)
    row = None
    if one_axis is not None:  # [S8] of `scara`: move along the null direction, constrain
        p, row = _place_on_axis(pr, p, *one_axis)
        r, srms = fit.residual_stats(p)
    # covariance: the normal matrix of the final pass at the solution, residual variance
    s2 = float(raw @ raw) / max(raw.size - pr.n_params + (row is not None), 1)
    cov = _covariance(A_cov, s2, row)
    X, Y, Kf, df, E = unpack(pr, p)
    res = np.split(-r, np.cumsum(counts)[:-1])
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    return ReprojectionRefinement(X, Y, Kf, df, None if E is None else E.copy(), res, srms,
                                  outliers, float(sigma), cov, parameter_names(pr), fit.nfev,
                                  history, time.perf_counter() - t0)


def _check_inputs(flange2base: Array, points: list[Array], pixels: list[Array], K: Array,
                  dist: Array | None, setup: str, robot_noise: tuple[float, float] | None
                  ) -> tuple[Array, Array, Array, NDArray[np.intp]]:
    """Validated camera ``(K, d8)``, robot poses and the corner count per station."""
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="setup")
    K, d8 = check_camera(K, dist)
    F = np.asarray(flange2base, float)
    n = len(F)
    if len(points) != n or len(pixels) != n:
        raise InputError(f"{n} robot poses but {len(points)} / {len(pixels)} corner sets")
    if n < 3:
        raise InputError(f"{n} stations: hand-eye calibration needs at least 3")
    if robot_noise is not None and not (robot_noise[0] > 0 and robot_noise[1] > 0):
        raise InputError(f"robot_noise {robot_noise}: expected two positive standard "
                         "deviations (rad, length)", option="robot_noise")
    counts = np.array([len(p) for p in points])
    if np.any(counts == 0):
        raise InputError(f"station {int(np.argmin(counts))} has no corners")
    return K, d8, F, counts


def _reweighted_passes(fit: _Fit, p: Array, r: Array, max_outer: int, history: list[float]
                       ) -> tuple[Array, Array, Array, float]:
    """Huber passes with Cauchy station weights on the station RMS relative to the median
    station (until the weights settle); returns p, residuals, station RMS and sigma."""
    n = fit.pr.n
    w = np.ones(n)
    sigma = fit.sigma_of(r, np.ones(n, bool))
    srms = np.zeros(n)
    for _ in range(max_outer):
        p, cost, _, _ = fit.solve(p, w, sigma, "huber")
        history.append(cost)
        r, srms = fit.residual_stats(p)
        sigma = fit.sigma_of(r, w > 0.5)
        med = float(np.median(srms))
        w_new = 1.0 / (1.0 + (srms / (_CAUCHY * max(med, sigma))) ** 2)
        done = np.max(np.abs(w_new - w)) < 1e-3
        w = w_new
        if done:
            break
    return p, r, srms, sigma


class _Fit:
    """The reprojection problem's passes: residual statistics, robust scale, and one
    weighted (robust) least-squares solve on the structured normal equations."""

    def __init__(self, pr: ReprojectionProblem, counts: NDArray[np.intp]) -> None:
        self.pr = pr
        self.counts = counts
        self.starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
        self.g = 12 + pr.n_int
        self.prior = (np.r_[[1.0 / pr.robot[0]] * 3, [1.0 / pr.robot[1]] * 3]
                      if pr.robot else None)
        self.nfev = 0
        self._last: tuple[Array, tuple] | None = None

    def blocks(self, p: Array) -> tuple[Array, Array, Array | None]:
        """`predict_blocks` at `p`, kept for the next call at the same point (the end of
        one pass is where the next starts and where the statistics are taken)."""
        if self._last is None or not np.array_equal(self._last[0], p):
            self._last = (p.copy(), predict_blocks(self.pr, p))
        return self._last[1]

    def residual_stats(self, p: Array) -> tuple[Array, Array]:
        """Residuals ``(M, 2)`` (predicted minus observed, px) and station RMS ``(n,)``."""
        pred = self.blocks(p)[0] if self._last is not None and \
            np.array_equal(self._last[0], p) else predict_pixels(self.pr, p, False)[0]
        r = pred - self.pr.uv
        ss = np.bincount(self.pr.sid, weights=np.sum(r * r, axis=1), minlength=self.pr.n)
        return r, np.sqrt(ss / np.maximum(self.counts, 1))

    def sigma_of(self, r: Array, mask: Array) -> float:
        """Robust corner noise (px per axis) over the stations in `mask`."""
        sel = r[mask[self.pr.sid]].ravel()
        s = 1.4826 * float(np.median(np.abs(sel))) if sel.size else 1.0
        return max(s, 1e-6)

    def solve(self, p: Array, w: Array, sigma: float, loss: str, final: bool = False
              ) -> tuple[Array, float, Array | None, Array | None]:
        """Minimise ``sum rho(r^2)`` over corners weighted by station weights `w` ``(n,)``
        (residuals in units of `sigma`, Huber threshold `_HUBER`) and the robot prior.

        Returns p, the cost (twice scipy's ``0.5 sum rho``) and, for the `final` pass, the
        normal matrix with scipy's robust scaling of the Jacobian (for the covariance) and
        the raw residuals of the weighted rows (zero-weight stations left out)."""
        pr, g, prior = self.pr, self.g, self.prior
        scale = (np.sqrt(w) / sigma)[pr.sid]  # (M,) per corner

        def rows(q: Array) -> tuple[Array, Array, Array | None, Array | None]:
            pred, Jg, Je = self.blocks(q)
            res = (pred - pr.uv) * scale[:, None]
            Jg = Jg * scale[:, None, None]
            if Je is not None:
                Je = Je * scale[:, None, None]
            rp = None if prior is None else q[g:].reshape(-1, 6) * prior
            return res, Jg, Je, rp

        def equations(q: Array) -> tuple[Array, Array, Array]:
            res, Jg, Je, rp = rows(q)
            pseudo, wr, _ = robust_residuals(res, loss, _HUBER)
            pri = None
            out = [pseudo.ravel()]
            if rp is not None:
                pp, wp, _ = robust_residuals(rp, loss, _HUBER)
                pri = (np.broadcast_to(prior, rp.shape), wp, rp)
                out.append(pp.ravel())
            A, b = normal_equations(Jg, Je, wr, res, self.starts, pri)
            return np.concatenate(out), A, b

        # the passes before the last only set the station weights: 1e-9 suffices there
        tol = 1e-12 if final else 1e-9
        sol = solve_normal_equations(equations, p,
                                     linear_solver=lambda A, d, b: schur_solve(A, d, b, g),
                                     ftol=tol, xtol=tol, gtol=tol, max_nfev=200,
                                     damping=(1e-9, 1e-3))
        self.nfev += int(sol.nfev)
        q = sol.x
        if not final:
            return q, float(2.0 * sol.fun), None, None
        res, Jg, Je, rp = rows(q)
        _, _, c = robust_residuals(res, loss, _HUBER)
        pri = None
        raw = res[w[pr.sid] > 0].ravel()
        if rp is not None:
            pri = (np.broadcast_to(prior, rp.shape), robust_residuals(rp, loss, _HUBER)[2], rp)
            raw = np.concatenate([raw, rp.ravel()])
        A_cov, _ = normal_equations(Jg, Je, c, res, self.starts, pri)
        return q, float(2.0 * sol.fun), A_cov, raw


def _place_on_axis(pr: ReprojectionProblem, p: Array, axis: OneAxis,
                   height: AxisHeight) -> tuple[Array, Array]:
    """Parameters moved along the unobservable direction so that the height holds, and the
    constraint row ``(n_params,)`` of the height at the result (`scara.AxisHeight`)."""
    from kinecal.calibration.handeye.refine import _jr

    X, Y = unpack(pr, p)[:2]
    X2, Y2 = height.place(axis, X, Y)
    q = p.copy()
    q[3:6] += X2[:3, 3] - X[:3, 3]
    q[9:12] += Y2[:3, 3] - Y[:3, 3]
    c = height.constraint(axis, Y2)
    row = np.zeros(pr.n_params)
    row[:12] = c
    # the rotations are R0 Exp(p): a change d of p turns the frame by J_r(p) d
    row[0:3] = _jr(q[0:3]).T @ c[0:3]
    row[6:9] = _jr(q[6:9]).T @ c[6:9]
    return q, row


def _covariance(A: Array, s2: float, row: Array | None) -> Array:
    """``s2 A^-1`` for the normal matrix ``A = J^T J`` ``(n_params, n_params)``, restricted
    to ``row . p = 0`` when a row is given (a constrained direction that J does not see)."""
    n = A.shape[0]
    try:
        if row is None:
            return s2 * np.linalg.inv(A)
        N = np.linalg.svd(row.reshape(1, -1))[2][1:].T
        return s2 * N @ np.linalg.inv(N.T @ A @ N) @ N.T
    except np.linalg.LinAlgError:
        return np.full((n, n), np.inf)


def _outlier_stations(srms: Array, counts: Array, sigma: float, level: float) -> Array:
    """Stations beyond the chi-square bound of pure corner noise (2 N_i dof), the robust
    spread of the station RMS values (median + 5 x 1.4826 MAD), three times the median
    station RMS and the median + 0.25 px (detection biases of a tenth of a pixel on oblique
    views are not outliers; a wrong robot pose costs pixels)."""
    med = float(np.median(srms))
    mad = 1.4826 * float(np.median(np.abs(srms - med)))
    out = (srms > med + 5.0 * mad) & (srms > max(3.0 * med, med + 0.25))
    if out.any():  # the chi-square bound only where the robust ones already flag
        dof = 2 * np.maximum(counts[out], 1)
        out[out] = srms[out] > np.sqrt(chdtri(dof, 1.0 - level) / dof) * sigma
    return out
