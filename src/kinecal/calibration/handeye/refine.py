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
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.noise import StationNoise
from kinecal.calibration.handeye.refine_passes import Passes
from kinecal.calibration.handeye.residuals import (  # noqa: F401 (their home before)
    _CAUCHY_C,
    _MIN_ESTIMATED,
    _chi2_isf6,
    _jacobian,
    _jr,
    _jr_inv,
    _scales,
    _update,
    camera_residuals,
    residual_jacobian,
    residuals_and_jacobian,
)

Array = NDArray[np.float64]

__all__ = ["LMRefinement", "camera_residuals", "flag_outliers", "lm", "residual_jacobian",
           "residuals_and_jacobian"]


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
    _, _, inlier, _ = Passes(G, C, None).reweighted(X, Y, True, level, 10, None)
    return [int(i) for i in np.flatnonzero(~inlier)]


