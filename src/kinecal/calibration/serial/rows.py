"""Residual and identification-Jacobian rows of a pose set, built in cache-sized chunks.

A calibration's least-squares system has 3 (or 6) rows per pose and one column per
parameter; at a million poses the Jacobian alone is 0.8 GB and the forward-kinematics
sweep that builds it records another ~1.2 KB of frames per pose. Nothing downstream needs
the whole matrix: Levenberg-Marquardt needs ``J^T J`` and ``J^T r``, the identifiability
analysis and the covariance need ``J^T J`` or an R factor (`kinecal.optimize.factor`).
`PoseRows` therefore sweeps the poses in chunks sized for the cache and folds each
chunk into those small matrices; memory stays at a few tens of bytes per pose (the
residual vector) plus one chunk.

Row layout (as `CalibrationProblem.residuals`): pose-major, per pose the position error
``p_model - p_measured`` and, with measured orientations, ``w * log(R_model R_meas^T)``
(``w`` = rotation weight, length unit per rad); times the square root of the row's weight
when `weighted` (the pose's ``weight``, and per-axis standard deviations:
`kinecal.calibration.serial.row_weights`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.row_weights import row_sqrt_weights
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.factor import qr_update
from kinecal.spatial import axis_angle_from_matrix, left_jacobian_inverse

__all__ = ["CHUNK_BYTES", "PoseRows"]

Array = NDArray[np.float64]

#: working set per chunk (FK frames + Jacobian rows): inside a 1 MB L2 plus a share of
#: the L3, the sweet spot measured for UR5 (33 parameters): 4000-16000 poses per chunk
CHUNK_BYTES = 8 << 20


class PoseRows:
    """Chunked residual and Jacobian rows of `data` for `model`.

    Parameters
    ----------
    model : SerialModel
    data : Measurements
    rotation_weight : float
        Length units per rad of the rotation rows (ignored without measured orientations).
    weighted : bool
        Multiply each pose's rows by ``sqrt(weight)`` (the data's weights).
    """

    def __init__(self, model: SerialModel, data: Measurements, rotation_weight: float,
                 weighted: bool = True) -> None:
        self.model = model
        self.q = np.asarray(data.q, dtype=float)
        self.xyz = np.asarray(data.xyz, dtype=float)
        self.marker = data.marker  # per-pose marker index (several tool points) or None
        self.R_meas_t = (None if data.rotations is None
                         else np.swapaxes(np.asarray(data.rotations, dtype=float), 1, 2))
        self.rows = 3 if self.R_meas_t is None else 6
        self.rotation_weight = float(rotation_weight)
        #: square roots of the row weights (N, rows) (pose weights and per-axis standard
        #: deviations, `kinecal.calibration.serial.row_weights`) or None
        self.sqrt_w = (row_sqrt_weights(data, self.rows, self.rotation_weight)
                       if weighted else None)
        self.n_poses = self.q.shape[0]

    # ------------------------------------------------------------------ chunks
    def chunk_poses(self, n_columns: int) -> int:
        """Poses per chunk for `n_columns` Jacobian columns (`CHUNK_BYTES` working set)."""
        motions = len(self.model.motions)
        per_pose = 8 * 3 * (2 * motions + self.rows * max(n_columns, 1) // 3 + 4)
        return int(np.clip(CHUNK_BYTES // per_pose, 16, 65536))

    def chunks(self, n_columns: int, keep: Array | None = None) -> Iterator[Array | slice]:
        """Pose selections (slices, or index arrays of `keep`) of one chunk each."""
        step = self.chunk_poses(n_columns)
        if keep is None:
            for s in range(0, self.n_poses, step):
                yield slice(s, min(s + step, self.n_poses))
        else:
            keep = np.asarray(keep)
            for s in range(0, keep.size, step):
                yield keep[s:s + step]

    def evaluate(self, p: Array, sel, columns: Array | None) -> tuple[Array, Array | None, Array]:
        """Rows of the poses `sel` at the full parameter vector `p`.

        Returns
        -------
        e : ndarray, shape (n, rows)
            Residual rows per pose.
        Jt : ndarray, shape (k, rows, n) or None
            Jacobian of `e` for the parameter indices `columns` (None: not computed).
        positions : ndarray, shape (n, 3)
            Model tool positions.
        """
        q = self.q[sel]
        marker = None if self.marker is None else self.marker[sel]
        if columns is None and self.R_meas_t is None:
            P = self.model.positions(q, p, marker)
            e = P - self.xyz[sel]
            if self.sqrt_w is not None:
                e = e * self.sqrt_w[sel]
            return e, None, P
        sweep = self.model.sweep(q, p, marker)
        P = sweep.positions
        e = P - self.xyz[sel]
        Jt = None
        if self.R_meas_t is not None:
            rot = axis_angle_from_matrix(sweep.rotations @ self.R_meas_t[sel])
            e = np.concatenate([e, self.rotation_weight * rot], axis=1)
            if columns is not None:
                Jt = sweep.jacobian_t("pose", columns=columns)
                Jl = left_jacobian_inverse(rot)
                Jt[:, 3:] = self.rotation_weight * np.einsum("nij,kjn->kin", Jl, Jt[:, 3:])
        else:
            Jt = sweep.jacobian_t(columns=columns)
        if self.sqrt_w is not None:
            sw = self.sqrt_w[sel]
            e = e * sw
            if Jt is not None:
                Jt *= sw.T
        return e, Jt, P

    # ------------------------------------------------------------------ passes
    def residuals(self, p: Array) -> tuple[Array, Array]:
        """Residual vector ``(rows * N,)`` (pose-major) and positions ``(N, 3)`` at `p`."""
        r = np.empty((self.n_poses, self.rows))
        P = np.empty((self.n_poses, 3))
        for sel in self.chunks(0):
            r[sel], _, P[sel] = self.evaluate(p, sel, None)
        return r.ravel(), P

    def normal_equations(self, p: Array, columns: Array, weight: Array | None = None,
                         parts: list | None = None) -> tuple[Array, Array, Array]:
        """Residual vector ``(rows * N,)``, ``J^T J`` ``(k, k)`` and ``J^T r`` ``(k,)``.

        Parameters
        ----------
        p : ndarray, shape (n_params,)
        columns : ndarray of int, shape (k,)
            Parameter indices of the Jacobian's columns.
        weight : ndarray, shape (N, rows), optional
            Further row weights (a stacked problem's ``1 / sigma``); the poses whose rows
            all weigh zero are not evaluated (their residual rows are zero).
        parts : list of (ndarray or None, ndarray or None), optional
            Pose groups, each with the positions in `columns` its rows reach (a robot
            system's chains: `kinecal.calibration.blocks.tips.column_groups`); each group's
            Gram matrix is accumulated on its own columns. Default: every pose, every
            column.
        """
        k = len(columns)
        r = np.zeros((self.n_poses, self.rows))
        A = np.zeros((k, k))
        g = np.zeros(k)
        live = None if weight is None else weight.any(axis=1)
        for poses, pos in parts or [(None, None)]:
            if live is not None and not live.all():
                poses = np.flatnonzero(live) if poses is None else poses[live[poses]]
            cols = columns if pos is None else columns[pos]
            for sel in self.chunks(len(cols), poses):
                e, Jt, _ = self.evaluate(p, sel, cols if len(cols) else None)
                if weight is not None:
                    ws = weight[sel]
                    e = e * ws
                    if Jt is not None:
                        Jt *= ws.T
                r[sel] = e
                if Jt is None:  # no column reaches these rows
                    continue
                J2 = Jt.reshape(len(cols), -1)  # rows in (row, pose) order
                Ag, gg = J2 @ J2.T, J2 @ np.ascontiguousarray(e.T).ravel()
                if pos is None:
                    A += Ag
                    g += gg
                else:
                    A[np.ix_(pos, pos)] += Ag
                    g[pos] += gg
        return r.ravel(), A, g

    def gram(self, p: Array, columns: Array, keep: Array | None = None,
             residuals: bool = False) -> tuple:
        """Gram matrix ``(k + 1, k + 1)`` of ``[J | r]`` and positions ``(N, 3)`` at `p`.

        With `keep` (pose indices) only those poses' rows enter and no positions are
        returned. With `residuals`, the residual vector ``(rows * N,)`` (pose-major) is
        returned third.
        """
        k = len(columns)
        G = np.zeros((k + 1, k + 1))
        P = np.empty((self.n_poses, 3)) if keep is None else None
        r = np.empty((self.n_poses, self.rows)) if residuals and keep is None else None
        for sel in self.chunks(k, keep):
            e, Jt, Pc = self.evaluate(p, sel, columns)
            if P is not None:
                P[sel] = Pc
            if r is not None:
                r[sel] = e
            J2 = Jt.reshape(k, -1)
            ev = np.ascontiguousarray(e.T).ravel()
            Jr = J2 @ ev
            G[:k, :k] += J2 @ J2.T
            G[:k, k] += Jr
            G[k, :k] += Jr
            G[k, k] += ev @ ev
        if residuals:
            return G, P, None if r is None else r.ravel()
        return G, P

    def factor(self, p: Array, columns: Array) -> tuple[Array, Array, Array]:
        """TSQR factor ``(k + 1, k + 1)`` of ``[J | r]``, residual vector and positions.

        The leading ``(k, k)`` block is the R of ``J`` (exact however ill-conditioned);
        the last column holds ``Q^T r`` and the residual norm left beyond the span of ``J``.
        """
        k = len(columns)
        R = None
        r = np.empty((self.n_poses, self.rows))
        P = np.empty((self.n_poses, 3))
        for sel in self.chunks(k):
            e, Jt, P[sel] = self.evaluate(p, sel, columns)
            r[sel] = e
            block = np.empty((Jt.shape[1] * Jt.shape[2], k + 1), order="F")
            block[:, :k] = Jt.reshape(k, -1).T
            block[:, k] = e.T.ravel()
            R = qr_update(R, block)
        if R is None:
            R = np.zeros((k + 1, k + 1))
        return R, r.ravel(), P
