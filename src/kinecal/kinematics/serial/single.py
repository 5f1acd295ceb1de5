"""One pose at a time: a serial chain folded into constant transforms and joint motions.

A controller asking for one corrected target, or an inverse-kinematics step, calls forward
kinematics for a single configuration; the chunked batch kernels of
`kinecal.kinematics.serial.compose` then spend their time on per-call set-up that does not
scale with the work. For one parameter vector the chain is

    C_0 J_1(q_1) C_1 J_2(q_2) ... J_n(q_n) C_n

with ``C_k`` the constant transform of the motions between two joints (base frame, D-H
offsets, fixed frames, tool) and ``J_k`` the joint's own motion: a rotation by
``value + q_k`` about a unit axis of the moving frame, or a translation along it.
`SingleChain` computes the ``C_k`` once (with the batch kernels, so they mean exactly what
the batch path composes) and writes the chain out as straight-line Python on floats
(`kinecal.kinematics.serial.unrolled`): a pose of a six-joint arm costs about 1.5 us of
arithmetic and one array. Results agree with the batch path to round-off (1e-12 relative;
tests/kinematics/test_single_pose.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.compose import transforms
from kinecal.kinematics.serial.motions import ROTATION, Motion
from kinecal.kinematics.serial.unrolled import unroll

__all__ = ["SingleChain"]

Array = NDArray[np.float64]


class SingleChain:
    """The chain of one parameter vector, ready for single configurations.

    Parameters
    ----------
    motions : sequence of Motion
        The model's chain (`SerialModel.motions`).
    motion_index : ndarray of int, shape (m,)
        Parameter index of each motion.
    n_joints : int
    p : ndarray, shape (n_params,)
        The parameter vector (copied).
    """

    def __init__(self, motions: Sequence[Motion], motion_index: NDArray[np.intp],
                 n_joints: int, p: Array) -> None:
        self.p = np.array(p, dtype=float)
        joint_at = {m.joint: i for i, m in enumerate(motions) if m.joint is not None}
        order = [joint_at[j] for j in range(n_joints)]
        cuts = [-1, *order, len(motions)]
        q0 = np.zeros((1, n_joints))
        consts = []
        for a, b in pairwise(cuts):  # the motions strictly between two joints
            sub = list(motions[a + 1:b])
            consts.append(transforms(sub, motion_index[a + 1:b], q0, self.p)[0] if sub
                          else np.eye(4))
        self.first = consts[0]
        self.after = np.stack(consts[1:])  # (n, 4, 4): the constant after each joint
        self.offset = np.zeros(n_joints)
        self.axis = np.zeros((n_joints, 3))  # each joint's axis in the frame before it
        self.revolute = np.zeros(n_joints, bool)
        for j, i in enumerate(order):
            m = motions[i]
            self.axis[j] = (np.eye(3)[m.axis] if m.direction is None
                            else np.asarray(m.direction, float))
            self.revolute[j] = m.kind == ROTATION
            self.offset[j] = self.p[motion_index[i]]
        self._unrolled: dict = {}

    def unrolled(self, jacobian: str | None = None):
        """The chain as straight-line Python (`kinecal.kinematics.serial.unrolled`):
        ``f(q_1, ..., q_n)`` -> the tool frame's 3 x 4 entries (and the Jacobian's), built
        on first use."""
        f = self._unrolled.get(jacobian)
        if f is None:
            f = self._unrolled[jacobian] = unroll(self.first, self.after, self.axis,
                                                  self.revolute, self.offset, jacobian)
        return f

    def transform(self, q: list[float]) -> Array:
        """``tool2base`` ``(4, 4)`` at one configuration `q` (``n_joints`` floats,
        checked), from the unrolled chain."""
        return np.array(self.unrolled()(*q) + _LAST_ROW).reshape(4, 4)

    def position(self, q: list[float]) -> Array:
        """The tool point ``(3,)`` at one configuration `q` (floats, checked)."""
        v = self.unrolled()(*q)
        return np.array((v[3], v[7], v[11]))

    def transform_and_jacobian(self, q: list[float], outputs: str = "pose"
                               ) -> tuple[Array, Array]:
        """``tool2base`` ``(4, 4)`` and the geometric joint Jacobian ``(6 or 3, n_joints)``
        (``outputs`` ``"pose"``: d(x, y, z) and the small rotation of the tool frame in the
        measurement frame; ``"position"``: d(x, y, z)), as `SerialModel.joint_jacobian`."""
        v = self.unrolled(outputs)(*q)
        return (np.array(v[:12] + _LAST_ROW).reshape(4, 4),
                np.array(v[12:]).reshape(6 if outputs == "pose" else 3, len(self.offset)))


_LAST_ROW = (0.0, 0.0, 0.0, 1.0)
