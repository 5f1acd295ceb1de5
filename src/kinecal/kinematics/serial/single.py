"""One pose at a time: a serial chain folded into constant transforms and joint motions.

A controller asking for one corrected target, or an inverse-kinematics step, calls forward
kinematics for a single configuration; the chunked batch kernels of
`kinecal.kinematics.serial.compose` then spend their time on per-call set-up that does not
scale with the work. For one parameter vector the chain is

    C_0 J_1(q_1) C_1 J_2(q_2) ... J_n(q_n) C_n

with ``C_k`` the constant transform of the motions between two joints (base frame, D-H
offsets, fixed frames, tool) and ``J_k`` the joint's own motion: a rotation by
``value + q_k`` about an axis of the moving frame (or a unit direction), or a translation
along it. `SingleChain` computes the ``C_k`` once (with the batch kernels, so they mean
exactly what the batch path composes) and writes each ``J_k`` as
``A_k + cos(t_k) B_k + sin(t_k) S_k + t_k D_k`` with constant 4 x 4 matrices (Rodrigues:
``R = I + sin t K + (1 - cos t) K^2``), so a pose costs a few numpy calls on ``(n, 4, 4)``
stacks and one product per joint. Results agree with the batch path to round-off (1e-12
relative; tests/kinematics).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.compose import transforms
from kinecal.kinematics.serial.motions import ROTATION, Motion

__all__ = ["SingleChain"]

Array = NDArray[np.float64]
_NEXT, _PREV = [1, 2, 0], [2, 0, 1]  # (u x a)_k = u_{k+1} a_{k+2} - u_{k+2} a_{k+1}


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
        after = np.stack(consts[1:])  # (n, 4, 4): the constant after each joint
        n = n_joints
        A, B, S, D = (np.zeros((n, 4, 4)) for _ in range(4))
        self.offset = np.zeros(n)
        self.axis = np.zeros((n, 3))  # each joint's axis in the frame before its motion
        self.revolute = np.zeros(n, bool)
        for j, i in enumerate(order):
            m = motions[i]
            u = np.eye(3)[m.axis] if m.direction is None else np.asarray(m.direction, float)
            self.axis[j] = u
            self.revolute[j] = m.kind == ROTATION
            self.offset[j] = self.p[motion_index[i]]
            A[j] = np.eye(4)
            if m.kind == ROTATION:
                K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
                K2 = K @ K
                A[j, :3, :3] += K2  # R = I + K^2 - cos t K^2 + sin t K
                B[j, :3, :3] = -K2
                S[j, :3, :3] = K
            else:
                D[j, :3, 3] = u  # a translation by t along u
        # each joint's motion times the constant after it: J_k(t) C_k
        self.A, self.B, self.S = A @ after, B @ after, S @ after
        self.D = D @ after if D.any() else None

    def _motions(self, q: Array) -> Array:
        """``J_k(q_k) C_k`` for every joint ``(n, 4, 4)``."""
        t = q + self.offset
        M = self.A + np.cos(t)[:, None, None] * self.B
        M += np.sin(t)[:, None, None] * self.S
        if self.D is not None:
            M += t[:, None, None] * self.D
        return M

    def transform(self, q: Array) -> Array:
        """``tool2base`` ``(4, 4)`` at one configuration `q` ``(n_joints,)`` (checked)."""
        M = self._motions(q)
        n = len(M)
        P = M[0:n - 1:2] @ M[1:n:2]  # neighbours multiplied pairwise in one call
        T = self.first
        for Pk in P:
            T = T @ Pk
        return T @ M[-1] if n % 2 else T

    def transform_and_jacobian(self, q: Array, outputs: str = "pose") -> tuple[Array, Array]:
        """``tool2base`` ``(4, 4)`` and the geometric joint Jacobian ``(6 or 3, n_joints)``
        (``outputs`` ``"pose"``: d(x, y, z) and the small rotation of the tool frame in the
        measurement frame; ``"position"``: d(x, y, z)), as `SerialModel.joint_jacobian`."""
        M = self._motions(q)
        n = len(M)
        before = np.empty((n, 4, 4))  # the frame each joint's motion acts in
        T = self.first
        for k in range(n):
            before[k] = T
            T = T @ M[k]
        u = np.einsum("kij,kj->ki", before[:, :3, :3], self.axis)  # axes, measurement frame
        arm = T[:3, 3] - before[:, :3, 3]
        cross = u[:, _NEXT] * arm[:, _PREV] - u[:, _PREV] * arm[:, _NEXT]  # u x (p - o)
        lin = np.where(self.revolute[:, None], cross, u)  # or u for a translation
        J = np.zeros((6 if outputs == "pose" else 3, n))
        J[:3] = lin.T
        if outputs == "pose":
            J[3:] = (u * self.revolute[:, None]).T
        return T, J
