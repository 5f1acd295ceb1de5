"""Row weights from a tracker file's per-axis standard deviations (``sx, sy, sz`` and
``srx, sry, srz``; `kinecal.io.tracker_columns`).

An instrument's standard deviations describe its own noise, not what the model cannot
explain: on a real arm the unmodelled error (0.3-0.5 mm on a UR10) dwarfs a laser
tracker's 0.003-0.07 mm, and weighting rows by ``1 / s^2`` alone lets the quietest rows
pull the fit (held-out error 0.476 mm against 0.445 mm unweighted on the UR10 of
ipa-robot-accuracy, series B in halves; 0.445 mm with ``tau`` estimated, 0.25 mm). Each row
is therefore weighted by

``w_ik = c / (s_ik^2 + tau_k^2)``

with ``s_ik`` the standard deviation of row k of pose i (the position rows in the length
unit; the rotation rows about the measurement frame's axes in rad), ``tau_k`` the
unmodelled error of its kind (one for the positions, one for the rotations:
`Measurements.sigma_floor`), and ``c`` making the mean position weight 1. A rotation row,
computed as ``L * log(R R_m^T)`` (``L``: the rotation weight, length per rad), gets
``w / L^2``: its weight follows from the standard deviations, not from ``L``. The pose's
``weight`` column multiplies it.

``tau`` is estimated from the fit without these weights (`estimate_floor`): ``tau^2 =
RSS / (m - k) - mean(s^2)`` over the rows of its kind (``k`` the free parameters in
proportion to the rows), at least 0 (`kinecal.calibration.serial.api.calibrate` runs the
two fits).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.data import Measurements

__all__ = ["estimate_floor", "row_sqrt_weights", "sigma_row_scale"]

Array = NDArray[np.float64]

#: relative floor of a variance (a zero standard deviation and a zero floor: a finite weight)
_TINY = 1e-30


def sigma_row_scale(data: Measurements, rotation_weight: float) -> Array | None:
    """``sqrt(w_ik)`` ``(N, rows)`` of the module docstring (without the pose weights), or
    None when `data` has no standard deviations or no estimated floor yet."""
    if data.sigma is None or data.sigma_floor is None:
        return None
    s = np.asarray(data.sigma, dtype=float)
    tau = np.asarray(data.sigma_floor, dtype=float)
    var = np.square(s)
    var[:, :3] += tau[0] ** 2
    if s.shape[1] == 6:
        var[:, 3:] += tau[1] ** 2
    var = np.maximum(var, _TINY * max(float(var.max(initial=0.0)), 1.0))
    w = 1.0 / var
    w /= float(np.mean(w[:, :3]))
    if s.shape[1] == 6:
        w[:, 3:] /= max(float(rotation_weight), 1e-300) ** 2
    return np.sqrt(w)


def row_sqrt_weights(data: Measurements, rows: int, rotation_weight: float) -> Array | None:
    """The square roots of every residual row's weight ``(N, rows)``: the pose weights
    (``weight`` column) times `sigma_row_scale`; None when all are 1."""
    scale = sigma_row_scale(data, rotation_weight)
    pose = None if data.weights is None else np.sqrt(np.asarray(data.weights, dtype=float))
    if scale is None and pose is None:
        return None
    out = np.ones((len(data), rows)) if scale is None else scale[:, :rows].copy()
    if pose is not None:
        out *= pose[:, None]
    return out


def estimate_floor(errors: Array, rotation_errors: Array | None, sigma: Array,
                   n_free: int) -> Array:
    """``tau`` ``(2,)`` (length unit, rad) from the residuals of the unweighted fit.

    Parameters
    ----------
    errors : ndarray, shape (N, 3)
        Position errors (length unit).
    rotation_errors : ndarray, shape (N, 3) or None
        Rotation error vectors (rad).
    sigma : ndarray, shape (N, 3) or (N, 6)
        The rows' standard deviations.
    n_free : int
        Free parameters of that fit (shared by the row kinds in proportion to their rows).
    """
    parts = [(np.asarray(errors, float), np.asarray(sigma, float)[:, :3])]
    if rotation_errors is not None and np.shape(sigma)[1] == 6:
        parts.append((np.asarray(rotation_errors, float), np.asarray(sigma, float)[:, 3:]))
    m_all = sum(e.size for e, _ in parts)
    tau = np.zeros(2)
    for k, (e, s) in enumerate(parts):
        dof = max(e.size - n_free * e.size / m_all, 1.0)
        tau[k] = np.sqrt(max(float(np.sum(e * e)) / dof - float(np.mean(s * s)), 0.0))
    return tau
