"""Levenberg-Marquardt refinement of a hand-eye solution on the absolute-pose cost.

Beyond paper 001 (which refines ``A X = X B`` with metaheuristics, see `refine_meta`):
the target pose ``Y`` is estimated jointly with ``X`` from ``G_i X C_i = Y`` (paper 001,
sec. 2, eq. (1)), which uses every station once instead of station pairs, so no
measurement enters many pairs with correlated errors.

Residual of station i (in the camera frame, where the largest noise enters): with the
predicted ``C^_i = X^-1 G_i^-1 Y``,

    r_i = ( log(R^_i^T R_Ci) / s_R ,  (t_Ci - t^_i) / s_t )      (6 numbers)

``s_R`` (rad) and ``s_t`` (length) are robust (median-based) scales of the rotation and
translation residuals, which sets the rotation / translation weighting from the data
(override with ``rotation_weight``: length per radian). The robust version runs
iteratively reweighted Levenberg-Marquardt with Cauchy weights on the station distance
``d_i = |r_i|`` and then flags stations with ``d_i^2`` beyond the chi-square(6) quantile
``outlier_level`` as outliers; a last non-robust pass uses the inliers only.

Each pass is scipy's MINPACK Levenberg-Marquardt with the analytic Jacobian
(`residual_jacobian`, through the right Jacobian of SO(3)), checked against finite
differences in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtri
from kinecal.spatial import (
    axis_angle_from_matrix,
    invert_transform,
    matrix_from_axis_angle,
    skew,
    transform_from,
)

Array = NDArray[np.float64]

__all__ = ["LMRefinement", "camera_residuals", "flag_outliers", "lm", "residual_jacobian",
           "residuals_and_jacobian"]


@lru_cache(maxsize=1)
def _chi3_median() -> float:
    """Median of the chi distribution with 3 degrees of freedom (scale of the length of a
    3-vector of N(0, s) components, in units of s)."""
    return float(np.sqrt(chdtri(3, 0.5)))

#: Cauchy tuning constant (95 % efficiency on Gaussian data), in units of the per-dof scale.
_CAUCHY_C = 2.3849


@dataclass
class LMRefinement:
    """Result of `lm`.

    Attributes
    ----------
    X, Y : ndarray, shape (4, 4)
        Refined hand-eye transform and target pose.
    outliers : list of int
        0-based station indices flagged as outliers.
    distances : ndarray, shape (n,)
        Normalised station distances ``d_i`` (chi with 6 dof for inliers).
    scales : (float, float)
        Robust residual scales ``(s_R rad, s_t length)``.
    nfev : int
        Residual evaluations.
    history : list of float
        Weighted cost after each outer iteration.
    """

    X: Array
    Y: Array
    outliers: list[int]
    distances: Array
    scales: tuple[float, float]
    nfev: int
    history: list[float] = field(default_factory=list)


def _update(T0: Array, p: Array) -> Array:
    """``T0`` perturbed by ``p = (omega (3) rad, v (3) length)``: ``R0 Exp(omega), t0 + v``."""
    return transform_from(T0[:3, :3] @ matrix_from_axis_angle(p[:3]), T0[:3, 3] + p[3:])


def camera_residuals(G: Array, C: Array, X: Array, Y: Array, Ginv: Array | None = None
                     ) -> tuple[Array, Array]:
    """Rotation (rad, rotation vectors) and translation residuals per station.

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses.
    C : ndarray, shape (n, 4, 4)
        ``target2cam`` measurements.
    X, Y : ndarray, shape (4, 4)
        Hand-eye transform and target pose (stacks broadcast: e.g. ``(h, 1, 4, 4)``
        against ``(1, n, 4, 4)`` poses give ``(h, n, 3)`` residuals).
    Ginv : ndarray, shape (n, 4, 4), optional
        ``invert_transform(G)`` when the caller has it (repeated evaluations).

    Returns
    -------
    rot : ndarray, shape (n, 3)
        ``log(R^_i^T R_Ci)`` in rad.
    trans : ndarray, shape (n, 3)
        ``t_Ci - t^_i`` (length unit).
    """
    pred = invert_transform(X) @ (invert_transform(G) if Ginv is None else Ginv) @ Y
    rot = axis_angle_from_matrix(np.swapaxes(pred[..., :3, :3], -1, -2) @ C[..., :3, :3])
    return rot, C[..., :3, 3] - pred[..., :3, 3]


def _jr(w: Array) -> Array:
    """Right Jacobian of SO(3) at rotation vectors ``(..., 3)`` -> ``(..., 3, 3)``."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    small = th < 1e-6
    ts = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ts)) / ts**2)
    b = np.where(small, 1.0 / 6.0 - th**2 / 120.0, (ts - np.sin(ts)) / ts**3)
    K = skew(w)
    return np.eye(3) - a * K + b * (K @ K)


