"""Levenberg-Marquardt refinement of a hand-eye solution on the absolute-pose cost.

Beyond paper 001 (which refines ``A X = X B`` with metaheuristics, see `refine_meta`):
the target pose ``Y`` is estimated jointly with ``X`` from ``G_i X C_i = Y`` (paper 001,
sec. 2, eq. (1)), which uses every station once instead of station pairs, so no
measurement enters many pairs with correlated errors.

Residual of station i (in the camera frame, where the largest noise enters): with the
predicted ``C^_i = X^-1 G_i^-1 Y``,

    r_i = ( log(R^_i^T R_Ci) ,  t_Ci - t^_i )      (6 numbers)

whitened by the station's noise covariance ``Sigma_i`` (`kinecal.calibration.handeye.noise`:
the camera's rotation, the translation, and the robot's rotation, whose lever from the
flange to the target couples the residual's rotation and translation). The components are
estimated from the residuals (REML) on the stations weighted above 1/2, so the rotation /
translation weighting and the robot's share come from the data; ``rotation_weight``
(length per radian) fixes a diagonal weighting instead, and below 6 stations two robust
(median-based) scales are used. The robust version runs iteratively reweighted
Levenberg-Marquardt with Cauchy weights on the whitened station distance ``d_i =
|L_i^-1 r_i|`` (median-based scales in the first pass) and then flags stations with
``d_i^2`` beyond the chi-square(6) quantile ``outlier_level`` as outliers; a last
non-robust pass uses the inliers only, with the noise re-estimated on them.

Each pass is scipy's MINPACK Levenberg-Marquardt with the analytic Jacobian
(`residual_jacobian`, through the right Jacobian of SO(3)), checked against finite
differences in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

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
#: stations from which the three noise components are estimated (fewer: two robust scales)
_MIN_ESTIMATED = 6


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
    noise : StationNoise or None
        The stations' noise model the final pass weighed them by
        (`kinecal.calibration.handeye.noise`).
    """

    X: Array
    Y: Array
    outliers: list[int]
    distances: Array
    scales: tuple[float, float]
    nfev: int
    history: list[float] = field(default_factory=list)
    noise: Any = None


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
    eye_in_hand: bool = True,
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
        Fixed weighting, length units per radian of rotation residual (e.g. 1000 mm/rad),
        and no robot component. Default: the station noise estimated from the residuals
        (`kinecal.calibration.handeye.noise`: the camera's rotation, the translation and
        the robot's rotation with its lever).
    outlier_level : float
        Chi-square(6) probability beyond which a station is flagged.
    max_outer : int
        Maximum reweighting iterations.
    start_inliers : ndarray of int, optional
        Robust mode: stations trusted at the start (e.g. a consensus set of
        `ransac.consensus_start`): the first pass weighs only them, and the residual scales
        come from the stations currently weighted above 1/2 instead of all stations (which
        at 50 % outliers puts the median on the outliers).
    eye_in_hand : bool
        The set-up (where a flange rotation swings the target from: the robot component).

    Returns
    -------
    LMRefinement
    """
    from kinecal.calibration.handeye.refine_passes import Passes

    fit = Passes(G, C, rotation_weight, eye_in_hand)
    X, Y, inlier, theta = fit.reweighted(X0.copy(), Y0.copy(), robust, outlier_level,
                                         max_outer, start_inliers)
    # final least squares on the inliers, the noise estimated from them
    for _ in range(2 if fit.estimates else 1):
        theta = fit.noise(X, Y, inlier, theta, final=True)
        X, Y = fit.solve(X, Y, inlier.astype(float), fit.whitening(X, Y, theta))
    rot, tr = camera_residuals(G[inlier], C[inlier], X, Y, fit.Ginv[inlier])
    sr = max(float(np.sqrt(np.mean(np.sum(rot**2, 1)) / 3.0)), 1e-13)
    st = max(float(np.sqrt(np.mean(np.sum(tr**2, 1)) / 3.0)), 1e-13 * fit.L)
    if rotation_weight is not None:
        sr = st / rotation_weight
    d = fit.distances(X, Y, theta)
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    from kinecal.calibration.handeye.noise import StationNoise

    return LMRefinement(X, Y, outliers, d, (sr, st), fit.nfev, fit.history,
                        StationNoise(theta, fit.source))


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
    from kinecal.calibration.handeye.refine_passes import Passes

    _, _, inlier, _ = Passes(G, C, None).reweighted(X, Y, True, level, 10, None)
    return [int(i) for i in np.flatnonzero(~inlier)]


@lru_cache(maxsize=8)
def _chi2_isf6(alpha: float) -> float:
    """The chi-square(6) quantile exceeded with probability `alpha` (cached)."""
    return float(chdtri(6, alpha))
