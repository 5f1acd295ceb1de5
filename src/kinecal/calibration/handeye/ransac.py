"""A consensus start for the robust refinement when many stations are outliers.

Iteratively reweighted least squares (`refine.lm`) starts from a closed form over all
stations; with half the stations corrupted, that start is pulled so far that reweighting
keeps part of the outliers (KNOWN-DEFECTS: median 4.75 mm at 50 % outliers). Random sample
consensus (Fischler & Bolles 1981) on minimal sets avoids it: 3 stations (two motions, the
fewest that fix X) give a hypothesis by Park's closed form, every station is scored by its
normalised residual against it, and the hypothesis with the smallest sum of the 40 %
smallest squared residuals (least trimmed squares, which tolerates up to 60 % outliers)
wins. Its consensus set then seeds `refine.lm`.

Deterministic: the samples come from ``numpy.random.default_rng(seed)``; with at most
``max_samples`` minimal sets, all of them are tried.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye import axxb
from kinecal.calibration.handeye._motions import motion_pairs
from kinecal.calibration.handeye.errors import mean_target_pose
from kinecal.calibration.handeye.refine import camera_residuals

Array = NDArray[np.float64]

__all__ = ["ConsensusStart", "consensus_start"]

#: fraction of the stations whose squared residuals the trimmed score sums
TRIM = 0.4


@dataclass
class ConsensusStart:
    """Result of `consensus_start`: X, target pose Y, the trimmed score (normalised),
    the consensus set (station indices) and the number of hypotheses tried."""

    X: Array
    Y: Array
    score: float
    inliers: NDArray[np.intp]
    hypotheses: int


def _distances(G: Array, C: Array, X: Array, Y: Array, sr: float, st: float) -> Array:
    rot, tr = camera_residuals(G, C, X, Y)
    return np.sum((rot / sr) ** 2, axis=1) + np.sum((tr / st) ** 2, axis=1)


def consensus_start(G: Array, C: Array, scales: tuple[float, float],
                    seed: int | np.random.Generator | None = 0,
                    max_samples: int = 300) -> ConsensusStart | None:
    """Best minimal-set hypothesis of ``G_i X C_i = Y`` by least trimmed squares.

    Parameters
    ----------
    G, C : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand) and
        ``target2cam``.
    scales : (float, float)
        Rotation (rad) and translation (length) scales that make the two residual kinds
        comparable (e.g. the robust scales of a first refinement).
    seed : int or Generator, optional
        Seed of the sampling.
    max_samples : int
        Hypotheses drawn (all 3-subsets when there are fewer).

    Returns
    -------
    ConsensusStart or None
        None when no minimal set is non-degenerate (or fewer than 5 stations: nothing to
        gain over the plain refinement).
    """
    n = len(G)
    if n < 5:
        return None
    rng = np.random.default_rng(seed)
    subsets = list(combinations(range(n), 3))
    if len(subsets) > max_samples:
        pick = rng.choice(len(subsets), size=max_samples, replace=False)
        subsets = [subsets[k] for k in np.sort(pick)]
    sr, st = scales
    k = max(3, int(np.ceil(TRIM * n)))
    best: tuple[float, Array, Array] | None = None
    tried = 0
    for s in subsets:
        idx = np.array(s)
        A, B = motion_pairs(G[idx], C[idx], "all")
        ang = np.linalg.norm(np.cross(_axes(A)[0], _axes(A)[1]))
        if not np.isfinite(ang) or ang < 0.05:  # (nearly) parallel axes: X not fixed
            continue
        X = axxb.park(A, B)
        Y = mean_target_pose(G[idx], X, C[idx])
        tried += 1
        d2 = _distances(G, C, X, Y, sr, st)
        score = float(np.sum(np.partition(d2, k - 1)[:k]))
        if best is None or score < best[0]:
            best = (score, X, Y)
    if best is None:
        return None
    score, X, Y = best
    d2 = _distances(G, C, X, Y, sr, st)
    s0 = 1.4826 * np.sqrt(np.median(np.sort(d2)[:max(k, 3)]) / 6.0) * 1.5
    inliers = np.flatnonzero(d2 <= (3.0 * max(s0, 1e-12)) ** 2 * 6.0)
    if len(inliers) >= 3:
        Y = mean_target_pose(G[inliers], X, C[inliers])
    return ConsensusStart(X, Y, score, inliers, tried)


def _axes(A: Array) -> Array:
    """Unit rotation axes ``(m, 3)`` of motions (NaN for null rotations)."""
    from kinecal.spatial import axis_angle_from_matrix

    w = axis_angle_from_matrix(A[:, :3, :3])
    with np.errstate(invalid="ignore", divide="ignore"):
        return w / np.linalg.norm(w, axis=1, keepdims=True)
