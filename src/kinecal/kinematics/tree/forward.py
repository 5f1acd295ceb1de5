"""Forward kinematics and Jacobians of a system, row by row on each row's chain.

Every row of a measurement names its chain (its tip); the rows of one tip are swept
together on that chain (`kinecal.kinematics.tree.chain.PathChain`, the serial kernels), and
the results are scattered back into row order. The Jacobian columns are the system's
parameters: a chain writes the columns of the parameters it reaches and leaves the others
zero, so the columns of shared elements collect the rows of every chain through them. No
system-wide product is formed per row.

`SystemSweep` is the sweep of several chains at once, with the interface of
`kinecal.kinematics.serial.sweep.Sweep` (``positions``, ``rotations``, ``jacobian_t``), so
that the residual blocks of `kinecal.calibration.blocks` use a system as they use an arm.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.tree.chain import PathChain

__all__ = ["SystemKinematics", "SystemSweep"]

Array = NDArray[np.float64]
Rows = slice | NDArray[np.intp]


def _put(out: Array, sel: NDArray[np.intp], rows: Rows, J: Array) -> None:
    """``out[sel, :, rows] = J`` for index arrays `sel` (axis 0) and `rows` (axis 2)."""
    if isinstance(rows, slice):
        out[sel, :, rows] = J
        return
    for i, c in enumerate(sel):  # one row set per column: no (k, rows, n) index grids
        out[c][:, rows] = J[i]


def _chain_jacobian(chain: PathChain, cols: NDArray[np.intp], q: Array, p: Array, jac
                    ) -> tuple[NDArray[np.intp], Array]:
    """The positions in `cols` of the parameters `chain` reaches and their Jacobian rows
    ``jac(columns)`` (multiplier columns added): one sweep's worth, not the system's."""
    sel = chain.columns_of(cols)
    sub = cols[sel]
    J = jac(sub)
    chain.multiplier_rows(J, sub, q, p, jac)
    return sel, J


def _per_vector(chain: PathChain, q: Array, p: Array, call: Callable) -> Array:
    """``call(chain_q, p)`` for one vector, or stacked over a population of vectors (a
    coupled chain's readings differ per vector)."""
    if p.ndim == 1 or not chain.coupled:
        return call(chain.chain_q(q, p if p.ndim == 1 else p[0]), p)
    return np.stack([call(chain.chain_q(q, v), v) for v in p])


class SystemSweep:
    """Sweeps of the chains of a set of rows (module docstring).

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        Tool points (or link points) in the measurement frame.
    """

    def __init__(self, parts: list[tuple[PathChain, Rows, object, Array]], n: int,
                 p: Array) -> None:
        self.parts = parts
        self.n = n
        self.p = p
        self.positions = np.empty((n, 3))
        for _, rows, s, _ in parts:
            self.positions[rows] = s.positions
        self._rotations: Array | None = None

    @property
    def rotations(self) -> Array:
        """Tool-frame orientations ``(N, 3, 3)`` in the measurement frame."""
        if self._rotations is None:
            R = np.empty((self.n, 3, 3))
            for _, rows, s, _ in self.parts:
                R[rows] = s.rotations
            self._rotations = R
        return self._rotations

    def jacobian_t(self, outputs: str = "position", columns: ArrayLike | None = None,
                   out: Array | None = None) -> Array:
        """Identification Jacobian ``(k, 3 or 6, N)`` of the system parameters `columns`
        (default all), as `kinecal.kinematics.serial.sweep.Sweep.jacobian_t`."""
        if outputs not in ("position", "pose"):
            raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
        n_params = len(self.p)
        cols = np.arange(n_params) if columns is None else np.asarray(columns, dtype=np.intp)
        if out is None and len(self.parts) == 1 and self.parts[0][1] == slice(0, self.n):
            chain, _, s, q = self.parts[0]  # one chain's rows, in order: no scatter
            sel, J = _chain_jacobian(chain, cols, q, self.p,
                                     lambda c: s.jacobian_t(outputs, columns=c))
            if sel.size == cols.size:
                return J
            Jt = np.zeros((cols.size, J.shape[1], self.n))
            _put(Jt, sel, slice(None), J)
            return Jt
        Jt = np.zeros((cols.size, 6 if outputs == "pose" else 3, self.n)) if out is None \
            else out
        for chain, rows, s, q in self.parts:
            sel, J = _chain_jacobian(chain, cols, q, self.p,
                                     lambda c, s=s: s.jacobian_t(outputs, columns=c))
            _put(Jt, sel, rows, J)
        return Jt


class SystemKinematics:
    """Forward kinematics of a system's tips, row by row (module docstring); a base class
    of `kinecal.kinematics.tree.system.SystemModel`, which sets ``_chains`` (a list of
    `PathChain`, one per tip), ``_nominal``, ``n_params``, ``n_joints`` and ``name``.

    Every method takes the readings of the system's joints ``q`` ``(N, n_joints)`` (rad;
    prismatic: length unit; joints off a row's chain are ignored) and, as `marker`, the
    tip of each row: an index ``(N,)`` into `marker_names` (the tip names); None means
    the first tip.
    """

    # ------------------------------------------------------------------ checks
    def _check_params(self, params: ArrayLike | None) -> Array:
        if params is None:
            return self._nominal
        p = np.asarray(params, dtype=float)
        if p.shape[-1:] != (self.n_params,) or p.ndim > 2:
            raise InputError(f"parameters: expected shape ({self.n_params},) or (P, "
                             f"{self.n_params}), got {p.shape}")
        return p

    def _one_vector(self, params: ArrayLike | None) -> Array:
        p = self._check_params(params)
        if p.ndim != 1:
            raise InputError("expected one parameter vector")
        return p

    def _check_q(self, q: ArrayLike) -> Array:
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InputError(f"joint values: expected shape (N, {self.n_joints}) (the "
                             f"system's joints {', '.join(self.joint_names)}), got "
                             f"{np.shape(q)}")
        if not np.isfinite(q).all():
            raise InputError("joint values contain NaN or infinite entries")
        return q

    def tip_index(self, marker: ArrayLike | None, n: int) -> NDArray[np.intp]:
        """Checked tip index per row ``(n,)`` (None: the first tip everywhere)."""
        if marker is None:
            return np.zeros(n, dtype=np.intp)
        m = np.asarray(marker)
        if m.shape != (n,) or not np.issubdtype(m.dtype, np.integer):
            raise InputError(f"tip: expected {n} integer tip indices (one per row), got "
                             f"shape {m.shape}")
        if m.size and (m.min() < 0 or m.max() >= len(self._chains)):
            raise InputError(f"tip: indices must lie in 0..{len(self._chains) - 1} "
                             f"({', '.join(self.marker_names)})")
        return m.astype(np.intp, copy=False)

    def _groups(self, marker: ArrayLike | None, n: int) -> list[tuple[PathChain, Rows]]:
        """The chain and the rows of each tip present."""
        tips = self.tip_index(marker, n)
        out: list[tuple[PathChain, Rows]] = []
        for t in np.unique(tips):
            rows = np.flatnonzero(tips == t)
            if rows[-1] - rows[0] + 1 == rows.size:  # a block of rows: a view, no copies
                rows = slice(int(rows[0]), int(rows[-1]) + 1)
            out.append((self._chains[int(t)], rows))
        return out

    # ------------------------------------------------------------------ kinematics
    def positions(self, q: ArrayLike, params: ArrayLike | None = None,
                  marker: ArrayLike | None = None) -> Array:
        """Tool points ``(N, 3)`` or ``(P, N, 3)`` of each row's tip (length unit)."""
        q, p = self._check_q(q), self._check_params(params)
        out = np.empty((*p.shape[:-1], len(q), 3))
        for chain, rows in self._groups(marker, len(q)):
            out[..., rows, :] = _per_vector(chain, q[rows], p, chain.positions)
        return out

    def fk(self, q: ArrayLike, params: ArrayLike | None = None,
           marker: ArrayLike | None = None) -> Array:
        """Tool frames ``(N, 4, 4)`` or ``(P, N, 4, 4)`` (``tool2world``) of each row's tip."""
        q, p = self._check_q(q), self._check_params(params)
        out = np.empty((*p.shape[:-1], len(q), 4, 4))
        for chain, rows in self._groups(marker, len(q)):
            out[..., rows, :, :] = _per_vector(chain, q[rows], p, chain.fk)
        return out

    def sweep(self, q: ArrayLike, params: ArrayLike | None = None,
              marker: ArrayLike | None = None) -> SystemSweep:
        """Forward kinematics keeping what the Jacobian needs (`SystemSweep`)."""
        q, p = self._check_q(q), self._one_vector(params)
        parts = [(chain, rows, chain.sweep(chain.chain_q(q[rows], p), p), q[rows])
                 for chain, rows in self._groups(marker, len(q))]
        return SystemSweep(parts, len(q), p)

    def jacobian_t(self, q: ArrayLike, params: ArrayLike | None = None,
                   outputs: str = "position", columns: ArrayLike | None = None,
                   marker: ArrayLike | None = None) -> Array:
        """Identification Jacobian ``(k, 3 or 6, N)`` of the parameter indices `columns`
        (default all), chunk by chunk on each chain."""
        q, p = self._check_q(q), self._one_vector(params)
        cols = np.arange(self.n_params) if columns is None else np.asarray(columns, np.intp)
        out = np.zeros((cols.size, 6 if outputs == "pose" else 3, len(q)))
        for chain, rows in self._groups(marker, len(q)):
            qr = q[rows]
            qc = chain.chain_q(qr, p)
            sel, J = _chain_jacobian(chain, cols, qr, p, lambda c, qc=qc, chain=chain:
                                     chain.jacobian_t(qc, p, outputs, c))
            _put(out, sel, rows, J)
        return out

    def identification_jacobian(self, q: ArrayLike, params: ArrayLike | None = None,
                                outputs: str = "position",
                                marker: ArrayLike | None = None) -> Array:
        """`jacobian_t` of every parameter as ``(N, 3 or 6, n_params)``."""
        Jt = self.jacobian_t(q, params, outputs, marker=marker)
        return np.ascontiguousarray(Jt.transpose(2, 1, 0))

    def joint_jacobian(self, q: ArrayLike, params: ArrayLike | None = None,
                       outputs: str = "pose", marker: ArrayLike | None = None) -> Array:
        """Derivative of each row's tool pose with respect to the system's joint readings
        ``(N, 6 or 3, n_joints)`` (zero for joints off the row's chain; a coupled joint's
        column adds, times its multiplier, to its leader's)."""
        q, p = self._check_q(q), self._one_vector(params)
        out = np.zeros((len(q), 6 if outputs == "pose" else 3, self.n_joints))
        for chain, rows in self._groups(marker, len(q)):
            Jc = chain.joint_jacobian(chain.chain_q(q[rows], p), p, outputs)
            mult = np.where(chain.multiplier >= 0, p[np.maximum(chain.multiplier, 0)], 1.0)
            M = np.zeros((chain.n_joints, self.n_joints))  # chain joints -> system joints
            np.add.at(M, (np.arange(chain.n_joints), chain.source), mult)
            out[rows] = Jc @ M
        return out
