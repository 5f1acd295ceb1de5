"""Each block's noise: stated, or estimated from the fit (variance component estimation).

Files of different kinds come with different noise (a ballbar's 2 um, a touch probe's
5 um, a socket's 10 um); the fit weighs each residual row by ``1 / sigma`` of its
observation. A block without a stated noise gets one estimated from its own residual:
``sigma_b^2 = RSS_b / r_b`` with ``RSS_b`` its unweighted residual sum of squares and
``r_b = m_b - trace(A^-1 J_b^T W_b J_b)`` its *redundancy*, the share of the degrees of
freedom its rows keep after the fit (Foerstner 1979, "Ein Verfahren zur Schaetzung von
Varianz- und Kovarianzkomponenten", Allgemeine Vermessungs-Nachrichten 86; Koch,
*Parameter Estimation and Hypothesis Testing in Linear Models*, 1999, sec. 3.6). The
weights change the fit, so fit and estimate alternate until the estimates settle.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.stack import StackedProblem

__all__ = ["MAX_ROUNDS", "SETTLED", "initial_sigma", "redundancies", "variance_factors"]

Array = NDArray[np.float64]

#: fit / estimate rounds at most
MAX_ROUNDS = 12
#: the estimates have settled when every noise changed by less than this fraction
SETTLED = 1e-3


def initial_sigma(blocks: Sequence[ResidualBlock]) -> tuple[list[Array], list[bool]]:
    """Noise per observation of each block to start from, and which blocks state theirs.

    A block without a stated noise starts at the median stated noise of the blocks in its
    unit (1 when none states one); only ratios between blocks matter to the fit.
    """
    stated = [b.stated_sigma() for b in blocks]
    known = [s is not None for s in stated]
    by_unit: dict[str, list[float]] = {}
    for b, s in zip(blocks, stated, strict=True):
        if s is not None:
            by_unit.setdefault(b.unit, []).append(float(np.median(s)))
    out = []
    for b, s in zip(blocks, stated, strict=True):
        if s is None:
            guess = float(np.median(by_unit[b.unit])) if b.unit in by_unit else 1.0
            s = guess * b.relative_sigma()
        out.append(np.asarray(s, dtype=float))
    return out, known


def redundancies(problem: StackedProblem, x: Array) -> Array:
    """Redundancy ``r_b`` of each block at `x` (they sum to ``m - rank``; rows left out of
    the fit count in neither).

    ``trace(A^-1 J_b^T J_b)`` is summed over the block's own columns only (the arm's and
    its nuisance): the normal matrix ``A`` is formed once, never a matrix of the whole
    problem per block (200 fixed-point files held 9 GB of such matrices).
    """
    parts = problem.normal_parts(x)  # the normal matrix and the trackers' shares in one pass
    _, A, _ = problem.assemble(parts, x)
    d = np.sqrt(np.clip(np.diag(A), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    Ainv = np.linalg.pinv(A / np.outer(d, d), rcond=1e-12, hermitian=True) / np.outer(d, d)
    dense = [part.dense for part in parts]
    rows = problem._weighted_rows(x, only=dense) if any(dense) else iter([None] * len(parts))
    out = []
    k = problem.k
    for m, part, s, row in zip(problem.used_rows, parts, problem.slices, rows, strict=True):
        cols = np.r_[np.arange(k), np.arange(s.start, s.stop)]
        if row is not None:  # from the rows, as exact as they are
            Jb = np.hstack([row[1], row[2]])
            t = np.sum((Jb @ Ainv[np.ix_(cols, cols)]) * Jb)
        elif part.nn.size:  # a block that sums its own share (`normal_parts`)
            G = np.block([[part.aa, part.an], [part.an.T, part.nn]])
            t = np.sum(Ainv[np.ix_(cols, cols)] * G)
        else:  # a block without unknowns: from its Gram matrix (`arm_normal`)
            t = np.sum(Ainv[:k, :k] * part.aa)
        out.append(m - float(t))
    return np.array(out)


def variance_factors(problem: StackedProblem, x: Array, residuals: list[Array]
                     ) -> tuple[Array, Array]:
    """``RSS_b / r_b`` of each block in units of its current noise (1 when the noise is
    right), and the redundancies ``r_b``. NaN where a block keeps no redundancy."""
    r = redundancies(problem, x)
    rss = np.array([float(np.sum((ri * w) ** 2)) for ri, w in
                    zip(residuals, problem.row_weight, strict=True)])
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(r > 1e-6 * np.array(problem.used_rows), rss / r, np.nan)
    return f, r
