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

A fit holds its joint-error terms at the edges of the joint readings it saw
(`kinecal.kinematics.serial.joint_errors_envelope`): so does the training fit of a fold.
The held-out rows' coefficient columns ``J_i`` are the chain's joint Jacobian times the
terms' basis evaluated with the *training* poses' envelope, which is what the fit would
predict there (the residual ``r_i`` is that of the start values, exact when those are
zero, as for the terms ``auto`` adds).

One pass over the poses accumulates the per-fold Gram matrices of all columns for every
partition (`kinecal.calibration.serial.cross_validation_folds`: random folds, and folds
blocked by joint range or time order); every candidate and fold is then ``(k, k)``
algebra, plus a second pass for the held-out distances. Memory stays linear in the poses.

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
from kinecal.calibration.serial.cross_validation_folds import (
    FOLD_SEED,
    Partition,
    blocked_folds,
    fold_of,
    partitions,
)
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC

__all__ = ["FOLD_SEED", "CVScore", "FoldedRows", "Partition", "blocked_folds",
           "cross_validate", "data_poses", "fold_of", "n_poses", "one_standard_error",
           "partitions", "within_and_beyond"]

Array = NDArray[np.float64]
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
    parameter indices `columns` (rows weighted like the fit), for every partition of the
    poses into folds, and the tool positions.

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
    partitions : sequence of Partition, optional
        The ways of dealing the poses into `k` folds (default: random folds only).

    Attributes
    ----------
    parts : list of Partition
    folds : ndarray of int, shape (N,)
        The first partition's folds.
    grams : ndarray, shape (k, m + 1, m + 1)
        Per fold of the first partition, the Gram matrix of its poses' rows ``[J | r]``.
    total : ndarray, shape (m + 1, m + 1)
        Their sum: the Gram matrix of all rows.
    positions : ndarray, shape (N, 3)
        Model tool positions at `params`.
    """

    def __init__(self, model: SerialModel, data: Measurements, params: Array,
                 columns: Sequence[int], k: int = 10, rotation_weight: float = 0.0,
                 partitions: Sequence[Partition] | None = None) -> None:
        self.cols = np.asarray(columns, dtype=np.intp)
        self.params = np.asarray(params, dtype=float)
        m = self.cols.size
        n = len(data)
        self.k = k
        self.parts = list(partitions) if partitions else [
            Partition("random", fold_of(n, k, data_poses(data)))]
        self.folds = self.parts[0].folds
        self.rows = PoseRows(model, data, rotation_weight, weighted=True)
        self.sw = (np.ones(n) if data.weights is None
                   else np.sqrt(np.asarray(data.weights, dtype=float)))
        self._terms = model._joint_terms
        n_geo = model._n_geometric
        coef = np.flatnonzero(self.cols >= n_geo) if self._terms is not None else []
        self._coef_pos = np.asarray(coef, dtype=np.intp)
        self._coef_term = self.cols[self._coef_pos] - n_geo
        # the joint-reading columns (the chain's joint Jacobian) rebuild the held-out
        # coefficient columns of each fold (a parameter's rows are asked for once)
        self._eval_cols = self.cols
        if self._coef_pos.size:
            extra = [c for c in dict.fromkeys(model._joint_columns.tolist())
                     if c not in set(self.cols.tolist())]
            self._eval_cols = np.r_[self.cols, np.asarray(extra, dtype=np.intp)]
        where = {int(c): i for i, c in enumerate(self._eval_cols)}
        self._jq_pos = (np.array([where[int(c)] for c in model._joint_columns], dtype=np.intp)
                        if self._coef_pos.size else np.zeros(0, dtype=np.intp))
        self._revolute = [kd != PRISMATIC for kd in model.joint_kinds]
        self._q = np.asarray(data.q, dtype=float)
        G = [np.zeros((part.k, m + 1, m + 1)) for part in self.parts]
        self.positions = np.empty((n, 3))
        keep = n * self.rows.rows * self._eval_cols.size <= _KEEP_ELEMENTS
        self._kept: list | None = [] if keep else None
        for sel in self.rows.chunks(self._eval_cols.size):
            e, Jt, P = self.rows.evaluate(self.params, sel, self._eval_cols)
            self.positions[sel] = P
            if self._kept is not None:
                self._kept.append((sel, e, Jt))
            # rows [J | r] pose-major: a fold's poses are then one contiguous block
            B = np.concatenate([Jt[:m], e.T[None]], axis=0).transpose(0, 2, 1)
            for p, part in enumerate(self.parts):
                f = part.folds[sel]
                order = np.argsort(f, kind="stable")
                Bo = np.ascontiguousarray(B[:, order])
                bounds = np.searchsorted(f[order], np.arange(part.k + 1))
                for fold in range(part.k):
                    lo, hi = bounds[fold], bounds[fold + 1]
                    if hi > lo:
                        Bf = Bo[:, lo:hi].reshape(m + 1, -1)
                        G[p][fold] += Bf @ Bf.T
        self._grams = G
        self.grams = G[0]
        self.total = G[0].sum(axis=0)

    def _steps(self, candidates: Sequence[Sequence[int]], p: int,
               penalties: Sequence[tuple[Array, Array] | None] | None = None) -> list:
        """Per candidate its columns and the training steps ``(K, len(S))`` of every fold
        of partition `p`.

        `penalties`: per candidate None or ``(d, h)`` (each ``(len(S),)``): a quadratic
        penalty ``sum d (h + dx)^2`` on the training fits (a prior whose value is ``-h``
        away from the linearisation point, `kinecal.calibration.serial.prior_auto`):
        ``dx_f = -(A_f + diag(d))^-1 (b_f + d h)``.
        """
        k, m = self.parts[p].k, self.cols.size
        G = self._grams[p]
        total = self.total
        steps = []
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
        return steps

    def _held_out(self, sel, Jt: Array, folds: Array, bounds: tuple[Array, Array]) -> Array:
        """Position rows ``(m, 3, n)`` of the poses `sel` as their folds' training fits see
        them: coefficient columns from the basis within each fold's training envelope
        (`bounds`: per fold the lowest and highest training readings, ``(K, n_joints)``)."""
        m = self.cols.size
        J3 = Jt[:m, :3]
        if not self._coef_pos.size:
            return J3
        q = self._q[sel]
        low, high = bounds[0][folds], bounds[1][folds]
        # rows within their fold's raw readings: the all-pose basis as it is
        at = np.flatnonzero(((q < low) | (q > high)).any(axis=1))
        if not at.size:
            return J3
        J3 = J3.copy()
        Jq = Jt[self._jq_pos, :3]  # (n_joints, 3, n): the chain's joint Jacobian
        joint = self._terms.joint_of[self._coef_term]
        W = self._terms.basis_rows(q[at], low[at], high[at])[:, self._coef_term]
        J3[self._coef_pos[:, None], :, at[None, :]] = np.moveaxis(
            Jq[joint][:, :, at] * W.T[:, None, :], 2, 1)
        return J3

    def scores(self, candidates: Sequence[Sequence[int]], partition: int = 0,
               penalties: Sequence[tuple[Array, Array] | None] | None = None
               ) -> list[CVScore]:
        """Cross-validation score of each candidate (its columns as positions in
        `columns`) on the folds of partition number `partition`; `penalties` as in
        `_steps` (priors)."""
        k = self.parts[partition].k
        folds = self.parts[partition].folds
        steps = self._steps(candidates, partition, penalties)
        bounds = (np.stack([self._q[folds != f].min(axis=0) for f in range(k)]),
                  np.stack([self._q[folds != f].max(axis=0) for f in range(k)]))
        n = folds.size
        dist = np.zeros((len(candidates), n))
        chunks = self._kept if self._kept is not None else (
            (sel, *self.rows.evaluate(self.params, sel, self._eval_cols)[:2])
            for sel in self.rows.chunks(self._eval_cols.size))
        for sel, e, Jt in chunks:
            f = folds[sel]
            J3 = self._held_out(sel, Jt, f, bounds)
            for c, (S, dx) in enumerate(steps):
                # held-out prediction r_i + J_i dx_f of each pose with its own fold's step
                step = np.einsum("krn,nk->nr", J3[S], dx[f]) if S.size else 0.0
                dist[c, sel] = np.linalg.norm(e[:, :3] + step, axis=1) / self.sw[sel]
        out = []
        counts = np.bincount(folds, minlength=k)
        for c in range(len(candidates)):
            means = np.bincount(folds, weights=dist[c], minlength=k) / counts
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


def within_and_beyond(random: Sequence[CVScore], blocked: Sequence[Sequence[CVScore]]
                      ) -> list[CVScore]:
    """Per candidate, the score ``auto`` ranks: half the random folds' mean (the poses
    among the calibration poses) and half the mean over the blocked partitions (poses
    beyond them: a joint's range, a stretch of time). Its standard error is the random
    folds' (the blocked folds' means differ by design: the outer blocks extrapolate).
    Without blocked partitions, the random score itself."""
    if not blocked:
        return list(random)
    out = []
    for c, sc in enumerate(random):
        beyond = float(np.mean([part[c].mean for part in blocked]))
        out.append(CVScore(0.5 * sc.mean + 0.5 * beyond, sc.se, sc.fold_means))
    return out


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
