"""`Sweep`: forward kinematics of one parameter vector with the frames the Jacobian needs.

The identification Jacobian follows from the frames recorded before each motion: a
rotation about a unit axis ``u`` through ``o`` moves the tool point ``p`` by
``u x (p - o)`` per radian and turns the tool frame by ``u``; a translation along ``u``
moves it by ``u``. This holds for an axis of the moving frame and for a general (URDF)
axis alike, since the recorded ``u`` is the motion's axis in the fixed frame.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

if TYPE_CHECKING:
    from kinecal.kinematics.serial import SerialModel

__all__ = ["Sweep"]

Array = NDArray[np.float64]


class Sweep:
    """Result of `SerialModel.sweep`: tool poses and the frames before each motion.

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        Tool points in the measurement frame (length unit).
    rotations : ndarray, shape (N, 3, 3)
        Tool-frame orientations in the measurement frame.
    frames : list of (ndarray (3, N), ndarray (3, N))
        Axis of each motion and origin of the moving frame before it.
    """

    def __init__(self, model: SerialModel, o_end: Array, frames: list, R: Array) -> None:
        self.model = model
        self.positions = o_end  # (N, 3)
        self.rotations = R  # (N, 3, 3): tool frame orientation in the measurement frame
        self.frames = frames

    def joint_jacobian_t(self, outputs: str = "pose") -> Array:
        """Geometric Jacobian ``(n_joints, 6 or 3, N)`` with respect to the joint readings.

        A joint's reading adds to the value of one motion of the chain, so its column is
        that motion's parameter column of `jacobian_t` (a rotation for a revolute joint,
        a translation for a prismatic one).
        """
        return self.jacobian_t(outputs, columns=self.model._joint_columns)

    def jacobian_t(self, outputs: str = "position", columns: ArrayLike | None = None) -> Array:
        """Identification Jacobian ``(n, 3 or 6, N)`` (see
        `SerialModel.identification_jacobian`).

        `columns` (parameter indices) restricts the rows to those parameters, in that
        order; only their motions are differentiated.
        """
        if outputs not in ("position", "pose"):
            raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
        model = self.model
        cols = np.arange(model.n_params) if columns is None else np.asarray(columns)
        row_of = np.full(model.n_params, -1)
        row_of[cols] = np.arange(cols.size)
        p_end = self.positions.T  # (3, N)
        rows = 3 if outputs == "position" else 6
        Jt = np.zeros((cols.size, rows, p_end.shape[1]))
        for (u, o), k, is_rot in zip(self.frames, model._motion_index, model._rotation_mask,
                                     strict=True):
            r_ = row_of[k]
            if r_ < 0:
                continue
            if not is_rot:  # a translation moves the point along its axis
                Jt[r_, :3] = u
                continue
            d = p_end - o  # a rotation about u through o: u x (p - o)
            Jt[r_, 0] = u[1] * d[2] - u[2] * d[1]
            Jt[r_, 1] = u[2] * d[0] - u[0] * d[2]
            Jt[r_, 2] = u[0] * d[1] - u[1] * d[0]
            if rows == 6:
                Jt[r_, 3:] = u
        return Jt
