"""Probe poses and leg readings of the Stewart-platform CMM (papers/004) as arrays.

A pose is the probe tip ``(x, y, z, alpha, beta, gamma)`` (length unit; radians in the
Python API, degrees in files and on the command line; ``R = Rz(gamma) Ry(beta) Rx(alpha)``,
see `kinecal.kinematics.stewart.platform`). Here: their checks (`as_poses`, `check_leg_readings`)
and conversions (`poses_from_rt`, `degrees_to_radians`, `radians_to_degrees`; the last
three are re-exported by `kinecal.kinematics.stewart.platform`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.spatial import rpy_from_matrix

__all__ = ["LEG_RANGE_SLACK", "as_poses", "check_leg_readings", "degrees_to_radians",
           "poses_from_rt",
           "radians_to_degrees"]

Array = NDArray[np.float64]

#: leg readings this share of the stroke outside `leg_range` are read (with the
#: ``leg-range`` warning: noise at the range's ends, a nominal range); further out refused
LEG_RANGE_SLACK = 0.01


def as_poses(poses: ArrayLike) -> Array:
    """Checked probe poses ``(..., 6)``: 6 finite columns (length unit, rad)."""
    x = np.asarray(poses, dtype=float)
    if x.shape[-1:] != (6,):
        raise InputError(f"poses must have 6 columns (x, y, z, alpha, beta, gamma), got {x.shape}")
    bad = ~np.isfinite(x).all(axis=-1)
    if bad.any():
        i = int(np.argmax(bad.reshape(-1)))
        raise InputError("poses must be finite numbers", row=i + 1)
    return x


def poses_from_rt(R: Array, t: Array) -> Array:
    """Poses ``(..., 6)`` (rad) from rotations ``(..., 3, 3)`` and tip positions ``(..., 3)``."""
    return np.concatenate([t, rpy_from_matrix(R)], axis=-1)


def degrees_to_radians(poses_deg: Sequence[float] | ArrayLike) -> Array:
    """Convert poses (x, y, z, alpha, beta, gamma in deg) to the API's radians."""
    x = np.array(poses_deg, dtype=float)
    x[..., 3:] = np.deg2rad(x[..., 3:])
    return x


def radians_to_degrees(poses: ArrayLike) -> Array:
    """Convert poses (angles in rad) to (x, y, z, alpha, beta, gamma in deg)."""
    x = np.array(poses, dtype=float)
    x[..., 3:] = np.rad2deg(x[..., 3:])
    return x


def check_leg_readings(legs: ArrayLike, leg_range: tuple[float, float], *,
                       file: str | None = None, row_offset: int = 1) -> Array:
    """Validate leg readings: shape ``(N, 6)``, finite, inside `leg_range`.

    Parameters
    ----------
    legs : array_like, shape (6,) or (N, 6)
        Leg readings (length unit).
    leg_range : (float, float)
        Admissible readings ``(l_min, l_max)`` (length unit).
    file : str, optional
        File name for the error message.
    row_offset : int
        Number of the first row in messages (1 = first data row).

    Returns
    -------
    ndarray, shape (N, 6)

    Raises
    ------
    InputError
        Naming the first bad row (readings more than `LEG_RANGE_SLACK` of the stroke
        outside the range; closer ones are read with the ``leg-range`` warning).
    """
    L = np.atleast_2d(np.asarray(legs, dtype=float))
    if L.ndim != 2 or L.shape[1] != 6:
        raise InputError(f"leg lengths must have 6 columns, got shape {L.shape}", file=file)
    bad = ~np.isfinite(L).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError("leg lengths must be finite numbers", file=file, row=i + row_offset)
    lo, hi = leg_range
    stroke = hi - lo if np.isfinite(hi) else max(abs(lo), 1.0)
    beyond = np.max(np.maximum(lo - L, L - hi), axis=1, initial=-np.inf)  # > 0: outside
    far = beyond > LEG_RANGE_SLACK * stroke
    if far.any():
        i = int(np.argmax(far))
        raise InputError(
            f"leg lengths {np.array2string(L[i], precision=6)} outside the leg range "
            f"[{lo:g}, {hi:g}] by more than {LEG_RANGE_SLACK:.0%} of the stroke (another "
            "unit, another leg order or another machine?)",
            file=file,
            row=i + row_offset,
        )
    near = beyond > 1e-12 * max(1.0, hi)
    if near.any():
        warn("leg-range",
             f"{int(near.sum())} of {L.shape[0]} rows"
             f"{'' if file is None else ' of ' + str(file)} read legs outside the leg range "
             f"[{lo:g}, {hi:g}], by up to {float(beyond.max()):.3g} (within "
             f"{LEG_RANGE_SLACK:.0%} of the stroke: solved as read, a nominal range is not "
             "the exact stroke)")
    return L
