"""Closed-form solvers of ``A_i X = Z B_i`` (robot-world / hand-eye calibration).

Naming follows OpenCV's ``calibrateRobotWorldHandEye``: ``A_i = world2cam``,
``X = base2world``, ``Z = gripper2cam``, ``B_i = base2gripper``. For kinecal's inputs
(eye-in-hand) the world is the target: ``A_i = target2cam``, ``B_i = base2flange``,
``X = base2target`` and ``Z = flange2cam``, so the hand-eye transform is ``Z^-1``
(`kinecal.calibration.handeye.calibrate_handeye` does this mapping).

Unlike ``A X = X B`` these solvers use the absolute poses, not relative motions. Both
take ``A, B`` of shape ``(n, 4, 4)`` (lengths in any unit L) and return ``(X, Z)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye._motions import length_scale
from kinecal.spatial import project_to_rotation, transform_from

Array = NDArray[np.float64]

__all__ = ["li", "shah"]


def _translations(A: Array, B: Array, RX: Array, RZ: Array) -> tuple[Array, Array]:
    """Least squares ``R_A t_X - t_Z = R_Z t_B - t_A`` for ``(t_X, t_Z)`` (both ``(3,)``)."""
    n = len(A)
    M = np.concatenate([A[:, :3, :3], np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2)
    rhs = (B[:, :3, 3] @ RZ.T - A[:, :3, 3]).reshape(-1)
    sol = np.linalg.lstsq(M.reshape(-1, 6), rhs, rcond=None)[0]
    return sol[:3], sol[3:]


def _signed_rotation(v: Array) -> Array:
    """Reshape a 9-vector (row-major) into the rotation it is proportional to (det > 0)."""
    R = v.reshape(3, 3)
    det = np.linalg.det(R)
    R = R / (np.sign(det) * abs(det) ** (1.0 / 3.0))
    return project_to_rotation(R)


def shah(A: Array, B: Array) -> tuple[Array, Array]:
    """Shah (2013), "Solving the robot-world/hand-eye calibration problem using the
    Kronecker product", ASME J. Mechanisms Robotics 5(3).

    ``R_A R_X R_B^T = R_Z`` gives ``(R_A (x) R_B) vec(R_X) = vec(R_Z)`` (row-major vec).
    With ``K = sum_i R_A,i (x) R_B,i``, ``vec(R_X)`` and ``vec(R_Z)`` are the
    right and left singular vectors of the largest singular value of K, scaled so that
    ``det = +1`` and orthonormalised; the translations then follow by linear least squares
    from ``R_A t_X - t_Z = R_Z t_B - t_A``.

    Parameters
    ----------
    A, B : ndarray, shape (n, 4, 4)
        Absolute poses with ``A_i X = Z B_i`` (length unit L).

    Returns
    -------
    X, Z : ndarray, shape (4, 4)
        Translations in L.
    """
    K = np.einsum("kij,kab->iajb", A[:, :3, :3], B[:, :3, :3]).reshape(9, 9)
    U, _, Vt = np.linalg.svd(K)
    RX = _signed_rotation(Vt[0])
    RZ = _signed_rotation(U[:, 0])
    tX, tZ = _translations(A, B, RX, RZ)
    return transform_from(RX, tX), transform_from(RZ, tZ)


def li(A: Array, B: Array) -> tuple[Array, Array]:
    """Li, Wang & Wu (2010), "Simultaneous robot-world and hand-eye calibration using
    dual-quaternions and Kronecker product", Int. J. Phys. Sci. 5(10).

    The paper's Kronecker formulation: one linear system in
    ``(vec(R_X), vec(R_Z), t_X, t_Z)`` (24 unknowns),

        (R_A (x) I_3) vec(R_X) - (I_3 (x) R_B^T) vec(R_Z) = 0
        (I_3 (x) t_B^T) vec(R_Z) - R_A t_X + t_Z = t_A,

    solved by least squares, then both rotations orthonormalised. kinecal divides all
    lengths by their rms L before solving (the unknowns then have comparable scales,
    making the result independent of the length unit) and re-solves the translations with
    the orthonormal rotations.

    Parameters
    ----------
    A, B : ndarray, shape (n, 4, 4)
        Absolute poses with ``A_i X = Z B_i`` (length unit L).

    Returns
    -------
    X, Z : ndarray, shape (4, 4)
        Translations in L.
    """
    n = len(A)
    L = length_scale(A[:, :3, 3], B[:, :3, 3])
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    tA, tB = A[:, :3, 3] / L, B[:, :3, 3] / L
    I3 = np.eye(3)
    M = np.zeros((n, 12, 24))
    M[:, :9, :9] = np.einsum("kij,ab->kiajb", RA, I3).reshape(n, 9, 9)
    M[:, :9, 9:18] = -np.einsum("ij,kba->kiajb", I3, RB).reshape(n, 9, 9)
    M[:, 9:, 9:18] = np.einsum("ij,kb->kijb", I3, tB).reshape(n, 3, 9)
    M[:, 9:, 18:21] = -RA
    M[:, 9:, 21:24] = I3
    rhs = np.zeros((n, 12))
    rhs[:, 9:] = tA
    sol = np.linalg.lstsq(M.reshape(-1, 24), rhs.reshape(-1), rcond=None)[0]
    RX = _signed_rotation(sol[:9])
    RZ = _signed_rotation(sol[9:18])
    tX, tZ = _translations(A, B, RX, RZ)
    return transform_from(RX, tX), transform_from(RZ, tZ)


#: Solvers by name (OpenCV's CALIB_ROBOT_WORLD_HAND_EYE_* flags, lower case).
SOLVERS = {"shah": shah, "li": li}
