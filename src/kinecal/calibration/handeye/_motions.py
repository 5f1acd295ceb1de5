"""Relative motions, quaternion algebra and the checks shared by the hand-eye solvers.

Conventions (docs/handeye.md): ``G_i`` is the pose of the moving part in the fixed frame
the robot reports (eye-in-hand: ``flange2base``; eye-to-hand: ``base2flange``), ``C_i`` is
``target2cam``. The unknown ``X`` satisfies ``G_i X C_i = Y`` for a constant ``Y``
(paper 001, sec. 2, eq. (1): T6 Tm Tc = Tg), hence for any two stations i, j

    A X = X B,   A = G_j^-1 G_i,   B = C_j C_i^-1     (paper 001, eqs. (2)-(3)).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import (
    invert_transform,
    project_to_rotation,
    quaternion_from_matrix,
    transform_from,
)

Array = NDArray[np.float64]

__all__ = [
    "check_motions",
    "degenerate_motions",
    "finish",
    "length_scale",
    "motion_pairs",
    "qmat_left",
    "qmat_right",
    "solve_translation",
]

#: Rotation angles below this (rad) carry no information about the rotation axis.
MIN_ANGLE = 1e-6


def pair_indices(n: int, pairs: str) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Station index pairs ``(i, j)``: ``"all"`` i < j (OpenCV), ``"consecutive"`` (j = i + 1).

    The arrays are cached per ``(n, pairs)`` and read-only."""
    if pairs not in ("all", "consecutive"):
        raise InputError(f"unknown pairs {pairs!r}; expected 'all' or 'consecutive'",
                         option="pairs")
    return _pair_indices(int(n), pairs)


@lru_cache(maxsize=64)
def _pair_indices(n: int, pairs: str) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    if pairs == "all":
        i, j = np.triu_indices(n, k=1)
    else:
        i = np.arange(n - 1)
        j = i + 1
    i.flags.writeable = False
    j.flags.writeable = False
    return i, j


def motion_pairs(G: Array, C: Array, pairs: str = "all") -> tuple[Array, Array]:
    """Relative motions ``A = G_j^-1 G_i`` and ``B = C_j C_i^-1`` (paper 001, eq. (2)-(3)).

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (eye-in-hand ``flange2base``; eye-to-hand ``base2flange``), length unit L.
    C : ndarray, shape (n, 4, 4)
        ``target2cam`` poses, length unit L.
    pairs : {"all", "consecutive"}
        Every pair i < j (as OpenCV's solvers) or consecutive stations only (as the paper).

    Returns
    -------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A X = X B``.
    """
    i, j = pair_indices(G.shape[0], pairs)
    A = invert_transform(G)[j] @ G[i]  # each pose inverted once, not once per pair
    B = C[j] @ invert_transform(C)[i]
    return A, B


def check_motions(A: Array, what: str = "robot motions") -> None:
    """Raise `InputError` unless the motions contain two non-parallel rotation axes.

    All rotations turn about one axis k exactly when k is a common null vector of every
    ``R_k - I``, i.e. when the 3 x 3 matrix ``M = sum (R_k - I)^T (R_k - I)
    = sum (2 I - R_k - R_k^T)`` is singular; pure translations make ``M = 0``.

    Parameters
    ----------
    A : ndarray, shape (m, 4, 4)
        Relative motions.
    what : str
        Name used in the message.
    """
    lam = motion_spectrum(A[None, :, :3, :3])[0]
    if lam[-1] <= A.shape[0] * MIN_ANGLE**2:
        raise InputError(
            f"degenerate {what}: pure translations (no rotation between stations); the "
            "hand-eye rotation is unobservable, expected rotations about >= 2 non-parallel axes"
        )
    if lam[0] <= 1e-12 * lam[-1]:
        raise InputError(
            f"degenerate {what}: all rotations are about one axis; expected rotations about "
            ">= 2 non-parallel axes (the translation along that axis is unobservable)"
        )


def motion_spectrum(R: Array) -> Array:
    """Eigenvalues ``(..., 3)`` (ascending) of ``sum_k (2 I - R_k - R_k^T)`` for stacks of
    rotations ``(..., m, 3, 3)`` (see `check_motions`)."""
    S = R.sum(axis=-3)
    M = 2.0 * R.shape[-3] * np.eye(3) - (S + np.swapaxes(S, -1, -2))
    return np.linalg.eigvalsh(M)


def degenerate_motions(R: Array) -> NDArray[np.bool_]:
    """`check_motions`'s test for stacks ``(..., m, 3, 3)``: True where the rotations do not
    turn about two non-parallel axes."""
    lam = motion_spectrum(R)
    return (lam[..., -1] <= R.shape[-3] * MIN_ANGLE**2) | (lam[..., 0] <= 1e-12 * lam[..., -1])


