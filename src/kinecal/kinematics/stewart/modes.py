"""All real assembly modes of the Stewart-platform CMM for one set of leg lengths.

Also the workspace sampling (:func:`random_poses`) used by tests, simulation and benchmarks.

papers/004 (sec. 1) notes that the forward position problem of a parallel mechanism has
many solutions; its PSO finds one of them. Here every real solution is found by
vectorized multi-start Newton (:func:`kinecal.kinematics.stewart.forward.newton_batch` from
random poses: uniform orientations, tips in a box around the base) and clustering of the
converged poses. For the Table 3 legs there are 8 solutions above the base plane and
their 8 mirror images below it (reflection in the base plane: ``p_c -> M p_c``,
``R -> M R D`` with ``M = D = diag(1, 1, -1)``, valid because base and platform joints are
planar).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.stewart.forward import (
    StewartGeometry,
    default_tol,
    newton_batch,
    random_starts,
)
from kinecal.spatial import rotation_angle, rpy_from_matrix

__all__ = ["AssemblyModes", "forward_all", "random_poses", "workspace_box"]

Array = NDArray[np.float64]


@dataclass
class AssemblyModes:
    """Real assembly modes for one leg set, the physically sensible one first.

    Attributes
    ----------
    poses : ndarray, shape (K, 6)
        Probe poses (length unit, rad).
    residual : ndarray, shape (K,)
        Max abs leg-length error of each solution (length unit).
    above : ndarray of bool, shape (K,)
        Platform centre above the base plane (``z_c > 0``): a buildable machine.
    distance : ndarray, shape (K,)
        Distance to the neutral pose used for the ranking: tip distance (length unit)
        plus platform radius times the rotation angle (rad).
    hits : ndarray of int, shape (K,)
        Number of random starts that converged to each mode (basin size).
    n_starts : int
        Random starts used.
    """

    poses: Array
    residual: Array
    above: NDArray[np.bool_]
    distance: Array
    hits: NDArray[np.int64]
    n_starts: int

    def __len__(self) -> int:
        return int(self.poses.shape[0])


def forward_all(
    geom: StewartGeometry,
    legs: ArrayLike,
    *,
    starts: int = 4096,
    rng: np.random.Generator | int | None = None,
    tol: float | None = None,
    below: bool = True,
    cluster_tol: float = 1e-7,
) -> AssemblyModes:
    """Every real forward-kinematics solution for one set of leg readings.

    Parameters
    ----------
    geom : StewartGeometry
    legs : array_like, shape (6,)
        Leg readings (length unit), checked against the leg range.
    starts : int
        Random Newton starts (default 4096; all solved as one batch).
    rng : Generator or int, optional
        Random generator or seed (default seed 0: deterministic).
    tol : float, optional
        Newton tolerance on the max abs leg error (length unit; default
        ``1e-13 * max(L)``).
    below : bool
        Also search below the base plane (the mirror images).
    cluster_tol : float
        Two converged poses closer than this (tip distance plus platform radius times
        rotation angle, length unit) are the same mode.

    Returns
    -------
    AssemblyModes
        Sorted: modes above the base first, then by `distance` to the neutral pose; the
        first one is the physically sensible solution (the one the machine is in).
    """
    L = geom.check_legs(legs)
    if L.shape[0] != 1:
        raise InputError(f"forward_all takes one leg set (6,), got {L.shape[0]} rows")
    if starts < 1:
        raise InputError("starts must be positive", option="starts")
    gen = np.random.default_rng(0 if rng is None else rng)
    R0, t0 = random_starts(geom, starts, gen, below=below)
    Lp = np.repeat(L + geom.leg_offsets, starts, axis=0)
    tol = default_tol(Lp) if tol is None else float(tol)
    R, t, res, _ = newton_batch(geom.tip_joints, geom.base_joints, Lp, R0, t0, tol=tol)
    ok = res < tol
    R, t, res = R[ok], t[ok], res[ok]
    scale = float(np.linalg.norm(geom.platform_joints, axis=1).max()) or 1.0
    centre = t - R @ geom.probe_vector
    # greedy clustering: a loop over the (few) modes, each step vectorized over all poses
    label = np.full(R.shape[0], -1)
    reps: list[int] = []
    while (label < 0).any():
        i = int(np.argmax(label < 0))
        dR = np.swapaxes(R[i], -1, -2) @ R
        d = np.linalg.norm(t - t[i], axis=1) + scale * rotation_angle(dR)
        label[(label < 0) & (d < cluster_tol)] = len(reps)
        reps.append(i)
    idx = np.array(reps, dtype=np.int64)
    hits = np.bincount(label, minlength=len(reps)) if reps else np.zeros(0, np.int64)
    neutral = geom.neutral_pose()
    dist = np.linalg.norm(t[idx] - neutral[:3], axis=1) + scale * rotation_angle(R[idx])
    above = centre[idx, 2] > 0.0
    order = np.lexsort((dist, ~above))
    idx = idx[order]
    poses = np.concatenate([t[idx], rpy_from_matrix(R[idx])], axis=1)
    return AssemblyModes(
        poses=poses,
        residual=res[idx],
        above=above[order],
        distance=dist[order],
        hits=hits[order],
        n_starts=starts,
    )


def workspace_box(geom: StewartGeometry) -> Array:
    """Default pose box for random workspace poses, shape (6, 2) (length unit, rad).

    Centred on the neutral pose: ``|x|, |y| <= 0.3 R_b``, ``z`` within
    ``+-(l_max - l_min) / 2``, each angle within +-20 deg. (The leg range alone admits
    poses turned by up to 90 deg, which a real CMM's joints and legs do not reach.)
    """
    x0 = geom.neutral_pose()
    rb = float(np.linalg.norm(geom.base_joints[:, :2], axis=1).max())
    lo, hi = geom.leg_range
    dz = 0.5 * (hi - lo) if np.isfinite(hi) else 0.2 * rb
    a = np.deg2rad(20.0)
    half = np.array([0.3 * rb, 0.3 * rb, dz, a, a, a])
    return np.stack([x0 - half, x0 + half], axis=1)


def random_poses(
    geom: StewartGeometry,
    n: int,
    rng: np.random.Generator | int | None = None,
    box: ArrayLike | None = None,
) -> Array:
    """``n`` random poses uniform in `box` whose legs lie inside the leg range.

    Parameters
    ----------
    geom : StewartGeometry
    n : int
        Number of poses.
    rng : Generator or int, optional
        Random generator or seed.
    box : array_like, shape (6, 2), optional
        Pose bounds (length unit, rad); default `workspace_box`.

    Returns
    -------
    ndarray, shape (n, 6)
        Poses (length unit, rad), rejection-sampled in vectorized batches.
    """
    gen = np.random.default_rng(rng)
    lim = workspace_box(geom) if box is None else np.asarray(box, dtype=float)
    if lim.shape != (6, 2) or not np.isfinite(lim).all():
        raise InputError(f"box must be 6 finite (low, high) rows, got {lim.shape}", option="box")
    lo, hi = geom.leg_range
    out = np.empty((0, 6))
    for _ in range(1000):  # batches of candidates until enough are reachable
        if out.shape[0] >= n:
            break
        cand = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * gen.random((max(4 * n, 256), 6))
        legs = geom.inverse(cand)
        ok = ((legs >= lo) & (legs <= hi)).all(axis=1)
        out = np.concatenate([out, cand[ok]])
    if out.shape[0] < n:
        raise InputError("the pose box holds (almost) no reachable pose", option="box")
    return out[:n]
