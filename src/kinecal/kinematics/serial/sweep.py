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
from kinecal.kinematics.serial.compose import chunks, frame_chain

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["JACOBIAN_ELEMENTS", "Sweep", "chunked_jacobian_t"]

Array = NDArray[np.float64]
#: poses per chunk of the Jacobian sweeps (the frames before every motion are kept)
JACOBIAN_ELEMENTS = 2048


def chunked_jacobian_t(model: SerialModel, q: Array, p: Array, outputs: str = "position",
                       columns: ArrayLike | None = None, marker: Array | None = None) -> Array:
    """Identification Jacobian ``(k, 3 or 6, N)`` of `columns` (default all parameters),
    one `Sweep` per chunk of `JACOBIAN_ELEMENTS` poses (see
    `SerialModel.jacobian_t`; `marker`: per-pose marker indices, checked)."""
    if outputs not in ("position", "pose"):
        raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
    cols = np.arange(model.n_params) if columns is None else np.asarray(columns)
    out = np.zeros((cols.size, 6 if outputs == "pose" else 3, q.shape[0]))
    for sel, (axes, o, frames) in chunks(model.motions, model._motion_index,
                                         model._corrected(q, p), p, frame_chain, True,
                                         elements=JACOBIAN_ELEMENTS,
                                         pose_values=model._pose_values(marker, p)):
        Sweep(model, axes, o, frames, sel.stop - sel.start, q[sel], p,
              None if marker is None else marker[sel]).jacobian_t(outputs, cols,
                                                                  out=out[..., sel])
    return out


class Sweep:
    """Result of `SerialModel.sweep`: tool poses and the frames before each motion.

    Parameters
    ----------
    model : SerialModel
    axes : list of 3 lists of 3
        Tool frame axes (``axes[a][k]``: component k of axis a), arrays ``(N,)`` or floats
        (`kinecal.kinematics.serial.compose.frame_chain`).
    origin : list of 3
        Tool point coordinates, arrays ``(N,)`` or floats.
    frames : list of (list of 3, list of 3)
        Axis of each motion and origin of the moving frame before it, as coordinates.
    n : int
        Number of poses N.
    q, p : ndarray, optional
        Raw joint readings ``(N, n_joints)`` and the parameter vector, for the chain rule
        through joint-error corrections (`kinecal.kinematics.serial.joint_errors`).
    marker : ndarray, shape (N,), optional
        Marker index per pose (models with several markers).

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        Tool points in the measurement frame (length unit).
    rotations : ndarray, shape (N, 3, 3)
        Tool-frame orientations in the measurement frame (built on first use).
    """

    def __init__(self, model: SerialModel, axes: list, origin: list, frames: list, n: int,
                 q: Array | None = None, p: Array | None = None,
                 marker: NDArray[np.intp] | None = None) -> None:
        self.model = model
        self.marker = marker
        self.q, self.p = q, p
        self.frames = frames
        self._axes = axes
        self._origin = origin
        self.n = n
        P = np.empty((n, 3))
        for k in range(3):
            P[:, k] = origin[k]
        self.positions = P
        self._rotations: Array | None = None

    @property
    def rotations(self) -> Array:
        """Tool-frame orientations ``(N, 3, 3)`` in the measurement frame."""
        if self._rotations is None:
            R = np.empty((self.n, 3, 3))
            for a in range(3):
                for k in range(3):
                    R[:, k, a] = self._axes[a][k]
            self._rotations = R
        return self._rotations

    def joint_jacobian_t(self, outputs: str = "pose") -> Array:
        """Geometric Jacobian ``(n_joints, 6 or 3, N)`` with respect to the joint readings.

        A joint's reading adds to the value of one motion of the chain, so its column is
        that motion's parameter column of `jacobian_t` (a rotation for a revolute joint,
        a translation for a prismatic one).
        """
        Jt = self.jacobian_t(outputs, columns=self.model._joint_columns)
        terms = self.model._joint_terms
        if terms is None:
            return Jt
        return terms.through_corrections(Jt, self.q, self.p[self.model._n_geometric:])

    def jacobian_t(self, outputs: str = "position", columns: ArrayLike | None = None,
                   out: Array | None = None) -> Array:
        """Identification Jacobian ``(n, 3 or 6, N)`` (see
        `SerialModel.identification_jacobian`).

        `columns` (parameter indices) restricts the rows to those parameters, in that
        order; only their motions are differentiated. `out`: a zero-filled array of the
        result's shape to write into.
        """
        if outputs not in ("position", "pose"):
            raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
        model = self.model
        cols = np.arange(model.n_params) if columns is None else np.asarray(columns)
        n_geo = model._n_geometric
        if (cols >= n_geo).any():  # joint-error coefficients: chain rule through dq / dc
            Jq = self.jacobian_t(outputs, columns=model._joint_columns)
            Jt = np.zeros((cols.size, Jq.shape[1], self.n)) if out is None else out
            geo = cols < n_geo
            Jt[geo] = self.jacobian_t(outputs, columns=cols[geo])
            Jt[~geo] = model._joint_terms.chain_rule_t(Jq, self.q, cols[~geo] - n_geo)
            return Jt
        row_of = np.full(model.n_params, -1)
        row_of[cols] = np.arange(cols.size)
        p_end = self._origin
        rows = 3 if outputs == "position" else 6
        Jt = np.zeros((cols.size, rows, self.n)) if out is None else out
        last_o = d = None
        for (u, o), k, is_rot in zip(self.frames, model._motion_index, model._rotation_mask,
                                     strict=True):
            r_ = row_of[k] if k >= 0 else -1  # k < 0: a constant motion, no parameter
            if r_ < 0:
                continue
            J = Jt[r_]
            if not is_rot:  # a translation moves the point along its axis
                J[0], J[1], J[2] = u
                continue
            if o is not last_o:  # rotations keep the origin: consecutive ones share p - o
                d = [p_end[i] - o[i] for i in range(3)]
                last_o = o
            _cross_into(J, u, d)  # a rotation about u through o moves p by u x (p - o)
            if rows == 6:
                J[3], J[4], J[5] = u
        if model._marker_set is not None:  # tool points per marker: columns masked by marker
            marker = np.zeros(self.n, np.intp) if self.marker is None else self.marker
            model._marker_set.fill_jacobian(Jt, self.frames, row_of, marker)
        return Jt


def _cross_into(J: Array, u, d) -> None:
    """``J[0:3] = u x d`` for coordinate triples (floats or arrays ``(n,)``), written in
    place (no temporaries for the results)."""
    for i, (a, b) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.multiply(u[a], d[b], out=J[i])
        J[i] -= u[b] * d[a]
