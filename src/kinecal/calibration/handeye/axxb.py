"""Closed-form solvers of ``A X = X B`` (hand-eye calibration), one function per method.

Paper 001 (``papers/001``, sec. 1 refs. [3]-[6]) uses the analytic solutions of Tsai,
Park, Horaud and Daniilidis as the starting point of its refinement; Andreff's linear
(Kronecker) formulation completes the set offered by OpenCV's ``calibrateHandEye``.

Every solver takes the motions ``A, B`` of shape ``(m, 4, 4)`` built by
`kinecal.calibration.handeye._motions.motion_pairs` (``A_k X = X B_k``, lengths in any
unit L) and returns ``X`` as a ``(4, 4)`` transform with a proper rotation. All but
`andreff` give the same X in any length unit; Andreff's joint linear system mixes
rotation entries and lengths as the paper (and OpenCV) does, see `andreff`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye._motions import (
    align_signs,
    finish,
    length_scale,
    motion_quaternions,
    qmat_left,
    qmat_right,
    solve_translation,
)
from kinecal.errors import InputError
from kinecal.spatial import (
    axis_angle_from_matrix,
    axis_angle_from_quaternion,
    matrix_from_quaternion,
    project_to_rotation,
    skew,
)

Array = NDArray[np.float64]

__all__ = ["andreff", "daniilidis", "horaud", "park", "tsai"]


def tsai(A: Array, B: Array) -> Array:
    """Tsai & Lenz (1989), "A new technique for fully autonomous and efficient 3D robotics
    hand/eye calibration", IEEE Trans. Robot. Autom. 5(3).

    Rotation: with the modified Rodrigues vectors ``P = 2 sin(theta/2) k`` of ``R_A``
    (their ``Pgij``) and ``R_B`` (``Pcij``), solve ``skew(P_A + P_B) P' = P_B - P_A`` by
    least squares, then ``P_X = 2 P' / sqrt(1 + |P'|^2)`` (the rotation step of the paper's
    two-step procedure). Translation: ``(R_A - I) t_X = R_X t_B - t_A`` (its second step).

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).

    Returns
    -------
    ndarray, shape (4, 4)
        X, translation in L.
    """
    qa, qb = motion_quaternions(A, B)
    R = _tsai_rotation(qa, qb)
    R = _tsai_rotation(qa, align_signs(qa, qb, R))
    return finish(R, solve_translation(A, B, R))


def _tsai_rotation(qa: Array, qb: Array) -> Array:
    pa, pb = 2.0 * qa[:, 1:], 2.0 * qb[:, 1:]  # P = 2 sin(theta/2) k
    M = skew(pa + pb).reshape(-1, 3)
    rhs = (pb - pa).reshape(-1)
    p1 = np.linalg.lstsq(M, rhs, rcond=None)[0]
    p = 2.0 * p1 / np.sqrt(1.0 + p1 @ p1)
    # |p| = 2 sin(theta/2): back to a unit quaternion (w, x, y, z)
    half = 0.5 * p
    w = np.sqrt(max(0.0, 1.0 - half @ half))
    return matrix_from_quaternion(np.concatenate([[w], half]))


def park(A: Array, B: Array) -> Array:
    """Park & Martin (1994), "Robot sensor calibration: solving AX = XB on the Euclidean
    group", IEEE Trans. Robot. Autom. 10(5).

    With ``alpha = log R_A`` and ``beta = log R_B`` (so ``alpha = R_X beta``), the
    least-squares rotation is ``R_X = (M^T M)^(-1/2) M^T`` with ``M = sum beta alpha^T``
    (the paper's closed-form least-squares solution). It is computed as the orthogonal polar
    factor of ``M^T`` by SVD (equal to that formula whenever ``M^T M`` is invertible, and
    still defined with only two independent axes). Motions within noise of 180 deg whose
    ``beta`` came out antipodal are flipped and the rotation solved again. Translation by
    least squares on ``(R_A - I) t_X = R_X t_B - t_A``.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).

    Returns
    -------
    ndarray, shape (4, 4)
        X, translation in L.
    """
    alpha = axis_angle_from_matrix(A[:, :3, :3])
    beta = axis_angle_from_matrix(B[:, :3, :3])
    R = _park_rotation(alpha, beta)
    # near 180 deg noise can send log R_B to the antipode (beta ~ -R_X^T alpha): flip those
    # and solve again (a kinecal addition; no effect on motions away from 180 deg)
    flip = np.sum(alpha * (beta @ R.T), axis=1) < 0
    if flip.any():
        R = _park_rotation(alpha, np.where(flip[:, None], -beta, beta))
    return finish(R, solve_translation(A, B, R))


def _park_rotation(alpha: Array, beta: Array) -> Array:
    Mt = alpha.T @ beta  # M^T = sum alpha beta^T
    U, _, Vt = np.linalg.svd(Mt)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def horaud(A: Array, B: Array) -> Array:
    """Horaud & Dornaika (1995), "Hand-eye calibration", Int. J. Robot. Res. 14(3).

    Rotation by unit quaternions: minimise ``sum |q_A * q_X - q_X * q_B|^2`` over unit
    ``q_X``, i.e. the eigenvector of the smallest eigenvalue of
    ``sum (Q(q_A) - W(q_B))^T (Q(q_A) - W(q_B))`` (the paper's linear closed form of the
    rotation). Translation by least squares on ``(R_A - I) t_X = R_X t_B - t_A``.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).

    Returns
    -------
    ndarray, shape (4, 4)
        X, translation in L.
    """
    qa, qb = motion_quaternions(A, B)
    R = _horaud_rotation(qa, qb)
    R = _horaud_rotation(qa, align_signs(qa, qb, R))
    return finish(R, solve_translation(A, B, R))


def _horaud_rotation(qa: Array, qb: Array) -> Array:
    D = qmat_left(qa) - qmat_right(qb)  # (m, 4, 4)
    S = np.einsum("kji,kjl->il", D, D)
    _, V = np.linalg.eigh(S)
    q = V[:, 0]
    return matrix_from_quaternion(q if q[0] >= 0 else -q)


def andreff(A: Array, B: Array) -> Array:
    """Andreff, Horaud & Espiau (2001), "Robot hand-eye calibration using
    structure-from-motion", Int. J. Robot. Res. 20(3) (first in 3DIM'99, "On-line
    hand-eye calibration").

    The paper's linear formulation: with the Kronecker product, ``R_A R_X = R_X R_B`` and
    the translation rows of ``A X = X B`` become one linear system in the 12 unknowns
    ``(vec R_X, t_X)`` (row-major vec, ``vec(R_A R_X R_B^T) = (R_A (x) R_B) vec R_X``),

        [ I_9 - R_A (x) R_B      0_9x3   ] [vec R_X]   [ 0_9 ]
        [ I_3 (x) t_B^T        I_3 - R_A ] [  t_X  ] = [ t_A ]      (one block per motion),

    solved jointly by linear least squares (minimum-norm solution); ``R_X`` is then scaled to
    ``det = +1`` and projected on SO(3) (the paper's orthogonalisation) and ``t_X`` is the
    one of the joint solution. This is also what OpenCV's ANDREFF computes.

    Because rotation entries (unit-free) and lengths share one least-squares system, the
    result depends on the length unit: in millimetres the translation rows dominate and,
    with noise, the rotation is typically 2-5 times less accurate than Park's (see
    docs/handeye.md). Noise-free data are solved exactly in any unit.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).

    Returns
    -------
    ndarray, shape (4, 4)
        X, translation in L.
    """
    m = len(A)
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    M = np.zeros((m, 12, 12))
    M[:, :9, :9] = np.eye(9) - np.einsum("kij,kab->kiajb", RA, RB).reshape(m, 9, 9)
    M[:, 9:, :9] = np.einsum("ij,kb->kijb", np.eye(3), B[:, :3, 3]).reshape(m, 3, 9)
    M[:, 9:, 9:] = np.eye(3) - RA
    rhs = np.zeros((m, 12))
    rhs[:, 9:] = A[:, :3, 3]
    x = np.linalg.lstsq(M.reshape(-1, 12), rhs.reshape(-1), rcond=None)[0]
    Rv = x[:9].reshape(3, 3)
    det = np.linalg.det(Rv)
    if not np.isfinite(det) or abs(det) < 1e-12:
        raise InputError("andreff: the linear system gives a singular rotation block; the "
                         "motions do not determine X (expected rotations about >= 2 axes)")
    Rv = Rv / (np.sign(det) * abs(det) ** (1.0 / 3.0))  # eq. (15): det = +1
    return finish(Rv, x[9:])


def daniilidis(A: Array, B: Array) -> Array:
    """Daniilidis (1999), "Hand-eye calibration using dual quaternions", Int. J. Robot.
    Res. 18(3).

    Each motion is a unit dual quaternion ``a = q + eps q'`` with ``q' = 1/2 t q``. The
    screw congruence theorem (sec. 4) makes the scalar parts of ``a x = x b`` redundant, so
    each motion gives the six rows of the paper's matrix S (eq. (31)),

        [ a - b     [a + b]x     0         0       ] (q  )
        [ a' - b'   [a' + b']x   a - b     [a + b]x ] (q' ) = 0     (vector parts a, b, a', b'),

    stacked into T (6m x 8, eq. (33)). Its two right singular vectors ``v7, v8`` of smallest
    singular value span the solution; ``x = lambda1 v7 + lambda2 v8`` with the constraints
    ``q^T q = 1`` and ``q^T q' = 0`` gives the quadratic in ``s = lambda1 / lambda2``
    (eq. (35)) whose root with the larger ``s^2 u1^T u1 + 2 s u1^T u2 + u2^T u2`` is taken
    (the paper's choice); rotation and translation come out together.

    The paper leaves the unit of length free, and the SVD weighs the rotation rows (size
    ``sin(theta/2)``) against the translation rows (size ``|t| / 2`` in that unit). kinecal
    measures lengths in the motions' own length per radian, ``L = rms|t| / rms(2
    sin(theta/2))`` over all motions of A and B, so that both kinds of rows carry equal
    weight: in raw millimetres, or in units of the rms translation, consecutive small
    motions of a continuous trajectory let the translation rows swamp the rotation rows
    and the answer goes off by tens of degrees (Tabb & Ahmad Yousef dataset 1, consecutive
    pairs: 36 deg / 51 m with the rms unit, 0.8 deg / 31 mm with L).

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).

    Returns
    -------
    ndarray, shape (4, 4)
        X, translation in L.
    """
    qa, qb = motion_quaternions(A, B)
    L = _length_per_radian(A, B, qa, qb)
    R = _horaud_rotation(qa, qb)  # Horaud's rotation (as `horaud`) for the signs
    R = project_to_rotation(_horaud_rotation(qa, align_signs(qa, qb, R)))
    qb = align_signs(qa, qb, R)  # a0 = b0 needs matching signs
    ta = np.concatenate([np.zeros((len(A), 1)), A[:, :3, 3] / L], axis=1)
    tb = np.concatenate([np.zeros((len(B), 1)), B[:, :3, 3] / L], axis=1)
    da = 0.5 * np.einsum("kij,kj->ki", qmat_left(ta), qa)  # q' = 1/2 t q
    db = 0.5 * np.einsum("kij,kj->ki", qmat_left(tb), qb)
    # rows of a x - x b (Hamilton products, w first); rows 1-3 of each block are the
    # vector parts, i.e. the paper's S of eq. (31) up to row and column order
    D0 = qmat_left(qa) - qmat_right(qb)
    D1 = qmat_left(da) - qmat_right(db)
    S = np.zeros((len(A), 6, 8))
    S[:, :3, :4] = D0[:, 1:]
    S[:, 3:, :4] = D1[:, 1:]
    S[:, 3:, 4:] = D0[:, 1:]
    _, _, Vt = np.linalg.svd(S.reshape(-1, 8), full_matrices=False)
    v7, v8 = Vt[6], Vt[7]
    u1, w1, u2, w2 = v7[:4], v7[4:], v8[:4], v8[4:]
    # eq. (35): s^2 u1.w1 + s (u1.w2 + u2.w1) + u2.w2 = 0 with s = lambda1 / lambda2
    a, b, c = u1 @ w1, u1 @ w2 + u2 @ w1, u2 @ w2
    if abs(a) > 1e-12:
        disc = np.sqrt(max(b * b - 4 * a * c, 0.0))
        roots = [(-b + disc) / (2 * a), (-b - disc) / (2 * a)]
        vals = [s * s * (u1 @ u1) + 2 * s * (u1 @ u2) + u2 @ u2 for s in roots]
        k = int(np.argmax(vals))
        l2 = 1.0 / np.sqrt(max(vals[k], 1e-300))
        x = roots[k] * l2 * v7 + l2 * v8
    else:  # lambda2 = 0 root (the quadratic degenerates): x along v7
        x = v7 / np.linalg.norm(u1)
    q, dq = x[:4], x[4:]
    if q[0] < 0:
        q, dq = -q, -dq
    n = np.linalg.norm(q)
    q, dq = q / n, dq / n
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    t = 2.0 * (qmat_left(dq) @ conj)[1:] * L  # t = 2 q' q*
    return finish(matrix_from_quaternion(q), t)


def _length_per_radian(A: Array, B: Array, qa: Array | None = None,
                       qb: Array | None = None) -> float:
    """``rms|t| / rms(2 sin(theta/2))`` over the motions of A and B (see `daniilidis`),
    the angles from their quaternions ``qa, qb`` ``(m, 4)`` (computed when not given)."""
    if qa is None or qb is None:
        qa, qb = motion_quaternions(A, B)
    t = np.concatenate([A[:, :3, 3], B[:, :3, 3]])
    theta = np.linalg.norm(axis_angle_from_quaternion(np.concatenate([qa, qb])), axis=-1)
    rot = float(np.sqrt(np.mean(4.0 * np.sin(0.5 * theta) ** 2)))
    L = length_scale(t) / rot if rot > 0 else length_scale(t)
    return L if np.isfinite(L) and L > 0 else 1.0


#: Solvers by name (the names of OpenCV's CALIB_HAND_EYE_* flags, lower case).
SOLVERS = {
    "tsai": tsai,
    "park": park,
    "horaud": horaud,
    "andreff": andreff,
    "daniilidis": daniilidis,
}

