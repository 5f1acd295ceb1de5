"""The covariance of the reprojection refinement's shared unknowns (X, the board pose, the
intrinsics) from the normal matrix of its final pass, with the robot-pose corrections
eliminated by their Schur complement (`covariance`); and one that is honest when the pass
itself is not (`station_aware_covariance`):

- stations that disagree beyond the pixel noise (the robot-pose noise estimated from the
  station consistency, `kinecal.calibration.handeye.robot_noise`, is significant) but were
  not given corrections (the estimate is no robot's noise: a wrong set-up, a bad
  recording): every corner of a station shares its station's error, so the corners'
  covariance ``s^2 (J^T J)^-1`` counts a thousand corners where fifteen stations decide
  (industrial_calibration's 15 real views: X's stated sigma 0.7-2.2 mm, while other
  intrinsics moved it 24 mm). The covariance is then that of the model with a correction
  per station of the estimated size, the corners at the pixel noise;
- intrinsics estimated from the same views and held: their uncertainty is in X's, through
  the joint normal matrix with the intrinsics' columns.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.bundle import normal_equations
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    parameter_names,
    predict_blocks,
    unpack,
)

Array = NDArray[np.float64]

__all__ = ["covariance", "station_aware_covariance"]


def covariance(A: Array, s2: float, row: Array | None, g: int) -> tuple[Array, Array | None]:
    """``s2 A^-1`` for the shared unknowns ``(g, g)`` and the standard deviations ``(n, 6)``
    of the robot-pose corrections (None without them), from the normal matrix ``A = J^T J``
    ``(p, p)`` with the corrections eliminated by their Schur complement (no dense inverse
    of the whole matrix); restricted to ``row . p = 0`` when a row is given (a constrained
    direction of the shared unknowns that J does not see)."""
    n = (A.shape[0] - g) // 6
    try:
        if n:
            idx = g + 6 * np.arange(n)[:, None] + np.arange(6)
            Ei = np.linalg.inv(A[idx[:, :, None], idx[:, None, :]])  # (n, 6, 6)
            Fs = A[:g, g:].reshape(g, n, 6).transpose(1, 0, 2)  # (n, g, 6)
            EiFt = Ei @ np.swapaxes(Fs, 1, 2)  # (n, 6, g)
            S = A[:g, :g] - np.einsum("sgi,sih->gh", Fs, EiFt)
        else:
            S = A
        if row is None:
            Sg = np.linalg.inv(S)
        else:
            N = np.linalg.svd(row[:g].reshape(1, -1))[2][1:].T
            Sg = N @ np.linalg.inv(N.T @ S @ N) @ N.T
    except np.linalg.LinAlgError:
        return np.full((g, g), np.inf), None if not n else np.full((n, 6), np.inf)
    if not n:
        return s2 * Sg, None
    # diagonal blocks of the inverse: E^-1 + E^-1 F^T S^-1 F E^-1
    dE = np.einsum("sig,gh,sih->si", EiFt, Sg, EiFt) + np.diagonal(Ei, axis1=1, axis2=2)
    return s2 * Sg, np.sqrt(np.clip(s2 * dE, 0.0, None))


def station_aware_covariance(pr: ReprojectionProblem, p: Array, inlier: NDArray[np.bool_],
                             sigma: float, noise: Any, row: Array | None, n_int: int
                             ) -> tuple[Array, list[str]] | None:
    """The covariance and names of the shared unknowns at the solution `p` (module
    docstring), or None when the final pass's is right (robot corrections modelled or not
    needed, and no held intrinsics from these views: `n_int` 0 or already free).

    Parameters
    ----------
    pr : ReprojectionProblem
    p : ndarray
        The solution.
    inlier : ndarray of bool, shape (n,)
    sigma : float
        Corner noise (px per axis).
    noise : RobotNoise
        The robot-pose noise estimate.
    row : ndarray or None
        A constraint row of the shared unknowns (one-axis robots).
    n_int : int
        Intrinsics estimated from these views (9 or 12), 0 otherwise.
    """
    from kinecal.calibration.handeye.robot_noise import SIGNIFICANCE

    station_level = (pr.robot is None and noise is not None and noise.statistic is not None
                     and noise.statistic > SIGNIFICANCE and noise.rotation > 0
                     and noise.translation > 0)
    n_int = max(n_int, pr.n_int)
    if not station_level and n_int == pr.n_int:
        return None
    X, Y, K, d, _ = unpack(pr, p)
    keep = np.flatnonzero(inlier)
    counts = np.bincount(pr.sid, minlength=pr.n)[keep]
    take = inlier[pr.sid]
    robot = (noise.rotation, noise.translation) if station_level else pr.robot
    sub = ReprojectionProblem(pr.F[keep], pr.P[take], pr.uv[take],
                              np.repeat(np.arange(len(keep)), counts).astype(np.intp),
                              pr.eye_in_hand, K, d, X, Y, n_int, robot, strict=False)
    q = np.zeros(sub.n_params)
    if pr.robot is not None:  # keep the fit's corrections where they are
        q[12 + n_int:] = p[12 + pr.n_int:].reshape(pr.n, 6)[keep].ravel()
    _, Jg, Je = predict_blocks(sub, q)
    if not (np.isfinite(Jg).all() and (Je is None or np.isfinite(Je).all())):
        return None
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
    w = np.ones((len(Jg), 2))
    prior = None
    if robot is not None:
        dpr = np.r_[[1.0 / robot[0]] * 3, [1.0 / robot[1]] * 3]
        prior = (np.broadcast_to(dpr, (len(keep), 6)), np.ones((len(keep), 6)),
                 np.zeros((len(keep), 6)))
    A, _ = normal_equations(Jg / sigma, None if Je is None else Je / sigma, w,
                            np.zeros((len(Jg), 2)), starts, prior)
    g = 12 + n_int
    cov, _ = covariance(A, 1.0, None if row is None else np.r_[row[:12], np.zeros(g - 12)], g)
    return cov, parameter_names(sub)[:g]
