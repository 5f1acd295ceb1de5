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

Every pass is scipy's trust-region least squares with the analytic Jacobian (right
Jacobians of SO(3); tested against finite differences). The covariance of the parameters
is ``s^2 (J^T J)^-1`` from the final pass.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.special import chdtri

from kinecal.calibration.handeye.camera import check_camera
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    parameter_names,
    predict_corners,
    predict_pixels,
    unpack,
)
from kinecal.calibration.handeye.scara import AxisHeight, OneAxis
from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = ["ReprojectionRefinement", "predict_corners", "refine_reprojection"]

_HUBER = 3.0
_CAUCHY = 2.5


@dataclass
class ReprojectionRefinement:
    """Result of `refine_reprojection`.

    Attributes
    ----------
    X, Y : ndarray, shape (4, 4)
        Refined hand-eye transform and board pose.
    K : ndarray, shape (3, 3)
    dist : ndarray, shape (8,)
        Intrinsics (refined when asked).
    corrections : ndarray, shape (n, 6) or None
        Estimated robot-pose corrections ``(rotation vector rad, translation)`` per station
        (flange frame), when robot noise was modelled.
    residuals : list of ndarray, shape (N_i, 2)
        Observed minus predicted corners per station (px), every station.
    station_rms : ndarray, shape (n,)
        RMS corner residual per station (px).
    outliers : list of int
        Stations left out of the final pass.
    sigma_px : float
        Corner noise (px per axis), robust estimate.
    cov : ndarray, shape (p, p)
        Covariance of the free parameters (order: X rotation, X translation, Y rotation,
        Y translation, intrinsics, corrections).
    names : list of str
        Names of the free parameters.
    nfev : int
    history : list of float
        Cost after each pass.
    seconds : float
    """

    X: Array
    Y: Array
    K: Array
    dist: Array
    corrections: Array | None
    residuals: list[Array]
    station_rms: Array
    outliers: list[int]
    sigma_px: float
    cov: Array
    names: list[str]
    nfev: int = 0
    history: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def X_cov(self) -> Array:
        """Covariance ``(6, 6)`` of X: rotation vector (rad, X frame), translation."""
        return self.cov[:6, :6]

    @property
    def X_std(self) -> tuple[Array, Array]:
        """Standard deviations of X: rotation (deg, about X's own axes) and translation."""
        d = np.sqrt(np.clip(np.diag(self.X_cov), 0.0, None))
        return np.degrees(d[:3]), d[3:]

    @property
    def Y_std(self) -> tuple[Array, Array]:
        """Standard deviations of the board pose: rotation (deg) and translation."""
        d = np.sqrt(np.clip(np.diag(self.cov[6:12, 6:12]), 0.0, None))
        return np.degrees(d[:3]), d[3:]

    @property
    def rms_px(self) -> float:
        """RMS corner residual over the inlier stations (px)."""
        keep = [r for i, r in enumerate(self.residuals) if i not in set(self.outliers)]
        allr = np.concatenate(keep) if keep else np.zeros((0, 2))
        return float(np.sqrt(np.mean(np.sum(allr**2, axis=1)))) if allr.size else 0.0


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
        along it either (`kinecal.calibration.handeye.scara`, eq. (3)); the solution is put
        where the height says, and the covariance is taken under that constraint.

    Returns
    -------
    ReprojectionRefinement
    """
    t0 = time.perf_counter()
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
    sid = np.repeat(np.arange(n), counts).astype(np.intp)
    P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in points])
    uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in pixels])
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    pr = ReprojectionProblem(F, P, uv, sid, setup == "eye-in-hand", K, d8, np.asarray(X0, float),
                  np.asarray(Y0, float), n_int, robot_noise)
    p = np.zeros(pr.n_params)
    nfev = 0
    history: list[float] = []

    def residual_stats(p: Array) -> tuple[Array, Array]:
        pred, _ = predict_pixels(pr, p, False)
        r = pred - uv
        ss = np.bincount(sid, weights=np.sum(r * r, axis=1), minlength=n)
        return r, np.sqrt(ss / np.maximum(counts, 1))

    def sigma_of(r: Array, mask: Array) -> float:
        sel = r[mask[sid]].ravel()
        s = 1.4826 * float(np.median(np.abs(sel))) if sel.size else 1.0
        return max(s, 1e-6)

    def solve(p: Array, w: Array, sigma: float, loss: str) -> tuple[Array, float, Any]:
        nonlocal nfev
        keep = w[sid] > 0
        sw = np.sqrt(w[sid][keep])[:, None]
        npix = 2 * int(keep.sum())
        prior = (np.r_[[1.0 / robot_noise[0]] * 3, [1.0 / robot_noise[1]] * 3]
                 if robot_noise else None)

        def fun(q: Array) -> Array:
            pred, _ = predict_pixels(pr, q, False)
            r = (sw * (pred[keep] - uv[keep]) / sigma).ravel()
            if prior is not None:
                r = np.concatenate([r, (q[12 + n_int:].reshape(-1, 6) * prior).ravel()])
            return r

        def jacobian(q: Array) -> Array:
            _, J = predict_pixels(pr, q, True)
            Jk = (J[keep] * (sw[:, :, None] / sigma)).reshape(npix, -1)
            if prior is not None:
                Jp = np.zeros((6 * n, pr.n_params))
                Jp[:, 12 + n_int:] = np.diag(np.tile(prior, n))
                Jk = np.vstack([Jk, Jp])
            return Jk

        sol = least_squares(fun, p, jac=jacobian, method="trf", loss=loss,
                            f_scale=_HUBER, x_scale="jac", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12, max_nfev=200)
        nfev += int(sol.nfev)
        return sol.x, float(2.0 * sol.cost), sol

    w = np.ones(n)
    r, srms = residual_stats(p)
    inlier = np.ones(n, bool)
    if robust:
        sigma = sigma_of(r, np.ones(n, bool))
        for _ in range(max_outer):
            p, cost, _ = solve(p, w, sigma, "huber")
            history.append(cost)
            r, srms = residual_stats(p)
            sigma = sigma_of(r, w > 0.5)
            med = float(np.median(srms))
            w_new = 1.0 / (1.0 + (srms / (_CAUCHY * max(med, sigma))) ** 2)
            done = np.max(np.abs(w_new - w)) < 1e-3
            w = w_new
            if done:
                break
        inlier = ~_outlier_stations(srms, counts, sigma, outlier_level)
        if inlier.sum() < 3:
            inlier = np.ones(n, bool)
    else:
        sigma = max(float(np.sqrt(np.mean(r**2))), 1e-6)
    # final pass: inliers, unit weights; sigma from their residuals
    sigma = sigma_of(r, inlier) if robust else sigma
    p, cost, sol = solve(p, inlier.astype(float), sigma, "huber" if robust else "linear")
    history.append(cost)
    r, srms = residual_stats(p)
    if not robust:
        sigma = max(float(np.sqrt(np.sum(r**2) / max(r.size - pr.n_params, 1))), 1e-12)
    # covariance: the Jacobian of the final pass at the solution, residual variance
    J = sol.jac
    m = J.shape[0]
    row = None
    if one_axis is not None:  # eq. (8) of `scara`: move along the null direction, constrain
        p, row = _place_on_axis(pr, p, *one_axis)
        r, srms = residual_stats(p)
    s2 = float(np.sum(sol.fun**2)) / max(m - pr.n_params + (row is not None), 1)
    cov = _covariance(J, s2, row)
    X, Y, Kf, df, E = unpack(pr, p)
    res = np.split(-r, np.cumsum(counts)[:-1])
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    return ReprojectionRefinement(X, Y, Kf, df, None if E is None else E.copy(), res, srms,
                                  outliers, float(sigma), cov, parameter_names(pr), nfev,
                                  history, time.perf_counter() - t0)


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


def _covariance(J: Array, s2: float, row: Array | None) -> Array:
    """``s2 (J^T J)^-1``, restricted to ``row . p = 0`` when a row is given (a constrained
    direction that J does not see)."""
    n = J.shape[1]
    try:
        if row is None:
            return s2 * np.linalg.inv(J.T @ J)
        N = np.linalg.svd(row.reshape(1, -1))[2][1:].T
        return s2 * N @ np.linalg.inv(N.T @ (J.T @ J) @ N) @ N.T
    except np.linalg.LinAlgError:
        return np.full((n, n), np.inf)


def _outlier_stations(srms: Array, counts: Array, sigma: float, level: float) -> Array:
    """Stations beyond the chi-square bound of pure corner noise (2 N_i dof), the robust
    spread of the station RMS values (median + 5 x 1.4826 MAD), three times the median
    station RMS and the median + 0.25 px (detection biases of a tenth of a pixel on oblique
    views are not outliers; a wrong robot pose costs pixels)."""
    dof = 2 * np.maximum(counts, 1)
    chi = np.sqrt(chdtri(dof, 1.0 - level) / dof) * sigma
    med = float(np.median(srms))
    mad = 1.4826 * float(np.median(np.abs(srms - med)))
    return (srms > chi) & (srms > med + 5.0 * mad) & (srms > max(3.0 * med, med + 0.25))
