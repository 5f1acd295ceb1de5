"""Poses as observations: the rows one arm configuration measured, tested and counted as one.

A tracker measuring three reflectors on the flange writes three rows per arm
configuration, one per ``marker``; a bad joint reading or a bump of the arm spoils all
three. Rows with the same joint readings and different markers are therefore one *pose*:
one observation of the outlier tests (their errors pooled, ``3 M`` components for ``M``
markers), one item of a leave-one-out or a cross-validation fold, one pose of the pose
counts in the warnings. A second row with the same joints *and* the same marker is a
repeated measurement of the pose, its own observation (the replicates of ``lack-of-fit``).

Entry points: `pose_groups` (the pose of each row), `pooled_norms` (a pose's error norm
from its rows'), `pose_outliers` (the chi-square outlier rule on poses, returning rows),
`describe_poses` (a pose list in words, by its rows).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics._common import JOINT_RESOLUTION, chi_outliers, repeat_groups

__all__ = ["describe_poses", "pooled_norms", "pose_groups", "pose_outliers", "pose_rows"]

Array = NDArray[np.float64]


def pose_groups(q: Array, marker: NDArray[np.intp] | None = None,
                resolution: float = JOINT_RESOLUTION) -> tuple[NDArray[np.intp], int]:
    """The pose of every row: rows with the same joint readings (within `resolution`) and
    different markers share one; the k-th repeat of a (joints, marker) row belongs to the
    k-th pose of those joints.

    Parameters
    ----------
    q : ndarray, shape (N, n_joints)
        Joint readings.
    marker : ndarray of int, shape (N,), optional
        Marker of each row (None: one tool point, every row its own pose unless repeated).
    resolution : float
        Joint readings closer than this in every joint are the same.

    Returns
    -------
    group : ndarray of int, shape (N,)
        Pose of each row, numbered by first appearance.
    n_poses : int
    """
    q = np.asarray(q, dtype=float)
    n = q.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.intp), 0
    joints, _ = repeat_groups(q, resolution=resolution)
    m = np.zeros(n) if marker is None else np.asarray(marker, dtype=float)
    rows, _ = repeat_groups(joints[:, None].astype(float), m[:, None], resolution=0.0)
    # occurrence of each row among the rows with its joints and marker (0 for the first)
    order = np.argsort(rows, kind="stable")
    first = np.searchsorted(rows[order], rows[order], side="left")
    occurrence = np.empty(n, dtype=np.intp)
    occurrence[order] = np.arange(n) - first
    return repeat_groups(joints[:, None].astype(float), occurrence[:, None].astype(float),
                         resolution=0.0)


def pose_rows(group: NDArray[np.intp], n_poses: int) -> list[NDArray[np.intp]]:
    """The rows of each pose, in pose order (rows in file order within a pose)."""
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(np.asarray(group)[order], np.arange(n_poses + 1))
    return [order[bounds[g]:bounds[g + 1]] for g in range(n_poses)]


def pooled_norms(d: Array, group: NDArray[np.intp], n_poses: int, dof: int | Array = 3
                 ) -> tuple[Array, Array]:
    """Error norm and components of each pose from its rows'.

    Parameters
    ----------
    d : ndarray, shape (N,)
        Error norm of each row (of `dof` components each).
    group : ndarray of int, shape (N,)
        Pose of each row (`pose_groups`).
    n_poses : int
    dof : int or ndarray, shape (N,)
        Components per row.

    Returns
    -------
    norm : ndarray, shape (n_poses,)
        ``sqrt(sum d_i^2)`` over the pose's rows.
    dof : ndarray, shape (n_poses,)
        Their components in all.
    """
    d = np.asarray(d, dtype=float)
    k = np.broadcast_to(np.asarray(dof, dtype=float), d.shape)
    ss = np.bincount(group, weights=d * d, minlength=n_poses)
    return np.sqrt(ss), np.bincount(group, weights=k, minlength=n_poses)


def pose_outliers(d: Array, group: NDArray[np.intp] | None = None, n_poses: int | None = None,
                  dof: int | Array = 3) -> list[int]:
    """Rows of the poses whose pooled error is an outlier (`chi_outliers` on the poses'
    `pooled_norms`); every row of such a pose, in row order. Without `group` each row is
    its own pose."""
    d = np.asarray(d, dtype=float)
    if group is None:
        return chi_outliers(d, dof)
    n_poses = int(group.max()) + 1 if n_poses is None and d.size else int(n_poses or 0)
    norm, k = pooled_norms(d, group, n_poses, dof)
    bad = chi_outliers(norm, k)
    return [int(i) for i in np.flatnonzero(np.isin(group, bad))]


def _ranges(rows: Sequence[int]) -> str:
    """``81-83`` for consecutive rows, else ``4, 9``."""
    rows = sorted(int(r) for r in rows)
    if len(rows) > 1 and rows[-1] - rows[0] == len(rows) - 1:
        return f"{rows[0]}-{rows[-1]}"
    return ", ".join(str(r) for r in rows)


def describe_poses(rows: Sequence[int], group: NDArray[np.intp] | None,
                   limit: int = 10) -> tuple[int, str]:
    """The number of poses the `rows` make and the poses in words, by their 0-based rows:
    ``(1, "rows 81-83")`` for one pose of three markers, ``(2, "4, 9")`` for two poses of
    one row each (at most `limit` poses shown)."""
    rows = sorted(int(r) for r in rows)
    if group is None:
        shown = ", ".join(str(r) for r in rows[:limit])
        return len(rows), shown + (", ..." if len(rows) > limit else "")
    by_pose: dict[int, list[int]] = {}
    for r in rows:
        by_pose.setdefault(int(group[r]), []).append(r)
    poses = list(by_pose.values())
    if all(len(p) == 1 for p in poses):
        return describe_poses(rows, None, limit)
    shown = "; ".join("rows " + _ranges(p) if len(p) > 1 else f"row {p[0]}"
                      for p in poses[:limit])
    return len(poses), shown + ("; ..." if len(poses) > limit else "")
