"""Error and residual metrics of hand-eye solutions.

- `pose_error`: geodesic rotation error (deg) and translation error of an estimate
  against a known truth (synthetic data).
- `station_residuals`: without a truth, how consistently the stations map the target to
  one place: ``G_i X C_i`` should be the same pose ``Y`` for every station i (paper 001,
  sec. 2, eq. (1)); the per-station deviation from ``Y`` is the residual reported by
  `kinecal.calibrate_handeye` and by ``kinecal handeye``.
- `axxb_residuals`: the ``A X`` vs ``X B`` mismatch per motion pair (the quantity the
  paper's refinement fitness is built on); `axxb_station_rms` its rms per station.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.spatial import pose_errors, project_to_rotation, transform_from

Array = NDArray[np.float64]

__all__ = [
    "axxb_residuals",
    "axxb_station_rms",
    "mean_target_pose",
    "pose_error",
    "station_residuals",
]


def pose_error(X_est: Array, X_true: Array) -> tuple[float, float]:
    """Rotation (deg, geodesic) and translation (length unit) error of ``X_est`` vs truth.

    Parameters
    ----------
    X_est, X_true : ndarray, shape (4, 4)
        Estimated and true transforms.

    Returns
    -------
    (float, float)
        Angle of ``R_true^T R_est`` in degrees, ``|t_est - t_true|``.
    """
    r, t = pose_errors(X_est, X_true)
    return float(np.degrees(r)), float(t)


def target_poses(G: Array, X: Array, C: Array) -> Array:
    """Target pose ``G_i X C_i`` seen through every station, shape ``(n, 4, 4)``."""
    return G @ X @ C


def mean_target_pose(G: Array, X: Array, C: Array) -> Array:
    """Chordal mean ``(4, 4)`` of the target poses ``G_i X C_i`` (projected mean rotation)."""
    P = target_poses(G, X, C)
    return transform_from(project_to_rotation(P[:, :3, :3].mean(axis=0)), P[:, :3, 3].mean(axis=0))


def station_residuals(
    G: Array, X: Array, C: Array, Y: Array | None = None
) -> tuple[Array, Array]:
    """Per-station deviation of ``G_i X C_i`` from the target pose ``Y``.

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (eye-in-hand ``flange2base``, eye-to-hand ``base2flange``).
    X : ndarray, shape (4, 4)
        Hand-eye transform.
    C : ndarray, shape (n, 4, 4)
        ``target2cam`` poses.
    Y : ndarray, shape (4, 4), optional
        The fixed target pose (``target2base`` eye-in-hand, ``target2flange`` eye-to-hand);
        default `mean_target_pose`.

    Returns
    -------
    rotation_deg : ndarray, shape (n,)
        Geodesic angle between ``G_i X C_i`` and ``Y`` in degrees.
    translation : ndarray, shape (n,)
        Distance between their origins (length unit of the inputs).
    """
    if Y is None:
        Y = mean_target_pose(G, X, C)
    r, t = pose_errors(target_poses(G, X, C), Y)
    return np.degrees(r), t


def axxb_residuals(A: Array, B: Array, X: Array) -> tuple[Array, Array]:
    """Per-motion mismatch between ``A_k X`` and ``X B_k``.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions.
    X : ndarray, shape (4, 4)
        Hand-eye transform.

    Returns
    -------
    rotation_deg : ndarray, shape (m,)
        Geodesic angle between ``A_k X`` and ``X B_k`` (deg).
    translation : ndarray, shape (m,)
        Distance between their translations (length unit).
    """
    r, t = pose_errors(A @ X, X @ B)
    return np.degrees(r), t


def axxb_station_rms(G: Array, C: Array, X: Array,
                     motions: tuple[Array, Array] | None = None) -> tuple[Array, Array]:
    """Per-station rms of the ``A X - X B`` mismatch over all pairs (i, j) containing it.

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand).
    C : ndarray, shape (n, 4, 4)
        ``target2cam``.
    X : ndarray, shape (4, 4)
        Hand-eye transform.
    motions : (ndarray, ndarray), optional
        ``motion_pairs(G, C, "all")`` when the caller has them.

    Returns
    -------
    rotation_deg, translation : ndarray, shape (n,)
        Rms over the n - 1 pairs of each station (deg, length unit).
    """
    from kinecal.calibration.handeye._motions import motion_pairs, pair_indices

    n = len(G)
    i, j = pair_indices(n, "all")
    A, B = motion_pairs(G, C, "all") if motions is None else motions
    rot, tr = axxb_residuals(A, B, X)
    ij = np.concatenate([i, j])  # each pair counts for both of its stations
    sr = np.bincount(ij, weights=np.concatenate([rot**2, rot**2]), minlength=n)
    st = np.bincount(ij, weights=np.concatenate([tr**2, tr**2]), minlength=n)
    return np.sqrt(sr / (n - 1)), np.sqrt(st / (n - 1))


def rms(x: Array) -> float:
    """Root mean square of an array (0 for an empty one)."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0

