"""Joint moves out of proportion to the correction they make: near-singular rows that the
condition number alone misses.

A compensated row whose inverse kinematics converged at a condition number of 552 (below
the ``near-singular`` threshold of 1e3) turned the UR5's wrist joints 4 and 6 by 146 deg in
opposite senses for a 1.5 mm correction: the arm is where it should be, but the robot
would swing its wrist through half a turn to get there. The *joint-move gain* of a row
compares its largest revolute joint move with the Cartesian correction it makes::

    gain = L * max |dq_revolute| / (correction + L * correction_rotation)

with ``L`` the arm's characteristic length (`kinecal.kinematics.serial.ik
.characteristic_length`), so that a joint turning by ``dq`` moves a tool ``L`` away by
about ``L dq``. A well-conditioned row has a gain of a few units (UR5, random
configurations: median 1.5); rows above `JOINT_MOVE_GAIN` are marked ``near-singular``
like those above the condition-number threshold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.ik import characteristic_length
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["JOINT_MOVE_GAIN", "joint_move_gain", "mark_large_moves"]

Array = NDArray[np.float64]

#: gain above which a converged row is near-singular: 50 times the joint move a
#: well-conditioned arm needs for the correction (UR5, random configurations: 0.9 % of the
#: rows the condition number leaves at "converged")
JOINT_MOVE_GAIN = 50.0


def joint_move_gain(model: SerialModel, dq: Array, correction: Array,
                    correction_rotation: Array) -> Array:
    """Per row: the joint-move gain (module docstring) ``(N,)``; 0 for an arm without
    revolute joints or a row without a joint move.

    Parameters
    ----------
    model : SerialModel
        The nominal model (its characteristic length, its revolute joints).
    dq : ndarray, shape (N, n_joints)
        Joint corrections (rad for revolute joints).
    correction : ndarray, shape (N,)
        Cartesian size of the correction (length unit).
    correction_rotation : ndarray, shape (N,)
        Its angle (rad; NaN for position-only compensation).
    """
    rev = ~model.is_prismatic()
    if not rev.any():
        return np.zeros(len(correction))
    L = characteristic_length(model)
    move = L * np.abs(np.asarray(dq, dtype=float)[:, rev]).max(axis=1)
    size = np.asarray(correction, dtype=float) + L * np.nan_to_num(
        np.asarray(correction_rotation, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(move > 0, move / np.maximum(size, np.finfo(float).tiny), 0.0)
    return gain


def mark_large_moves(model: SerialModel, status: NDArray[np.str_], dq: Array,
                     correction: Array, correction_rotation: Array) -> NDArray[np.str_]:
    """`status` with ``converged`` rows whose joint-move gain exceeds `JOINT_MOVE_GAIN`
    marked ``near-singular`` (a copy)."""
    gain = joint_move_gain(model, dq, correction, correction_rotation)
    out = np.array(status, copy=True)
    out[(out == "converged") & (gain > JOINT_MOVE_GAIN)] = "near-singular"
    return out
