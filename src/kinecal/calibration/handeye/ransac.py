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

from kinecal.calibration.handeye._motions import motion_pairs, pair_indices
from kinecal.calibration.handeye.errors import mean_target_pose
from kinecal.calibration.handeye.refine import camera_residuals
from kinecal.spatial import axis_angle_from_matrix, project_to_rotation, transform_from

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
    return np.sum((rot / sr) ** 2, axis=-1) + np.sum((tr / st) ** 2, axis=-1)


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
    X, Y, keep = _hypotheses(G, C, np.array(subsets, dtype=np.intp))
    if not keep.any():
        return None
    X, Y = X[keep], Y[keep]
    d2 = _distances(G[None], C[None], X[:, None], Y[:, None], sr, st)  # (h, n)
    score = np.sum(np.partition(d2, k - 1, axis=1)[:, :k], axis=1)
    best = int(np.argmin(score))  # the first of equal scores, as a loop keeping "<" would
    X, Y = X[best], Y[best]
    d2 = d2[best]
    s0 = 1.4826 * np.sqrt(np.median(np.sort(d2)[:max(k, 3)]) / 6.0) * 1.5
    inliers = np.flatnonzero(d2 <= (3.0 * max(s0, 1e-12)) ** 2 * 6.0)
    if len(inliers) >= 3:
        Y = mean_target_pose(G[inliers], X, C[inliers])
    return ConsensusStart(X, Y, float(score[best]), inliers, int(keep.sum()))


def _hypotheses(G: Array, C: Array, subsets: NDArray[np.intp]
                ) -> tuple[Array, Array, NDArray[np.bool_]]:
    """Park's X and the mean target pose Y of every minimal set ``(h, 3)`` of stations, all
    at once (the motions of every station pair and their logarithms computed once), and
    which sets are usable (the first two motions' axes at least 0.05 rad apart).

    Returns X, Y ``(h, 4, 4)`` and the mask ``(h,)``.
    """
    n = len(G)
    A, B = motion_pairs(G, C, "all")
    alpha = axis_angle_from_matrix(A[:, :3, :3])
    beta = axis_angle_from_matrix(B[:, :3, :3])
    # pair index of stations (a, b), a < b, in motion_pairs' order
    pid = np.full((n, n), -1, dtype=np.intp)
    i, j = pair_indices(n, "all")
    pid[i, j] = np.arange(len(i))
    s = subsets
    pairs = np.stack([pid[s[:, 0], s[:, 1]], pid[s[:, 0], s[:, 2]], pid[s[:, 1], s[:, 2]]],
                     axis=1)  # the 3 motions of each set, in motion_pairs' order
    al, be = alpha[pairs], beta[pairs]  # (h, 3, 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        ax = al[:, :2] / np.linalg.norm(al[:, :2], axis=2, keepdims=True)
    ang = np.linalg.norm(np.cross(ax[:, 0], ax[:, 1]), axis=1)
    keep = np.isfinite(ang) & (ang >= 0.05)  # (nearly) parallel axes: X not fixed
    R = _park_rotations(al, be)
    flip = np.sum(al * (be @ np.swapaxes(R, 1, 2)), axis=2) < 0
    R = np.where(flip.any(axis=1)[:, None, None],
                 _park_rotations(al, np.where(flip[..., None], -be, be)), R)
    # translation: least squares on (R_A - I) t_X = R_X t_B - t_A over the 3 motions
    Ah, Bh = A[pairs], B[pairs]
    M = (Ah[..., :3, :3] - np.eye(3)).reshape(len(s), 9, 3)
    rhs = (np.einsum("hij,hmj->hmi", R, Bh[..., :3, 3]) - Ah[..., :3, 3]).reshape(len(s), 9)
    N = np.swapaxes(M, 1, 2) @ M
    keep &= np.linalg.det(N) > 1e-12 * np.trace(N, axis1=1, axis2=2) ** 3
    t = np.zeros((len(s), 3))
    t[keep] = np.linalg.solve(N[keep], np.einsum("hki,hk->hi", M[keep], rhs[keep])[..., None]
                              )[..., 0]
    X = transform_from(R, t)
    P = G[s] @ X[:, None] @ C[s]  # target poses through the set's stations
    Y = transform_from(project_to_rotation(P[..., :3, :3].mean(axis=1)),
                       P[..., :3, 3].mean(axis=1))
    return X, Y, keep


def _park_rotations(alpha: Array, beta: Array) -> Array:
    """Park's rotation ``(h, 3, 3)`` from motion logarithms ``(h, m, 3)`` (`axxb.park`)."""
    U, _, Vt = np.linalg.svd(np.swapaxes(alpha, 1, 2) @ beta)
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[:, :, 2] *= d[:, None]
    return U @ Vt