def length_scale(*translations: Array) -> float:
    """Characteristic length (rms norm) of stacks of translations ``(m, 3)``; 1 if all zero."""
    t = np.concatenate([np.asarray(x, dtype=float).reshape(-1, 3) for x in translations])
    s = float(np.sqrt(np.mean(np.sum(t * t, axis=1)))) if t.size else 0.0
    return s if s > 0 and np.isfinite(s) else 1.0


def solve_translation(A: Array, B: Array, R_X: Array) -> Array:
    """Least-squares ``t_X`` from ``(R_A - I) t_X = R_X t_B - t_A`` stacked over motions.

    This is the translation step shared by Tsai & Lenz (1989), Park & Martin (1994) and
    Horaud & Dornaika (1995): the translation rows of ``A X = X B`` once ``R_X`` is known.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions.
    R_X : ndarray, shape (3, 3)
        Hand-eye rotation.

    Returns
    -------
    ndarray, shape (3,)
        Translation of X (length unit of the inputs).
    """
    M = (A[:, :3, :3] - np.eye(3)).reshape(-1, 3)
    rhs = (B[:, :3, 3] @ R_X.T - A[:, :3, 3]).reshape(-1)
    return np.linalg.lstsq(M, rhs, rcond=None)[0]


def finish(R: Array, t: Array) -> Array:
    """4x4 transform from a (projected) rotation ``(3, 3)`` and a translation ``(3,)``."""
    return transform_from(project_to_rotation(R), t)


def qmat_left(q: Array) -> Array:
    """Matrices ``(..., 4, 4)`` with ``qmat_left(p) @ q == p * q`` (Hamilton product, w first)."""
    return np.multiply(np.asarray(q, dtype=float)[..., _QMAT_INDEX], _QMAT_LEFT_SIGN,
                       order="C")


def qmat_right(q: Array) -> Array:
    """Matrices ``(..., 4, 4)`` with ``qmat_right(p) @ q == q * p`` (Hamilton product, w first)."""
    return np.multiply(np.asarray(q, dtype=float)[..., _QMAT_INDEX], _QMAT_RIGHT_SIGN,
                       order="C")


# entry (r, c) of both product matrices is +-q[_QMAT_INDEX[r, c]]: left rows (w, -x, -y, -z),
# (x, w, -z, y), (y, z, w, -x), (z, -y, x, w); right rows (w, -x, -y, -z), (x, w, z, -y),
# (y, -z, w, x), (z, y, -x, w)
_QMAT_INDEX = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_QMAT_LEFT_SIGN = np.array([[1.0, -1.0, -1.0, -1.0], [1.0, 1.0, -1.0, 1.0],
                            [1.0, 1.0, 1.0, -1.0], [1.0, -1.0, 1.0, 1.0]])
_QMAT_RIGHT_SIGN = np.array([[1.0, -1.0, -1.0, -1.0], [1.0, 1.0, 1.0, -1.0],
                             [1.0, -1.0, 1.0, 1.0], [1.0, 1.0, -1.0, 1.0]])


def motion_quaternions(A: Array, B: Array) -> tuple[Array, Array]:
    """Unit quaternions ``(m, 4)`` (w, x, y, z) of the rotations of A and B, both ``w >= 0``.

    ``R_A = R_X R_B R_X^T`` implies equal scalar parts, so taking ``w >= 0`` for both makes
    the signs consistent (only motions of exactly 180 deg stay ambiguous).
    """
    return quaternion_from_matrix(A[:, :3, :3]), quaternion_from_matrix(B[:, :3, :3])


def as_transforms(T: Array, name: str) -> Array:
    """Validate a stack of poses ``(n, 4, 4)`` (n >= 3) and return it as float."""
    from kinecal.spatial import check_transform

    T = np.asarray(T, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"{name}: expected shape (n, 4, 4), got {T.shape}")
    check_transform(T, tol=1e-5, name=name)
    return T


def align_signs(qa: Array, qb: Array, R: Array) -> Array:
    """Flip quaternions ``q_B`` ``(m, 4)`` so that ``q_A ~ q_X q_B q_X^*`` for rotation R.

    Near 180 deg the scalar parts are close to zero and the ``w >= 0`` convention of
    `motion_quaternions` can give ``q_A`` and ``q_B`` opposite signs because of noise;
    the quaternion methods (Tsai's modified Rodrigues vectors, Horaud, Daniilidis) then
    see an equation with the wrong sign. With a first estimate R of ``R_X`` the sign of
    each ``q_B`` is chosen to agree with ``q_A`` (a kinecal addition; noise-free data and
    motions below 180 deg are not affected).
    """
    pred_v = qb[:, 1:] @ R.T
    dot = qa[:, 0] * qb[:, 0] + np.sum(qa[:, 1:] * pred_v, axis=1)
    return np.where((dot < 0)[:, None], -qb, qb)
