"""Tracker points and poses as a residual block: ``p_model - p_measured`` (3 rows per row of
the file, 6 with measured orientations), no nuisance (the base frame is the arm's); rows
whitened by their per-axis standard deviations when the file gives them
(`kinecal.calibration.serial.row_weights`). Several set-ups: `kinecal.calibration.blocks.
stations`.

Its share of the normal equations (`arm_normal`) is accumulated over cache-sized chunks of
rows (`PoseRows`), and for a robot system chain by chain on the columns each chain reaches:
one Jacobian sweep per chain, the shared columns added, never the dense rows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, ResidualBlock
from kinecal.calibration.diagnostics.observations import pose_groups
from kinecal.calibration.serial.problem import characteristic_length, row_norms
from kinecal.calibration.serial.row_weights import sigma_row_scale
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["TrackerBlock"]

Array = NDArray[np.float64]


class TrackerBlock(ResidualBlock):
    """Measured tool points (and orientations) of a laser tracker or CMM.

    Parameters
    ----------
    data : Measurements
        Joint readings and measured points (the model's markers).
    sigma : float, optional
        Stated noise per coordinate of a row of weight 1 (length unit).
    rotation_weight : float, optional
        With orientations: length units per rad of the rotation rows (default: the
        workspace's characteristic length at nominal).
    """

    kind = "tracker"
    noise_of = "each measured coordinate"

    def __init__(self, data: Measurements, sigma: float | None = None,
                 rotation_weight: float | None = None) -> None:
        w = None if data.weights is None else 1.0 / np.sqrt(np.asarray(data.weights, float))
        super().__init__(data.source, data.q, data.marker, sigma, relative=w)
        self.data = data
        self.rows = 3 if data.rotations is None else 6
        self.obs_dof = self.rows
        self.rotation_weight = rotation_weight
        self._obs = np.repeat(np.arange(len(data), dtype=np.intp), self.rows)
        self._pose_rows: PoseRows | None = None
        self._scale: Array | None = None  # per-row whitening by the standard deviations

    @property
    def n_obs(self) -> int:
        return len(self.data)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        return self._obs

    def observation_poses(self) -> tuple[NDArray[np.intp], int]:
        """Rows of one arm configuration at several markers are one pose."""
        if self.marker is None:
            return np.arange(self.n_obs, dtype=np.intp), self.n_obs
        return pose_groups(self.q, self.marker)

    def start(self, model: SerialModel, params: Array) -> Array:
        if self._pose_rows is None:
            w = self.rotation_weight
            if w is None and self.rows == 6:
                w = self.rotation_weight = characteristic_length(model, self.data, params)
            self._pose_rows = PoseRows(model, self.data, w or 0.0, weighted=False)
            self._scale = sigma_row_scale(self.data, w or 1.0)
        return np.zeros(0)

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points=None) -> BlockRows:
        if self._pose_rows is None:
            self.start(model, params)
        cols = (np.zeros(0, dtype=np.intp) if columns is None else columns) if jacobian else None
        e, Jt, _ = self._pose_rows.evaluate(params, slice(None), cols)
        if self._scale is not None:  # rows whitened by their standard deviations
            e = e * self._scale
            if Jt is not None:
                Jt *= self._scale.T
        if not jacobian:
            return BlockRows(e.ravel())
        arm = Jt.transpose(2, 1, 0).reshape(e.size, Jt.shape[0])
        return BlockRows(e.ravel(), arm, np.zeros((arm.shape[0], 0)))

    def arm_normal(self, model: SerialModel, params: Array, columns: NDArray[np.intp],
                   weight: Array, groups: list | None = None
                   ) -> tuple[Array, Array, Array]:
        """Weighted residual ``(m,)``, ``J^T J`` ``(k, k)`` and ``J^T r`` ``(k,)`` of the
        rows (`ResidualBlock.arm_normal`): the serial calibration's chunked pass
        (`PoseRows.normal_equations`), group by group; the rows of weight zero are not
        evaluated (their residual is zero)."""
        if self._pose_rows is None:
            self.start(model, params)
        rows = self.rows
        W = np.asarray(weight, dtype=float).reshape(-1, rows)
        if self._scale is not None:
            W = W * self._scale
        # a group holds every row of its observations, in order (`column_groups`)
        parts = None if groups is None else [(rw[::rows] // rows, pos) for rw, pos in groups]
        return self._pose_rows.normal_equations(params, columns, W, parts)

    def observation_errors(self, r: Array) -> Array:
        """Distance error per measured point (length unit; the position rows, unweighted)."""
        e = np.asarray(r).reshape(-1, self.rows)[:, :3]
        return row_norms(e if self._scale is None else e / self._scale[:, :3])
