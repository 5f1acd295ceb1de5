"""Forward kinematics and derivatives of a serial arm: the `SerialKinematics` half of
`kinecal.kinematics.serial.model.SerialModel`.

Forward kinematics composes the chain's elementary motions over cache-sized chunks of poses
(and a whole population of parameter vectors at once), without Python loops over poses or
parameter vectors (`kinecal.kinematics.serial.compose`: positions from the tool point backwards,
frames forwards). The identification Jacobian follows from the frames of the forward sweep
(`kinecal.kinematics.serial.sweep`): a rotation about a unit axis ``u`` through ``o`` moves the
tool point ``p`` by ``u x (p - o)`` per radian, a translation along ``u`` moves it by ``u``.

These methods are the hot paths of every calibration (``benchmarks/bench_fk.py``,
``bench_calibration.py``); `SerialModel` inherits them, so a call costs no extra
indirection.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.compose import chunks, frame_chain, positions, transforms
from kinecal.kinematics.serial.markers import check_marker
from kinecal.kinematics.serial.single import SingleChain
from kinecal.kinematics.serial.sweep import Sweep, chunked_jacobian_t

__all__ = ["SerialKinematics"]

Array = NDArray[np.float64]


class SerialKinematics:
    """Forward kinematics, identification and joint Jacobians, and sweeps of a serial arm.

    A base class of `kinecal.kinematics.serial.model.SerialModel`, which sets up what these
    methods read: ``motions``, ``n_joints``, ``n_params``, ``name`` and the private
    parameter bookkeeping (``_nominal``, ``_motion_index``, ``_joint_columns``,
    ``_n_geometric``, ``_joint_terms``, ``_marker_set``). Not used on its own.
    """

    def _marker(self, marker: ArrayLike | None, n: int) -> NDArray[np.intp] | None:
        """Checked per-pose marker indices (None for a model with one tool point)."""
        return check_marker(self, marker, n)

    def _pose_values(self, marker: NDArray[np.intp] | None, p: Array) -> dict | None:
        return None if marker is None else self._marker_set.pose_values(marker, p)


    def _check_params(self, params: ArrayLike | None) -> Array:
        if params is None:
            return self._nominal
        p = np.asarray(params, dtype=float)
        if p.shape[-1:] != (self.n_params,) or p.ndim > 2:
            raise InputError(
                f"parameters: expected shape ({self.n_params},) or (P, {self.n_params}), "
                f"got {p.shape}"
            )
        return p

    def _check_q(self, q: ArrayLike) -> Array:
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InputError(
                f"joint values: expected shape (N, {self.n_joints}), got {np.shape(q)}"
            )
        if not np.isfinite(q).all():
            raise InputError("joint values contain NaN or infinite entries")
        return q

    def fk(self, q: ArrayLike, params: ArrayLike | None = None,
           marker: ArrayLike | None = None) -> Array:
        """Tool (or flange) frame in the measurement frame.

        Parameters
        ----------
        q : array_like, shape (N, n_joints) or (n_joints,)
            Joint angles (rad).
        params : array_like, shape (n_params,) or (P, n_params), optional
            Parameter vector(s); nominal if omitted.
        marker : array_like of int, shape (N,), optional
            Models with several markers: the marker index of each pose (into
            `marker_names`; default the first marker).

        Returns
        -------
        ndarray, shape (N, 4, 4) or (P, N, 4, 4)
            ``tool2base`` transforms (lengths in the model unit).
        """
        one = self._single(q, params, marker)
        if one is not None:  # one configuration: the folded chain (`single`)
            return one[0].transform(one[1])[None]
        q, p = self._check_q(q), self._check_params(params)
        if self._joint_terms is not None and p.ndim == 2:  # corrections differ per vector
            return np.stack([self.fk(q, row, marker) for row in p])
        return transforms(self.motions, self._motion_index, self._corrected(q, p), p,
                          pose_values=self._pose_values(self._marker(marker, len(q)), p))

    def positions(self, q: ArrayLike, params: ArrayLike | None = None,
                  marker: ArrayLike | None = None) -> Array:
        """Tool-point positions ``(N, 3)`` or ``(P, N, 3)``; see `fk`.

        Composed from the tool point backwards, chunk by chunk: no rotation stacks.
        """
        one = self._single(q, params, marker)
        if one is not None:
            return one[0].position(one[1])[None]
        q, p = self._check_q(q), self._check_params(params)
        if self._joint_terms is not None and p.ndim == 2:  # corrections differ per vector
            return np.stack([self.positions(q, row, marker) for row in p])
        return positions(self.motions, self._motion_index, self._corrected(q, p), p,
                         pose_values=self._pose_values(self._marker(marker, len(q)), p))

    def identification_jacobian(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "position",
        marker: ArrayLike | None = None,
    ) -> Array:
        """Analytic derivative of the tool pose with respect to every parameter.

        Parameters
        ----------
        q : array_like, shape (N, n_joints)
            Joint angles (rad).
        params : array_like, shape (n_params,), optional
            Parameter vector; nominal if omitted.
        outputs : {"position", "pose"}
            ``position``: d(x, y, z); ``pose``: additionally the small-rotation vector of the
            tool frame expressed in the measurement frame (rad per unit parameter).
        marker : array_like of int, shape (N,), optional
            Marker index per pose (see `fk`).

        Returns
        -------
        ndarray, shape (N, 3, n_params) or (N, 6, n_params)
            Length unit per length unit for lengths, length unit per rad for angles.
        """
        Jt = self.jacobian_t(q, params, outputs, marker=marker)
        return np.ascontiguousarray(Jt.transpose(2, 1, 0))

    def jacobian_t(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "position",
        columns: ArrayLike | None = None, marker: ArrayLike | None = None,
    ) -> Array:
        """`identification_jacobian` in parameter-major layout ``(n_params, 3 or 6, N)``.

        Cheaper for solvers that select parameter rows before reshaping; `columns`
        (parameter indices) keeps only those rows, in that order. Built chunk by chunk.
        """
        q = self._check_q(q)
        return chunked_jacobian_t(self, q, self._one_vector(params), outputs, columns,
                                  self._marker(marker, len(q)))

    def joint_jacobian(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "pose",
        marker: ArrayLike | None = None,
    ) -> Array:
        """Derivative of the tool pose with respect to the joint readings.

        Parameters
        ----------
        q : array_like, shape (N, n_joints)
            Joint readings (rad).
        params : array_like, shape (n_params,), optional
            Parameter vector; nominal if omitted.
        outputs : {"pose", "position"}
            ``pose``: d(x, y, z) and the small-rotation vector of the tool frame in the
            measurement frame; ``position``: d(x, y, z) only.

        Returns
        -------
        ndarray, shape (N, 6, n_joints) or (N, 3, n_joints)
            The geometric Jacobian: length unit per rad (and rad per rad) for a revolute
            joint.
        """
        q, p = self._check_q(q), self._one_vector(params)
        Jt = self.jacobian_t(q, p, outputs, columns=self._joint_columns, marker=marker)
        if self._joint_terms is not None:  # through the corrections q + dq(q)
            Jt = self._joint_terms.through_corrections(Jt, q, p[self._n_geometric:])
        return np.ascontiguousarray(Jt.transpose(2, 1, 0))

    def single_pose(self, q: ArrayLike, params: ArrayLike | None = None,
                    outputs: str = "pose") -> tuple[Array, Array] | None:
        """Tool frame ``(4, 4)`` and joint Jacobian ``(6 or 3, n_joints)`` (see
        `joint_jacobian`) at one configuration `q` ``(n_joints,)``, from the folded chain
        (`kinecal.kinematics.serial.single`): for callers that ask one pose at a time
        (an IK iteration, an online correction). None where the folded chain does not
        apply (markers, joint errors, a parameter vector seen for the first time): then
        use `fk` and `joint_jacobian`."""
        one = self._single(q, params, None)
        if one is None:
            return None
        if outputs not in ("position", "pose"):
            raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
        return one[0].transform_and_jacobian(one[1], outputs)

    def _single(self, q: ArrayLike, params: ArrayLike | None, marker: ArrayLike | None
                ) -> tuple[SingleChain, list[float]] | None:
        """The folded chain (`kinecal.kinematics.serial.single`) and the checked joint
        values as floats when `q` is one configuration ``(n_joints,)`` (a 1-D vector: a
        batch of one, ``(1, n_joints)``, stays on the batch path and gives the batch's
        bits) of a model without markers or joint errors, and the parameter vector is the
        nominal one or one
        seen before (its chain is then cached; a vector seen once takes the batch path, so a
        loop over changing vectors builds nothing); None otherwise."""
        if marker is not None or self._joint_terms is not None or self._marker_set is not None:
            return None
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_joints,):
            return None
        if params is None:
            key = b""
        else:
            p = np.asarray(params, dtype=float)
            if p.shape != (self.n_params,):
                return None
            key = p.tobytes()
        cache = self.__dict__.setdefault("_single_chains", {})
        chain = cache.get(key)
        if chain is None:
            if key and key not in cache:  # first sight of this vector: remember it only
                if len(cache) > 8:
                    cache.clear()
                cache[key] = None
                return None
            chain = cache[key] = SingleChain(self.motions, self._motion_index, self.n_joints,
                                             self._nominal if not key else p)
        values = q.tolist()
        if not all(map(math.isfinite, values)):
            raise InputError("joint values contain NaN or infinite entries")
        return chain, values

    def _corrected(self, q: Array, p: Array) -> Array:
        """The joint values the chain composes: ``q + dq(q, c)`` with joint errors
        (`kinecal.kinematics.serial.joint_errors`), else `q` itself; one parameter vector."""
        if self._joint_terms is None:
            return q
        return q + self._joint_terms.dq(q, p[self._n_geometric:])

    def _one_vector(self, params: ArrayLike | None) -> Array:
        p = self._check_params(params)
        if p.ndim != 1:
            raise InputError("identification_jacobian expects one parameter vector")
        return p

    def sweep(self, q: ArrayLike, params: ArrayLike | None = None,
              marker: ArrayLike | None = None) -> Sweep:
        """Forward kinematics of one parameter vector, keeping what the Jacobian needs.

        A solver that needs the positions at ``x`` and then, if the step is accepted, the
        Jacobian at the same ``x`` computes the chain once: ``s = model.sweep(q, p)``,
        ``s.positions``, later ``s.jacobian_t()``. One pass over all of `q` (callers with
        many poses sweep chunks of them, as `kinecal.calibration.serial.rows` does).
        """
        q, p = self._check_q(q), self._one_vector(params)
        m = self._marker(marker, len(q))
        _, (axes, o, frames) = next(chunks(self.motions, self._motion_index,
                                           self._corrected(q, p), p, frame_chain, True,
                                           elements=0, pose_values=self._pose_values(m, p)))
        return Sweep(self, axes, o, frames, q.shape[0], q, p, m)
