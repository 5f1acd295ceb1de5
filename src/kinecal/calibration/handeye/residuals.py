"""Residuals of a hand-eye station and their analytic Jacobian, shared by the refinement
(`kinecal.calibration.handeye.refine`), its passes (`refine_passes`) and the noise model
(`noise`): the camera-frame residual of ``G_i X C_i = Y``, the right Jacobian of SO(3) and
its inverse, the robust scales and the chi-square quantiles the outlier tests use.
"""

from __future__ import annotations

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

__all__ = ["camera_residuals", "residual_jacobian", "residuals_and_jacobian"]


@lru_cache(maxsize=1)
def _chi3_median() -> float:
    """Median of the chi distribution with 3 degrees of freedom (scale of the length of a
    3-vector of N(0, s) components, in units of s)."""
    return float(np.sqrt(chdtri(3, 0.5)))

#: Cauchy tuning constant (95 % efficiency on Gaussian data), in units of the per-dof scale.
_CAUCHY_C = 2.3849
#: stations from which the three noise components are estimated (fewer: two robust scales)
_MIN_ESTIMATED = 6


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


@lru_cache(maxsize=8)
def _chi2_isf6(alpha: float) -> float:
    """The chi-square(6) quantile exceeded with probability `alpha` (cached)."""
    return float(chdtri(6, alpha))
