"""K-fold cross-validation of nested calibration models on the calibration poses.

Every candidate model is a set of columns of one identification Jacobian (the geometric
free parameters plus some joint-error coefficients), linearised at the geometric
calibration ``x_g`` of all calibration poses. For fold ``f`` the training fit is the
Gauss-Newton step from ``x_g`` on the other folds' rows,

    dx_f = -(A - A_f)^-1 (b - b_f),   A = J^T W J,  b = J^T W r  (per-fold sums A_f, b_f),

and the held-out error of a pose ``i`` in fold ``f`` is the distance ``|r_i + J_i dx_f|``.
For a model linear in its parameters this is exactly K-fold cross-validation (the
training fit does not depend on where it starts); calibration models are linear to
second order in the corrections (the UR5 geometry moves by < 1 mm on a 1 m arm), and
``benchmarks/bench_error_models.py`` compares the step with full refits.

One pass over the poses accumulates the per-fold Gram matrices of all columns; every
candidate and fold is then ``(k, k)`` algebra, plus a second pass for the held-out
distances. Memory stays linear in the poses.

Folds are deterministic: a fixed permutation (seed 0, independent of the user's seed)
dealt round-robin into ``K`` folds of equal size (+-1). They deal *poses*, not rows: the
rows of one arm configuration measured at several markers
(`kinecal.calibration.diagnostics.observations.pose_groups`) are held out together, so
that no fold is trained on a pose it is then tested on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from kinecal.calibration.diagnostics.observations import pose_groups
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["CVScore", "FoldedRows", "cross_validate", "data_poses", "fold_of", "n_poses",
           "one_standard_error"]

Array = NDArray[np.float64]
#: seed of the fold permutation (fixed: the folds never depend on the user's seed)
FOLD_SEED = 0
#: per-pose Jacobian rows kept between the two passes up to this many numbers
_KEEP_ELEMENTS = 8_000_000


@dataclass(frozen=True)
class CVScore:
    """Cross-validation score of one candidate.

    Attributes
    ----------
    mean : float
        Mean held-out distance error over all calibration poses (length unit).
    se : float
        Standard error of `mean`: the standard deviation of the per-fold means over
        ``sqrt(K)``.
    fold_means : ndarray, shape (K,)
        Mean held-out distance error of each fold.
    """

    mean: float
    se: float
    fold_means: Array


def fold_of(n: int, k: int, poses: tuple[NDArray[np.intp], int] | None = None
            ) -> NDArray[np.intp]:
    """Fold index ``(n,)`` of every row: a fixed permutation of the poses dealt
    round-robin (`poses`: the pose of each row and their number; None: a pose per row)."""
    group, m = (np.arange(n), n) if poses is None else poses
    if k < 2 or k > m:
        raise InputError(f"cross-validation: expected 2 <= folds <= {m} poses, got {k}",
                         option="--folds")
    perm = np.random.default_rng(FOLD_SEED).permutation(m)
    folds = np.empty(m, dtype=np.intp)
    folds[perm] = np.arange(m) % k
    return folds[group]


def data_poses(data: Measurements) -> tuple[NDArray[np.intp], int] | None:
    """The pose of each row of `data` and their number; None when every row is its own
    pose (one tool point: a repeated row is a repeated measurement)."""
    if data.marker is None:
        return None
    return pose_groups(np.asarray(data.q, dtype=float), np.asarray(data.marker))


def n_poses(data: Measurements) -> int:
    """Number of poses of `data` (rows at several markers of one configuration: one)."""
    poses = data_poses(data)
    return len(data) if poses is None else poses[1]


def _solve(A: Array, b: Array) -> Array:
    try:
        c = scipy.linalg.cho_factor(A, check_finite=False)
        return scipy.linalg.cho_solve(c, b, check_finite=False)
    except np.linalg.LinAlgError:  # a fold that leaves the set rank-deficient
        return np.linalg.lstsq(A, b, rcond=None)[0]


class FoldedRows:
    """One pass over the poses at `params`: per-fold Gram matrices of ``[J | r]`` for the
    parameter indices `columns` (rows weighted like the fit), and the tool positions.

    Parameters
    ----------
    model : SerialModel
        The model holding every candidate's parameters.
    data : Measurements
        Calibration poses.
    params : ndarray, shape (n_params,)
        Linearisation point (the fit of the smallest model on all poses).
    columns : sequence of int
        Parameter indices of the union of all candidates' columns.
    k : int
        Number of folds.
    rotation_weight : float
        Length units per rad of the rotation rows (measured orientations only).

    Attributes
    ----------
    grams : ndarray, shape (k, m + 1, m + 1)
        Per fold, the Gram matrix of its poses' rows ``[J | r]``.
    total : ndarray, shape (m + 1, m + 1)
        Their sum: the Gram matrix of all rows.
    positions : ndarray, shape (N, 3)
        Model tool positions at `params`.
    """

    def __init__(self, model: SerialModel, data: Measurements, params: Array,
                 columns: Sequence[int], k: int = 10, rotation_weight: float = 0.0) -> None:
        self.cols = np.asarray(columns, dtype=np.intp)
        self.params = np.asarray(params, dtype=float)
        m = self.cols.size
        n = len(data)
        self.k = k
        self.folds = fold_of(n, k, data_poses(data))
        self.rows = PoseRows(model, data, rotation_weight, weighted=True)
        self.sw = (np.ones(n) if data.weights is None
                   else np.sqrt(np.asarray(data.weights, dtype=float)))
        G = np.zeros((k, m + 1, m + 1))
        self.positions = np.empty((n, 3))
        keep = n * self.rows.rows * m <= _KEEP_ELEMENTS
        self._kept: list | None = [] if keep else None
        for sel in self.rows.chunks(m):
            e, Jt, P = self.rows.evaluate(self.params, sel, self.cols)
            self.positions[sel] = P
            if self._kept is not None:
                self._kept.append((sel, e, Jt))
            f = self.folds[sel]
            order = np.argsort(f, kind="stable")
            bounds = np.searchsorted(f[order], np.arange(k + 1))
            for fold in range(k):
                at = order[bounds[fold]:bounds[fold + 1]]
                if not at.size:
                    continue
                B = np.concatenate([Jt[:, :, at].reshape(m, -1),
                                    np.ascontiguousarray(e[at].T).reshape(1, -1)])
                G[fold] += B @ B.T
        self.grams = G
        self.total = G.sum(axis=0)

    def scores(self, candidates: Sequence[Sequence[int]],
               penalties: Sequence[tuple[Array, Array] | None] | None = None
               ) -> list[CVScore]:
        """Cross-validation score of each candidate (its columns as positions in
        `columns`).

        `penalties`: per candidate None or ``(d, h)`` (each ``(len(S),)``): a quadratic
        penalty ``sum d (h + dx)^2`` on the training fits (a prior whose value is ``-h``
        away from the linearisation point, `kinecal.calibration.serial.prior_auto`):
        ``dx_f = -(A_f + diag(d))^-1 (b_f + d h)``.
        """
        k, m = self.k, self.cols.size
        G, total = self.grams, self.total
        steps = []  # per candidate: (K, len(S)) training steps
        for c, S in enumerate(candidates):
            S = np.asarray(S, dtype=np.intp)
            dx = np.zeros((k, S.size))
            if S.size:  # the training normal equations of every fold at once
                A = total[np.ix_(S, S)] - G[:, S][:, :, S]
                b = total[S, m] - G[:, S, m]
                if penalties is not None and penalties[c] is not None:
                    d, h = penalties[c]
                    A = A + np.diag(d)
                    b = b + d * h
                try:
                    dx = -np.linalg.solve(A, b[..., None])[..., 0]
                except np.linalg.LinAlgError:  # a fold leaves the set rank-deficient
                    dx = np.stack([-_solve(A[f], b[f]) for f in range(k)])
            steps.append((S, dx))
        n = self.folds.size
        dist = np.zeros((len(candidates), n))
        chunks = self._kept if self._kept is not None else (
            (sel, *self.rows.evaluate(self.params, sel, self.cols)[:2])
            for sel in self.rows.chunks(m))
        for sel, e, Jt in chunks:
            f = self.folds[sel]
            J3 = Jt[:, :3]
            for c, (S, dx) in enumerate(steps):
                # held-out prediction r_i + J_i dx_f of each pose with its own fold's step
                step = np.einsum("krn,nk->nr", J3[S], dx[f]) if S.size else 0.0
                dist[c, sel] = np.linalg.norm(e[:, :3] + step, axis=1) / self.sw[sel]
        out = []
        counts = np.bincount(self.folds, minlength=k)
        for c in range(len(candidates)):
            means = np.bincount(self.folds, weights=dist[c], minlength=k) / counts
            out.append(CVScore(float(dist[c].mean()), float(means.std(ddof=1) / np.sqrt(k)),
                               means))
        return out


def cross_validate(model: SerialModel, data: Measurements, params: Array,
                   columns: Sequence[int], candidates: Sequence[Sequence[int]], k: int = 10,
                   rotation_weight: float = 0.0) -> list[CVScore]:
    """K-fold cross-validation scores of nested candidates (module docstring).

    Parameters
    ----------
    model, data, params, columns, k, rotation_weight
        As in `FoldedRows`.
    candidates : sequence of sequence of int
        Each candidate's columns, as positions in `columns`.

    Returns
    -------
    list of CVScore
        One per candidate.
    """
    return FoldedRows(model, data, params, columns, k, rotation_weight).scores(candidates)


def one_standard_error(scores: Sequence[CVScore], sizes: Sequence[int]) -> tuple[int, int]:
    """The one-standard-error rule (Breiman et al. 1984; Hastie, Tibshirani, Friedman,
    *The Elements of Statistical Learning*, 2nd ed., sec. 7.10).

    Returns the index of the best-scoring candidate and of the chosen one: the fewest
    parameters (`sizes`) whose score is within one standard error of the best (ties in
    size: the lower score).
    """
    best = int(np.argmin([s.mean for s in scores]))
    limit = scores[best].mean + scores[best].se
    ok = [i for i, s in enumerate(scores) if s.mean <= limit]
    chosen = min(ok, key=lambda i: (sizes[i], scores[i].mean, i))
    return best, chosen
