"""The identification problem of the parallel-link CMM's 42 geometry parameters.

The identification residual is the inverse kinematics (papers/004 eq. 4-5)::

    r_ji = |R_j (p_i - s) + t_j - b_i| - o_i - L_ji

with the analytic Jacobian ``dr/db_i = -n_ji``, ``dr/dp_i = R_j^T n_ji``,
``dr/do_i = -1`` (``n_ji`` the unit leg vector). Each leg's 7 parameters only touch that
leg's residuals, so the 42-column Jacobian is block-structured.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.calibration.stewart.data import StewartData
from kinecal.kinematics.stewart.platform import N_PARAMETERS, PARAMETER_NAMES, StewartPlatform
from kinecal.spatial import matrix_from_rpy

__all__ = ["identifiability", "identification_jacobian", "residuals"]

Array = NDArray[np.float64]


def residuals(geom: StewartPlatform, data: StewartData) -> Array:
    """Predicted minus measured leg readings, shape (N, 6) (length unit)."""
    return geom.inverse(data.poses) - data.legs


def identification_jacobian(geom: StewartPlatform, poses: ArrayLike) -> Array:
    """Analytic derivative of the predicted readings by the 42 parameters.

    Parameters
    ----------
    geom : StewartPlatform
    poses : array_like, shape (N, 6)
        Probe poses (length unit, rad).

    Returns
    -------
    ndarray, shape (N * 6, 42)
        Row ``6 j + i`` is reading ``i`` at pose ``j``; columns in `PARAMETER_NAMES` order.
    """
    x = np.asarray(poses, dtype=float)
    R = matrix_from_rpy(x[:, 3:])
    lv = geom.leg_vectors_from(R, x[:, :3])
    n = lv / np.linalg.norm(lv, axis=-1, keepdims=True)  # (N, 6, 3)
    npl = np.einsum("nji,nkj->nki", R, n)  # R^T n_i, (N, 6, 3)
    N = x.shape[0]
    J = np.zeros((N, 6, N_PARAMETERS))
    legs = np.arange(6)
    for a in range(3):  # loop over x, y, z: each one a vectorized scatter over poses
        J[:, legs, 3 * legs + a] = -n[:, :, a]
        J[:, legs, 18 + 3 * legs + a] = npl[:, :, a]
    J[:, legs, 36 + legs] = -1.0
    return J.reshape(N * 6, N_PARAMETERS)


def identifiability(
    geom: StewartPlatform, poses: ArrayLike, rtol: float = 1e-10
) -> dict[str, object]:
    """Rank, condition number and singular values of the 42-parameter Jacobian.

    Columns are used as they are (all parameters are lengths in the same unit).

    Returns
    -------
    dict
        ``rank``, ``n_parameters``, ``condition_number``, ``singular_values`` (42,),
        ``unidentifiable``: the parameters dropped by QR with column pivoting beyond the rank.
    """
    from scipy.linalg import qr

    J = identification_jacobian(geom, poses)
    s = np.linalg.svd(J, compute_uv=False)
    rank = int(np.sum(s > rtol * s[0]))
    _, _, piv = qr(J, mode="economic", pivoting=True)
    cond = float(s[0] / s[rank - 1]) if rank else float("inf")
    return {
        "rank": rank,
        "n_parameters": N_PARAMETERS,
        "condition_number": cond,
        "singular_values": s,
        "unidentifiable": [PARAMETER_NAMES[k] for k in piv[rank:]],
    }

