"""Rigid registration of measured points onto a model's: the start of a tracker station's
frame, the re-registration of a validation set measured from another set-up
(``--validate-register``), and the test that a validation set sits in another frame
(``validation-frame``).

The rigid fit is Kabsch's (W. Kabsch, "A solution for the best rotation to relate two sets
of vectors", Acta Cryst. A32, 1976): the rotation from the SVD of the cross-covariance of
the centred point sets, its sign fixed to a proper rotation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import transform_from

__all__ = ["rigid_fit", "rigid_fit_poses"]

Array = NDArray[np.float64]

#: points count as on a line when the second singular value of their spread is below this
#: fraction of the first
COLLINEAR = 1e-6


def rigid_fit(P: Array, Q: Array) -> Array:
    """The rigid transform ``X`` ``(4, 4)`` minimising ``sum_i |R p_i + t - q_i|^2``.

    Parameters
    ----------
    P, Q : ndarray, shape (N, 3)
        Corresponding points (model, measured), N >= 3 not on one line.

    Raises
    ------
    InputError
        Fewer than three points, or points on one line (the turn about it is free).
    """
    P, Q = np.asarray(P, dtype=float), np.asarray(Q, dtype=float)
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    sv = np.linalg.svd(P - cp, compute_uv=False) if len(P) >= 2 else np.zeros(1)
    if len(P) < 3 or sv[1] <= COLLINEAR * max(sv[0], 1e-300):
        raise InputError(f"{len(P)} points on one line (or fewer than three): they do not "
                         "fix a rigid frame; measure poses spread over the workspace")
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return transform_from(R, cq - R @ cp)


def rigid_fit_poses(P: Array, Q: Array, R_model: Array | None = None,
                    R_meas: Array | None = None) -> Array:
    """`rigid_fit`, and where the points alone do not fix it (one or two poses, or all on a
    line) the measured orientations do: the rotation then is the mean of ``R_meas_i
    R_model_i^T`` (projected to a rotation), the translation the mean point offset."""
    try:
        return rigid_fit(P, Q)
    except InputError:
        if R_model is None or R_meas is None:
            raise
    M = np.einsum("nij,nkj->ik", np.asarray(R_meas, float), np.asarray(R_model, float))
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    return transform_from(R, np.mean(np.asarray(Q) - np.asarray(P) @ R.T, axis=0))