def _jr_inv(w: Array) -> Array:
    """Inverse right Jacobian of SO(3) at rotation vectors ``(..., 3)`` -> ``(..., 3, 3)``."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    small = th < 1e-6
    ts = np.where(small, 1.0, np.minimum(th, np.pi - 1e-6))
    c = np.where(small, 1.0 / 12.0 + th**2 / 720.0,
                 1.0 / ts**2 - (1.0 + np.cos(ts)) / (2.0 * ts * np.sin(ts)))
    K = skew(w)
    return np.eye(3) + 0.5 * K + c * (K @ K)


def residual_jacobian(G: Array, C: Array, X0: Array, Y0: Array, p: Array) -> Array:
    """Analytic Jacobian ``(n, 6, 12)`` of `camera_residuals` (unscaled) w.r.t. ``p``.

    ``p = (omega_X, v_X, omega_Y, v_Y)`` with ``X = (R_X0 Exp(omega_X), t_X0 + v_X)`` and the
    same for Y. With ``E_i = R_Y^T R_Gi R_X R_Ci`` (rotation residual ``log E_i``) and the
    right Jacobian ``J_r`` of SO(3):

    - ``d log E / d omega_X = J_r^-1(log E) R_C^T J_r(omega_X)``,
    - ``d log E / d omega_Y = -J_r^-1(log E) E^T J_r(omega_Y)``,
    - ``d t / d omega_X = -[t^]x J_r(omega_X)``, ``d t / d v_X = R_X^T``,
      ``d t / d v_Y = -R_X^T R_G^T`` for the translation residual ``t = t_C - t^``.
    """
    return residuals_and_jacobian(G, C, X0, Y0, p)[2]


def residuals_and_jacobian(G: Array, C: Array, X0: Array, Y0: Array, p: Array,
                           Ginv: Array | None = None) -> tuple[Array, Array, Array]:
    """`camera_residuals` ``(n, 3)`` twice at ``p`` and `residual_jacobian` ``(n, 6, 12)``
    there, sharing the work (`Ginv`: ``invert_transform(G)`` when the caller has it)."""
    X = _update(X0, p[:6])
    Y = _update(Y0, p[6:])
    rot, tr = camera_residuals(G, C, X, Y, Ginv)
    return rot, tr, _jacobian(G, C, X, Y, rot, tr, p)


def _jacobian(G: Array, C: Array, X: Array, Y: Array, rot: Array, tr: Array, p: Array
              ) -> Array:
    """`residual_jacobian` ``(n, 6, 12)`` at ``p`` from X, Y there and their
    `camera_residuals`."""
    pred_t = C[:, :3, 3] - tr
    RX, RY = X[:3, :3], Y[:3, :3]
    RC = C[:, :3, :3]
    E = RY.T @ G[:, :3, :3] @ RX @ RC
    Jinv = _jr_inv(rot)
    JX = _jr(p[0:3])
    n = len(G)
    J = np.zeros((n, 6, 12))
    J[:, :3, 0:3] = Jinv @ np.swapaxes(RC, 1, 2) @ JX
    J[:, :3, 6:9] = -Jinv @ np.swapaxes(E, 1, 2) @ _jr(p[6:9])
    J[:, 3:, 0:3] = -skew(pred_t) @ JX
    J[:, 3:, 3:6] = RX.T
    J[:, 3:, 9:12] = -RX.T @ np.swapaxes(G[:, :3, :3], 1, 2)
    return J


def _scales(rot: Array, trans: Array, L: float) -> tuple[float, float]:
    sr = float(np.median(np.linalg.norm(rot, axis=1))) / _chi3_median()
    st = float(np.median(np.linalg.norm(trans, axis=1))) / _chi3_median()
    return max(sr, 1e-13), max(st, 1e-13 * L)


def lm(
    G: Array,
    C: Array,
    X0: Array,
    Y0: Array,
    *,
    robust: bool = True,
    rotation_weight: float | None = None,
    outlier_level: float = 0.999,
    max_outer: int = 10,
    start_inliers: Array | None = None,
) -> LMRefinement:
    """Refine ``X`` and the target pose ``Y`` by (robust) Levenberg-Marquardt.

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (eye-in-hand ``flange2base``, eye-to-hand ``base2flange``), length L.
    C : ndarray, shape (n, 4, 4)
        ``target2cam`` poses, length L.
    X0, Y0 : ndarray, shape (4, 4)
        Starting hand-eye transform (a closed form) and target pose.
    robust : bool
        Cauchy-reweighted iterations and outlier flagging (default); False: plain
        least squares over all stations.
    rotation_weight : float, optional
        Fixed weighting, length units per radian of rotation residual (e.g. 1000 mm/rad).
        Default: the ratio of the robust residual scales ``s_t / s_R``.
    outlier_level : float
        Chi-square(6) probability beyond which a station is flagged.
    max_outer : int
        Maximum reweighting iterations.
    start_inliers : ndarray of int, optional
        Robust mode: stations trusted at the start (e.g. a consensus set of
        `ransac.consensus_start`): the first pass weighs only them, and the residual scales
        come from the stations currently weighted above 1/2 instead of all stations (which
        at 50 % outliers puts the median on the outliers).

    Returns
    -------
    LMRefinement
    """
    fit = _Passes(G, C, rotation_weight)
    X, Y, inlier = fit.reweighted(X0.copy(), Y0.copy(), robust, outlier_level, max_outer,
                                  start_inliers)
    # final plain least squares on the inliers, scales re-estimated from them (rms)
    rot, tr = camera_residuals(G[inlier], C[inlier], X, Y, fit.Ginv[inlier])
    sr = max(float(np.sqrt(np.mean(np.sum(rot**2, 1)) / 3.0)), 1e-13)
    st = max(float(np.sqrt(np.mean(np.sum(tr**2, 1)) / 3.0)), 1e-13 * fit.L)
    if rotation_weight is not None:
        sr = st / rotation_weight
    X, Y = fit.solve(X, Y, inlier.astype(float), sr, st)
    d = _distances(G, C, X, Y, sr, st, fit.Ginv)
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    return LMRefinement(X, Y, outliers, d, (sr, st), fit.nfev, fit.history)


class _Passes:
    """The weighted Levenberg-Marquardt passes of `lm` on stations (G, C)."""

    def __init__(self, G: Array, C: Array, rotation_weight: float | None) -> None:
        self.G, self.C, self.rotation_weight = G, C, rotation_weight
        self.Ginv = invert_transform(G)  # every evaluation's, computed once
        self.L = max(float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1)))), 1e-300)
        self.nfev = 0
        self.history: list[float] = []

    def solve(self, X: Array, Y: Array, w: Array, sr: float, st: float) -> tuple[Array, Array]:
        """Minimise the station residuals weighted by `w` ``(n,)`` and the scales (MINPACK's
        Levenberg-Marquardt with the analytic Jacobian)."""
        G, C, Gi = self.G, self.C, self.Ginv
        sw = np.sqrt(w)[:, None]
        scale = np.r_[[1.0 / sr] * 3, [1.0 / st] * 3]

        last: list[tuple[Array, ...]] = []  # MINPACK asks the Jacobian where it last
        # evaluated the residuals: their poses and residuals are reused there

        def fun(p: Array) -> Array:
            Xp, Yp = _update(X, p[:6]), _update(Y, p[6:])
            rot, tr = camera_residuals(G, C, Xp, Yp, Gi)
            last[:] = [(p.copy(), Xp, Yp, rot, tr)]
            return np.concatenate([sw * rot / sr, sw * tr / st], axis=1).ravel()

        def jac(p: Array) -> Array:
            if last and np.array_equal(last[0][0], p):
                J = _jacobian(G, C, *last[0][1:], p)
            else:
                J = residuals_and_jacobian(G, C, X, Y, p, Gi)[2]  # (n, 6, 12)
            return (J * (scale[None, :, None] * sw[:, :, None])).reshape(-1, 12)

        from scipy.optimize import least_squares

        sol = least_squares(fun, np.zeros(12), jac=jac, method="lm", x_scale="jac")
        self.nfev += int(sol.nfev)
        self.history.append(float(2.0 * sol.cost))
        return _update(X, sol.x[:6]), _update(Y, sol.x[6:])

    def scales(self, X: Array, Y: Array, mask: Array) -> tuple[float, float]:
        """Robust residual scales of the stations in `mask` ``(n,)``."""
        rot, tr = camera_residuals(self.G[mask], self.C[mask], X, Y, self.Ginv[mask])
        sr, st = _scales(rot, tr, self.L)
        if self.rotation_weight is not None:
            sr = st / self.rotation_weight
        return sr, st

    def reweighted(self, X: Array, Y: Array, robust: bool, outlier_level: float,
                   max_outer: int, start_inliers: Array | None
                   ) -> tuple[Array, Array, NDArray[np.bool_]]:
        """Cauchy-reweighted passes (robust) and the inlier mask ``(n,)`` they leave
        (all stations when fewer than 3 remain, or not robust)."""
        G, C = self.G, self.C
        n = len(G)
        w = np.ones(n)
        trusted = np.ones(n, bool)
        if robust and start_inliers is not None and len(start_inliers) >= 3:
            trusted = np.zeros(n, bool)
            trusted[np.asarray(start_inliers, dtype=np.intp)] = True
            w = trusted.astype(float)
        sr, st = self.scales(X, Y, trusted)
        if not robust:
            return X, Y, np.ones(n, bool)
        for _ in range(max_outer):
            X, Y = self.solve(X, Y, w, sr, st)
            sr, st = self.scales(X, Y, w > 0.5 if start_inliers is not None
                                 else np.ones(n, bool))
            d = _distances(G, C, X, Y, sr, st, self.Ginv)
            w_new = 1.0 / (1.0 + (d / (np.sqrt(6.0) * _CAUCHY_C)) ** 2)
            done = np.max(np.abs(w_new - w)) < 1e-3
            w = w_new
            if done:
                break
        d = _distances(G, C, X, Y, sr, st, self.Ginv)
        inlier = d**2 <= _chi2_isf6(1.0 - outlier_level)
        if inlier.sum() < 3:
            inlier = np.ones(n, bool)
        return X, Y, inlier


def _distances(G: Array, C: Array, X: Array, Y: Array, sr: float, st: float,
               Ginv: Array | None = None) -> Array:
    rot, tr = camera_residuals(G, C, X, Y, Ginv)
    return np.sqrt(np.sum((rot / sr) ** 2, 1) + np.sum((tr / st) ** 2, 1))


def flag_outliers(G: Array, C: Array, X: Array, Y: Array, level: float = 0.999) -> list[int]:
    """Stations whose normalised residual exceeds the chi-square(6) `level` quantile.

    Judged as `lm` judges them, from a robust refinement started at (`X`, `Y`): the
    residuals of an unrefined closed form also hold its own bias (Andreff's or
    Daniilidis' rotation, off by 0.01 deg under translation-only noise, flagged stations
    whose noise equalled the others'), which is no station's fault. Used for results that
    were not refined by `lm` (their X is kept).

    Parameters
    ----------
    G, C : ndarray, shape (n, 4, 4)
        Robot poses and ``target2cam``.
    X, Y : ndarray, shape (4, 4)
        Hand-eye transform and target pose.
    level : float
        Chi-square(6) probability.

    Returns
    -------
    list of int
        0-based station indices.
    """
    # `lm`'s robust passes decide its outliers before its last (plain) pass: stop there
    # (converged as tightly as `lm`'s: without rotation noise the rotation scale is at
    # round-off, and looser passes flag stations that `lm` does not)
    _, _, inlier = _Passes(G, C, None).reweighted(X, Y, True, level, 10, None)
    return [int(i) for i in np.flatnonzero(~inlier)]


@lru_cache(maxsize=8)
def _chi2_isf6(alpha: float) -> float:
    """The chi-square(6) quantile exceeded with probability `alpha` (cached)."""
    return float(chdtri(6, alpha))
