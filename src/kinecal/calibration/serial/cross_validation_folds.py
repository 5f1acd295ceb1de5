"""How the calibration poses are dealt into cross-validation folds.

Random folds (`fold_of`) hold out poses scattered among the others: they score how a model
*interpolates*. A calibration is also used beyond its poses, and random folds cannot see
how a model extrapolates, so ``--error-model auto`` also scores *blocked* folds
(`blocked_folds`; Roberts et al. 2017, "Cross-validation strategies for data with temporal,
spatial, hierarchical, or phylogenetic structure", *Ecography* 40(8), 913-929):

* by **joint range**: for each joint, the poses sorted by its reading and cut into ``K``
  contiguous blocks; holding out the first or last block asks the others to predict
  readings beyond their range, the blocks between to bridge a gap;
* by **time order** when the poses carry a time (``time`` column): ``K`` contiguous
  stretches of the measurement, which also test drift.

Every partition is deterministic (no dependence on the user's seed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError

__all__ = ["FOLD_SEED", "Partition", "blocked_folds", "fold_of", "partitions"]

#: seed of the random fold permutation (fixed: the folds never depend on the user's seed)
FOLD_SEED = 0


#: the pose of each row and the number of poses (rows of one arm configuration measured at
#: several markers are one pose), or None: a pose per row
Poses = tuple[NDArray[np.intp], int] | None


def fold_of(n: int, k: int, poses: Poses = None) -> NDArray[np.intp]:
    """Fold index ``(n,)`` of every row: a fixed permutation of the poses dealt
    round-robin (`poses`: the pose of each row and their number; None: a pose per row)."""
    group, m = (np.arange(n), n) if poses is None else poses
    _check(m, k)
    perm = np.random.default_rng(FOLD_SEED).permutation(m)
    folds = np.empty(m, dtype=np.intp)
    folds[perm] = np.arange(m) % k
    return folds[group]


def blocked_folds(values: NDArray[np.float64], k: int, poses: Poses = None
                  ) -> NDArray[np.intp]:
    """Fold index ``(n,)`` of every row: the poses in the order of `values` (a pose's first
    row's; stable: ties in the order given) cut into `k` contiguous blocks of equal size
    (+-1); a pose's rows stay together."""
    values = np.asarray(values, dtype=float)
    group, m = (np.arange(len(values)), len(values)) if poses is None else poses
    _check(m, k)
    first = np.full(m, -1, dtype=np.intp)
    for r in range(len(values) - 1, -1, -1):
        first[group[r]] = r
    order = np.argsort(values[first], kind="stable")
    folds = np.empty(m, dtype=np.intp)
    folds[order] = (np.arange(m) * k) // m
    return folds[group]


def _check(n: int, k: int) -> None:
    if k < 2 or k > n:
        raise InputError(f"cross-validation: expected 2 <= folds <= {n} poses, got {k}",
                         option="--folds")


@dataclass(frozen=True)
class Partition:
    """One way of dealing the poses into folds.

    Attributes
    ----------
    name : str
        ``random``, ``q{j}`` (blocked by joint j's reading, 1-based) or ``time``.
    folds : ndarray of int, shape (N,)
        Fold index of every pose, ``0..K-1``.
    """

    name: str
    folds: NDArray[np.intp]

    @property
    def blocked(self) -> bool:
        return self.name != "random"

    @property
    def k(self) -> int:
        """Number of folds."""
        return int(self.folds.max()) + 1


def partitions(q: NDArray[np.float64], k: int, time: NDArray[np.float64] | None = None,
               blocks: int | None = None, poses: Poses = None) -> list[Partition]:
    """The random partition, then the blocked ones: by time order when `time` ``(N,)`` is
    given, and by the range of every joint whose readings `q` ``(N, n_joints)`` vary
    (`blocks` folds each, default `k`; `poses` as in `fold_of`)."""
    q = np.asarray(q, dtype=float)
    blocks = k if blocks is None else blocks
    out = [Partition("random", fold_of(len(q), k, poses))]
    if time is not None:
        out.append(Partition("time", blocked_folds(np.asarray(time, dtype=float), blocks,
                                                   poses)))
    for j in range(q.shape[1]):
        if np.ptp(q[:, j]) > 0:
            out.append(Partition(f"q{j + 1}", blocked_folds(q[:, j], blocks, poses)))
    return out
