"""Statistics shared by the plausibility checks: repeated rows, rigid alignment, outliers.

Every threshold here is tied to a quantity of the data or the model (a quantile of a known
distribution, the model's reach or tolerances), never to a particular data set.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtri, fdtri

__all__ = [
    "ALPHA",
    "JOINT_RESOLUTION",
    "MEDIAN_MULTIPLE",
    "UNIT_FACTORS",
    "FitTest",
    "chi3_outliers",
    "chi_outliers",
    "plural",
    "repeat_groups",
    "rigid_rms",
    "similarity_fit",
    "unit_factor_name",
]

Array = NDArray[np.float64]

#: two joint readings closer than this (rad, or length unit for prismatic joints) in every
#: joint are the same pose: below any encoder's resolution, and 1 m from the axis it moves
#: the tool by 1 um, far below any calibration instrument's noise
JOINT_RESOLUTION = 1e-6
#: length-unit factors a scale mismatch is named after (measured / model)
UNIT_FACTORS = {
    1e-3: "metres in a millimetre model",
    1e3: "millimetres in a metre model",
    1e-1: "centimetres in a millimetre model",
    1e1: "millimetres in a centimetre model",
    1e-2: "metres in a centimetre model",
    1e2: "centimetres in a metre model",
    1 / 25.4: "inches in a millimetre model",
    25.4: "millimetres in an inch model",
}
#: an outlier's distance error is at least this many times the median one
MEDIAN_MULTIPLE = 5.0
#: significance level of the statistical checks: a clean data set trips a check with
#: at most this probability (the checks are few, so the family-wise rate stays near it)
ALPHA = 1e-3


def plural(n: int, word: str) -> str:
    """``"1 pose"``, ``"3 poses"``."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def repeat_groups(*columns: Array, resolution: float = JOINT_RESOLUTION) -> tuple[Array, int]:
    """Group rows that repeat each other.

    Parameters
    ----------
    *columns : ndarray, shape (N, k_i)
        Row-aligned arrays; rows equal within `resolution` in every column are one group
        (``resolution=0``: exactly equal).

    Returns
    -------
    group : ndarray of int, shape (N,)
        Group index of each row (groups numbered by first appearance).
    n_groups : int
    """
    X = np.concatenate([np.asarray(c, dtype=float).reshape(len(c), -1) for c in columns], axis=1)
    if X.shape[0] == 0:
        return np.zeros(0, dtype=np.intp), 0
    key = X
    if resolution > 0:  # X is a fresh array: rounded in place
        np.divide(X, resolution, out=X)
        np.round(X, out=X)
    key += 0.0  # -0.0 and 0.0 are one value (and one bit pattern below)
    if X.shape[0] <= 64 and np.isfinite(key).all():  # a few rows: sorted whole at once
        order = np.lexsort(key.T[::-1])  # stable: equal rows keep their order
        srt = key[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = np.any(srt[1:] != srt[:-1], axis=1)
        inverse = np.empty(len(order), dtype=np.intp)
        inverse[order] = np.cumsum(new) - 1
        first = order[new]  # each group's first row
        shared = first[:0]
    else:
        # Linear in the rows: one 64-bit hash per row, grouped by a 1-D sort; the rows of
        # groups with several members are compared with their group's first row, and only
        # a hash collision falls back to sorting whole rows.
        _, first, inverse = np.unique(_row_hash(key), return_index=True, return_inverse=True)
        inverse = inverse.ravel()
        shared = np.flatnonzero(np.bincount(inverse)[inverse] > 1)
    if not np.array_equal(key[shared], key[first[inverse[shared]]]):
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.ravel()
    # renumber by first appearance so that group numbers follow the file order
    order = np.empty(first.size, dtype=np.intp)
    order[np.argsort(first)] = np.arange(first.size)
    return order[inverse], int(first.size)


def _row_hash(key: Array) -> NDArray[np.uint64]:
    """A 64-bit hash of each row's bits (FNV-1a over the 64-bit words, then mixed)."""
    bits = np.ascontiguousarray(key, dtype=float).view(np.uint64)
    h = np.full(bits.shape[0], 0xCBF29CE484222325, dtype=np.uint64)
    prime = np.uint64(0x100000001B3)
    for j in range(bits.shape[1]):
        h ^= bits[:, j]
        h *= prime
        h ^= h >> np.uint64(29)
    return h


def _centered(A: Array) -> tuple[Array, Array]:
    c = A.mean(axis=0)
    return A - c, c


def rigid_rms(A: Array, B: Array, reflection: bool = False) -> float:
    """RMS distance ``|R A_i + t - B_i|`` after the best rigid motion (Kabsch).

    With `reflection` the best orthogonal ``R`` (rotation or mirror) is used instead.
    """
    A0, _ = _centered(np.asarray(A, dtype=float))
    B0, _ = _centered(np.asarray(B, dtype=float))
    if A0.shape[0] == 0:
        return 0.0
    U, S, Vt = np.linalg.svd(A0.T @ B0)
    d = 1.0 if reflection else float(np.sign(np.linalg.det(U @ Vt)) or 1.0)
    ss = (A0 * A0).sum() + (B0 * B0).sum() - 2.0 * (S[0] + S[1] + d * S[2])
    return float(np.sqrt(max(ss, 0.0) / A0.shape[0]))


def similarity_fit(A: Array, B: Array) -> tuple[float, float]:
    """Scale ``s`` and RMS residual of the best similarity ``B ~ s R A + t`` (Umeyama 1991).

    Returns ``(nan, nan)`` when the points `A` do not spread.
    """
    A0, _ = _centered(np.asarray(A, dtype=float))
    B0, _ = _centered(np.asarray(B, dtype=float))
    var = float((A0 * A0).sum())
    if A0.shape[0] < 2 or var <= 0:
        return float("nan"), float("nan")
    U, S, Vt = np.linalg.svd(A0.T @ B0)
    d = float(np.sign(np.linalg.det(U @ Vt)) or 1.0)
    c = float(S[0] + S[1] + d * S[2])
    ss = float((B0 * B0).sum()) - c * c / var
    return c / var, float(np.sqrt(max(ss, 0.0) / A0.shape[0]))


def unit_factor_name(ratio: float) -> str:
    """What a measured / model length ratio most likely means (nearest known factor)."""
    best = min(UNIT_FACTORS, key=lambda f: abs(np.log(ratio / f)))
    if abs(np.log(ratio / best)) < np.log(1.5):
        return UNIT_FACTORS[best]
    return "another length unit or a wrong scale"


def chi_outliers(d: Array, dof: int | Array = 3, alpha: float = ALPHA) -> list[int]:
    """Poses whose error norm is an outlier (median/MAD rule, size-aware threshold).

    `d` holds the norms of residual vectors of `dof` components per pose (3 for a measured
    position; an array ``(N,)`` when poses differ, e.g. a pose measured at three markers
    has 9). The noise of each component is estimated robustly from the median norm (for
    isotropic Gaussian noise of std sigma, ``median(d) = sigma sqrt(chi2_dof median)``,
    1.5382 sigma for 3 components), or from the RMS of the poses below the limit when that
    is larger (the median of few poses is a noisy scale); a pose is an outlier when
    ``(d / sigma)^2`` exceeds the
    chi-square(dof) quantile that a clean set of N poses exceeds anywhere with probability
    `alpha` (Bonferroni: ``1 - alpha / N``), the median + 5 * 1.4826 MAD rule of the robust
    losses, and `MEDIAN_MULTIPLE` times the median (a residual that is a model's misfit
    rather than noise has heavier tails than Gaussian noise; a gross measurement error
    stands far beyond all three). With unequal `dof` the median and MAD rules apply to the
    norms divided by ``sqrt(chi2_dof median)`` (the same rules for equal `dof`).
    """
    d = np.asarray(d, dtype=float)
    n = d.size
    if n < 5:
        return []
    k = np.broadcast_to(np.asarray(dof, dtype=float), d.shape)
    dofs, which = np.unique(k, return_inverse=True)  # the quantiles once per dof
    m = np.sqrt(chdtri(dofs, 0.5))[which]  # the median norm of unit noise, per pose
    z = d / m
    med = float(np.median(z))
    mad = 1.4826 * float(np.median(np.abs(z - med)))
    if med <= 0 or mad <= 0:
        return []
    q = np.sqrt(chdtri(dofs, alpha / n))[which]
    floor = max(med + 5.0 * mad, MEDIAN_MULTIPLE * med) * m
    sigma = med
    # the median is a noisy scale for few poses: also the RMS of the poses that pass, and
    # the larger of the two
    inner = d <= np.maximum(sigma * q, floor)
    if inner.any():
        sigma = max(sigma, float(np.sqrt(np.sum(d[inner] ** 2) / np.sum(k[inner]))))
    limit = np.maximum(sigma * q, floor)
    return [int(i) for i in np.flatnonzero(d > limit)]


def chi3_outliers(d: Array, alpha: float = ALPHA) -> list[int]:
    """`chi_outliers` of position errors (3 components per pose)."""
    return chi_outliers(d, 3, alpha)


class FitTest:
    """Extra-sum-of-squares F-test of added columns, from a Gram matrix of ``[J | E | r]``.

    Parameters
    ----------
    G : ndarray, shape (k + e + 1, k + e + 1)
        Gram matrix of the free columns ``J`` (k), the candidate columns ``E`` (e) and the
        residual ``r`` at the current solution.
    k : int
        Number of free columns.
    n_rows : int
        Number of residual rows (for the degrees of freedom).
    scale : ndarray, shape (k + e,), optional
        Column factors making the columns comparable (rank decisions).

    Attributes
    ----------
    rss_free, rss_full : float
        Residual sum of squares of the linearised fit on ``J`` and on ``[J | E]``.
    added : int
        Rank the candidates add (confounded candidates add nothing).
    step : ndarray, shape (e,)
        The candidates' values in the full linearised fit (their unit), signs as the
        residual's correction (``-`` of the Gauss-Newton step).
    p_significant : bool
        Reduction significant at level `ALPHA`.
    """

    def __init__(self, G: Array, k: int, n_rows: int, scale: Array | None = None,
                 rtol: float = 1e-12) -> None:
        m = G.shape[0] - 1
        D = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
        A = G[:m, :m] * D[:, None] * D[None, :]
        g = G[:m, m] * D
        rss0 = float(G[m, m])
        red_free, rank_free, _ = self._reduction(A[:k, :k], g[:k], rtol)
        red_full, rank_full, x = self._reduction(A, g, rtol)
        self.rss_free = max(rss0 - red_free, 0.0)
        self.rss_full = max(rss0 - red_full, 0.0)
        self.added = rank_full - rank_free
        self.dof = n_rows - rank_full
        self.step = -(x * D)[k:]
        self.significant = False
        if self.added > 0 and self.dof > 0:
            if self.rss_full <= 0.0:
                self.significant = self.rss_free > 0.0
            else:
                f = ((self.rss_free - self.rss_full) / self.added) / (self.rss_full / self.dof)
                self.significant = f > float(fdtri(self.added, self.dof, 1.0 - ALPHA))

    @staticmethod
    def _reduction(A: Array, g: Array, rtol: float) -> tuple[float, int, Array]:
        if A.shape[0] == 0:
            return 0.0, 0, np.zeros(0)
        w, V = np.linalg.eigh(A)
        keep = w > rtol * max(w.max(), 1e-300)
        x = V[:, keep] @ ((V[:, keep].T @ g) / w[keep])
        return float(g @ x), int(keep.sum()), x
