"""The checks of `kinecal.kinematics.serial.ik.solve_ik`'s targets and seed joints: bad
shapes, non-finite values and non-rigid frames are refused with what was expected (one
frame and one seed on floats: a controller asking for one target pays microseconds)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.spatial import check_transform

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["check_seed", "check_targets"]

Array = NDArray[np.float64]


def _frame_ok(T: list[list[float]], tol: float = 1e-6) -> bool:
    """`kinecal.spatial.check_transform`'s tests of one frame on floats (False: let it
    say what is wrong)."""
    if not all(math.isfinite(x) for row in T for x in row):
        return False
    if max(abs(T[3][0]), abs(T[3][1]), abs(T[3][2]), abs(T[3][3] - 1.0)) > tol:
        return False
    (a, b, c, _), (d, e, f, _), (g, h, i, _) = T[:3]
    cols = ((a, d, g), (b, e, h), (c, f, i))
    for j in range(3):
        for k in range(j, 3):
            dot = cols[j][0] * cols[k][0] + cols[j][1] * cols[k][1] + cols[j][2] * cols[k][2]
            if abs(dot - (1.0 if j == k else 0.0)) > tol:
                return False
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) > 0.0


def check_targets(targets: ArrayLike) -> Array:
    t = np.asarray(targets, dtype=float)
    if t.shape == (4, 4) and _frame_ok(t.tolist()):  # one frame: checked on floats
        return t[None]
    if t.ndim == 1 and t.shape == (3,):
        t = t[None]
    elif t.shape == (4, 4):
        t = t[None]
    if not ((t.ndim == 2 and t.shape[1] == 3) or (t.ndim == 3 and t.shape[1:] == (4, 4))):
        raise InputError(f"targets: expected positions (N, 3) or tool frames (N, 4, 4), "
                         f"got shape {t.shape}")
    if not np.isfinite(t).all():
        raise InputError("targets contain NaN or infinite values")
    if t.ndim == 3:
        check_transform(t, name="target")
    return t


def check_seed(model: SerialModel, q0: ArrayLike | None, n: int) -> Array:
    lim = np.asarray(model.joint_limits, dtype=float)
    if q0 is None:
        return np.tile(0.5 * (lim[:, 0] + lim[:, 1]), (n, 1))
    q = np.asarray(q0, dtype=float)
    if q.ndim == 1:
        q = q[None].copy() if n == 1 else np.tile(q, (n, 1))
    if q.shape != (n, model.n_joints):
        raise InputError(f"q0: expected ({n}, {model.n_joints}) or ({model.n_joints},) seed "
                         f"joints, got {np.shape(q0)}")
    if not (all(map(math.isfinite, q.ravel().tolist())) if q.size <= 64
            else np.isfinite(q).all()):
        raise InputError("q0 contains NaN or infinite values")
    return q
