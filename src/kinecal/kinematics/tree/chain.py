"""`PathChain`: one chain of a system (root to a link or a tip) on the system's parameters.

A chain is a serial chain of elementary motions, so its forward kinematics and its
identification Jacobian are those of `kinecal.kinematics.serial` (`SerialKinematics`: the
chunked kernels, `Sweep`); what differs is the bookkeeping. The chain's motions index the
*system's* parameter vector directly (``_motion_index``), so that the Jacobian columns of
two chains through one element are the same columns and ``jacobian_t(columns=...)`` of any
system parameters is zero where the chain does not reach them.

The chain's joint readings come from the system's: chain joint ``j`` reads system joint
``source[j]`` times a multiplier (1, or the ``JOINT.multiplier`` parameter of a coupled
joint, `kinecal.kinematics.tree.elements`). The derivative with respect to a multiplier is
the joint's column times the leader's reading.

A chain may end in a per-row point (``point=True``): three translations whose values are
given per row (a point fixed in the last link, e.g. an unknown socket on a positioner's
table), placed at three slots after the system's parameters; their Jacobian columns are the
link's axes, i.e. the derivative with respect to the point.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.kinematics import SerialKinematics
from kinecal.kinematics.serial.motions import ROTATION, TRANSLATION, Motion

__all__ = ["PathChain"]

Array = NDArray[np.float64]
_POINT = ("x", "y", "z")


class PathChain(SerialKinematics):
    """A chain of a system (module docstring).

    Parameters
    ----------
    name : str
        What the chain ends at (messages).
    motions : sequence of Motion
        Root to end; each moving motion's ``joint`` is its chain joint index.
    index : ndarray of int, shape (m,)
        System parameter index of each motion.
    n_params : int
        Length of the system's parameter vector.
    source : ndarray of int, shape (n_joints,)
        System joint read by each chain joint.
    multiplier : ndarray of int, shape (n_joints,)
        System parameter index of each chain joint's multiplier, -1 for none.
    point : bool
        End in a per-row point (three more slots, module docstring).
    """

    def __init__(self, name: str, motions: Sequence[Motion], index: NDArray[np.intp],
                 n_params: int, source: NDArray[np.intp], multiplier: NDArray[np.intp],
                 point: bool = False) -> None:
        motions = list(motions)
        index = np.asarray(index, dtype=np.intp)
        if point:
            motions += [Motion(TRANSLATION, k, f"point.{c}", key=c) for k, c in enumerate(_POINT)]
            index = np.r_[index, n_params + np.arange(3)]
            n_params += 3
        self.name = name
        self.motions = motions
        self.n_params = n_params
        self.n_joints = len(source)
        self.source = np.asarray(source, dtype=np.intp)
        self.multiplier = np.asarray(multiplier, dtype=np.intp)
        self.coupled = bool((self.multiplier >= 0).any())
        self.point = point
        self._motion_index = index
        self._rotation_mask = np.array([m.kind == ROTATION for m in motions])
        self._n_geometric = n_params
        self._joint_terms = None
        self._marker_set = None
        self._nominal = np.zeros(n_params)
        cols = {m.joint: int(index[i]) for i, m in enumerate(motions) if m.joint is not None}
        self._joint_columns = np.array([cols[j] for j in range(self.n_joints)], dtype=np.intp)
        self._point_values: Array | None = None
        #: the parameter indices the chain reaches (its motions' and its multipliers')
        self.reach = np.unique(np.r_[index, self.multiplier[self.multiplier >= 0]])

    def columns_of(self, cols: NDArray[np.intp]) -> NDArray[np.intp]:
        """Positions in `cols` of the parameters this chain reaches (the others' rows of
        its Jacobian are zero)."""
        return np.flatnonzero(np.isin(cols, self.reach))

    # ------------------------------------------------------------------ readings
    def chain_q(self, q: Array, p: Array) -> Array:
        """Chain joint readings ``(N, n_joints)`` from system readings ``(N, n_sys)`` at one
        parameter vector `p` (the multipliers of coupled joints applied)."""
        qc = q[:, self.source]
        if self.coupled:
            mult = np.where(self.multiplier >= 0, p[..., np.maximum(self.multiplier, 0)], 1.0)
            qc = qc * mult
        return qc

    def multiplier_rows(self, Jt: Array, cols: NDArray[np.intp], q: Array, p: Array,
                        jac) -> None:
        """Add the multiplier columns of `cols` to `Jt` ``(k, rows, N)`` in place.

        `jac(columns)` gives the chain's Jacobian ``(c, rows, N)`` of the parameter indices
        `columns` at the same readings; the column of joint j's multiplier is that of j's
        joint motion times the leader's reading ``q[:, source[j]]``.
        """
        if not self.coupled:
            return
        pos = {int(c): r for r, c in enumerate(cols)}
        joints = [j for j in range(self.n_joints) if int(self.multiplier[j]) in pos]
        if not joints:
            return
        Jq = jac(self._joint_columns[joints])
        for k, j in enumerate(joints):
            Jt[pos[int(self.multiplier[j])]] += Jq[k] * q[:, self.source[j]]

    # ------------------------------------------------------------------ per-row point
    def with_points(self, points: Array) -> PathChain:
        """A copy of this chain (``point=True``) with the per-row point values ``(N, 3)``
        (in its last link's frame, length unit), which the kinematics read through
        `_pose_values`."""
        out = copy.copy(self)
        out._point_values = np.asarray(points, dtype=float)
        return out

    def _marker(self, marker, n):  # no markers: the per-row values are the point's
        return None if self._point_values is None else np.arange(n)

    def _pose_values(self, marker, p: Array) -> dict | None:
        if self._point_values is None or marker is None:
            return None
        base = len(self.motions) - 3
        P = self._point_values[marker]
        return {base + k: np.broadcast_to(P[:, k], (*p.shape[:-1], len(P)))
                for k in range(3)}

    def point_vector(self, p: Array) -> Array:
        """`p` extended by the point's three slots (zeros: the values are per row)."""
        if not self.point:
            return p
        return np.concatenate([p, np.zeros((*p.shape[:-1], 3))], axis=-1)
