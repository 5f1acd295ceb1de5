"""Square-root factors of ``J^T J`` built block by block, without holding ``J``.

A tall least-squares matrix ``J`` (rows: measured coordinates, columns: parameters) is
known to everything downstream only through its Gram matrix ``J^T J``: the pivoting
decisions and diagonal of a column-pivoted QR, the singular values, least-squares
coefficients between columns and the covariance all depend on ``J`` only through
``J^T J``, because ``J = Q R`` with ``Q`` orthonormal. Any ``B`` with ``B^T B = J^T J``
(``R`` itself, or a root of the Gram matrix) therefore stands in for ``J``:

* `qr_update` folds one row block into an R factor (TSQR: the QR factorisation of the
  stacked R factors; Demmel, Grigori, Hoemmen, Langou 2012, "Communication-optimal
  parallel and sequential QR and LU factorizations", SIAM J. Sci. Comput. 34(1)). Exact to
  round-off however ill-conditioned ``J`` is.
* `gram_root` is a symmetric square root of an accumulated Gram matrix; it loses the
  directions below ``sqrt(eps)`` of the largest singular value, which is harmless for
  decisions at a relative threshold of 1e-4 and for well-conditioned sets.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["gram_root", "qr_update"]

Array = NDArray[np.float64]


def qr_update(R: Array | None, block: Array) -> Array:
    """R factor of ``[R; block]``: fold a row block into a running TSQR factor.

    Parameters
    ----------
    R : ndarray, shape (k, k), or None
        Current factor (None before the first block).
    block : ndarray, shape (m, k)
        Next rows (any memory layout; Fortran order avoids a copy).

    Returns
    -------
    ndarray, shape (k, k)
        Upper-triangular ``R'`` with ``R'^T R' = R^T R + block^T block``.
    """
    k = block.shape[1]
    top = 0 if R is None else R.shape[0]
    stacked = np.empty((top + block.shape[0], k), order="F")
    if R is not None:
        stacked[:top] = R
    stacked[top:] = block
    if stacked.shape[0] == 0:
        return np.zeros((k, k))
    from scipy.linalg import lapack  # on first use: scipy.linalg costs 0.1 s to import

    qr, _, _, info = lapack.dgeqrf(stacked, lwork=max(64 * k, 1), overwrite_a=1)
    if info != 0:  # pragma: no cover - LAPACK argument error
        raise RuntimeError(f"dgeqrf failed (info {info})")
    out = np.zeros((k, k))
    rows = min(k, stacked.shape[0])
    out[:rows] = np.triu(qr[:rows])
    return out


def gram_root(G: Array) -> Array:
    """Symmetric square root ``B`` ``(k, k)`` of a Gram matrix: ``B^T B = G``.

    Negative eigenvalues (round-off of a singular ``G``) are clipped to zero.
    """
    w, V = np.linalg.eigh(np.asarray(G, dtype=float))
    return np.sqrt(np.clip(w, 0.0, None))[:, None] * V.T
