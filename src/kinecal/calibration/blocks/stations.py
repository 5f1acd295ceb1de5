"""Tracker rows from several set-ups (stations): each station its own base frame, solved
with the arm as the block's own unknowns (`kinecal.calibration.blocks`).

A laser tracker moved between sessions measures the same arm in another frame. Row ``i``,
measured from station ``s``, is modelled as ``S_s T_model(q_i)``: the model's tool pose in
its own base frame (the model's ``base`` held) carried into the station's frame by

``S_s = T(t_s) R_s0 R(w_s)``,

``t_s`` the station's origin (``base@S.x .. base@S.z``), ``R_s0`` its orientation at the
start (a Kabsch registration of the nominal arm's points on the station's rows,
`kinecal.calibration.serial.registration`) and ``w_s`` the local rotation error after it
(``base@S.rx .. base@S.rz``, ``R(w) = Rz Ry Rx``): the parametrisation of the model's base
(docs/conventions.md), without a gimbal lock whatever the station's orientation. The
stations see where the arm stands only relative to each other: the mix is blind to a rigid
motion of the whole arm (`blind_to`), so the model's base frame and what moves the arm
rigidly are held. Residual rows as `kinecal.calibration.blocks.tracker.TrackerBlock`'s, in
the station's frame; a row's per-axis standard deviations whiten it
(`kinecal.calibration.serial.row_weights`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, ResidualBlock, group_rows
from kinecal.calibration.diagnostics.observations import pose_groups
from kinecal.calibration.serial.problem import characteristic_length
from kinecal.calibration.serial.registration import rigid_fit_poses
from kinecal.calibration.serial.row_weights import sigma_row_scale
from kinecal.data import Measurements
from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.frames import frame_transform
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import (
    axis_angle_from_matrix,
    left_jacobian_inverse,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle,
    rpy_from_matrix,
)

__all__ = ["StationBlock", "station_parameter_names"]

Array = NDArray[np.float64]

#: poses per forward-kinematics sweep (every frame of a sweep is kept for the Jacobian)
SWEEP_POSES = 4096
#: `tool-orientation`: the median orientation misfit after registration beyond this (deg)
TOOL_TURN = 10.0
_KEYS = ("x", "y", "z", "rx", "ry", "rz")


def station_parameter_names(name: str) -> list[str]:
    """``base@NAME.x .. base@NAME.rz``: the base frame seen from station `name`."""
    return [f"base@{name}.{k}" for k in _KEYS]


class StationBlock(ResidualBlock):
    """Tracker points (and poses) measured from several stations (module docstring).

    Parameters
    ----------
    data : Measurements
        With ``station`` indices (every row from one of ``station_names``).
    sigma : float, optional
        Stated noise per coordinate of a row of weight 1 (length unit).
    rotation_weight : float, optional
        With orientations: length units per rad of the rotation rows (default: the
        workspace's characteristic length at the start).
    """

    kind = "tracker"
    noise_of = "each measured coordinate"
    blind_to = frozenset({"translation", "rotation"})

    def __init__(self, data: Measurements, sigma: float | None = None,
                 rotation_weight: float | None = None) -> None:
        if data.station is None:
            raise InputError(f"{data.source}: no station column: a tracker file of one set-up "
                             "is a plain tracker block")
        w = None if data.weights is None else 1.0 / np.sqrt(np.asarray(data.weights, float))
        super().__init__(data.source, data.q, data.marker, sigma, relative=w)
        self.data = data
        self.rows = 3 if data.rotations is None else 6
        self.obs_dof = self.rows
        self.rotation_weight = rotation_weight
        self.station = np.asarray(data.station, dtype=np.intp)
        self.names = tuple(data.station_names)
        self.groups = group_rows(self.station, len(self.names))
        self._obs = np.repeat(np.arange(len(data), dtype=np.intp), self.rows)
        self._R0 = np.tile(np.eye(3), (len(self.names), 1, 1))
        self._base = np.eye(4)  # the model's (held) base frame, for the report
        self._scale: Array | None = None  # per-row whitening (standard deviations)
        self._started = False
        self._turn = 0.0

    # ------------------------------------------------------------------ layout
    @property
    def n_obs(self) -> int:
        return len(self.data)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        return self._obs

    @property
    def nuisance_names(self) -> list[str]:
        return [n for s in self.names for n in station_parameter_names(s)]

    def observation_poses(self) -> tuple[NDArray[np.intp], int]:
        """Rows of one arm configuration at several markers, from one station, are one
        pose (as `kinecal.calibration.blocks.tracker.TrackerBlock`'s)."""
        if self.marker is None:
            return np.arange(self.n_obs, dtype=np.intp), self.n_obs
        q = np.column_stack([self.q, 1e6 * self.station])  # never one pose across stations
        return pose_groups(q, self.marker)

    def nuisance_scale(self, length: float) -> Array:
        return np.tile([1.0, 1.0, 1.0, 1.0 / length, 1.0 / length, 1.0 / length],
                       len(self.names))

    def observation_labels(self) -> list[str]:
        labels = super().observation_labels()
        return [f"{lab} ({self.names[s]})" for lab, s in zip(labels, self.station,
                                                             strict=True)]

    # ------------------------------------------------------------------ start
    def start(self, model: SerialModel, params: Array) -> Array:
        """Each station registered on its rows (`rigid_fit_poses`): its orientation is the
        reference of its local rotation, the nuisance starts at ``(t_s, 0, 0, 0)``."""
        if self.rotation_weight is None and self.rows == 6:
            self.rotation_weight = characteristic_length(model, self.data, params)
        self._scale = sigma_row_scale(self.data, self.rotation_weight or 1.0)
        self._base = frame_transform(model, params, "base")
        T = model.fk(self.q, params, self.marker)
        out = []
        turn = []  # rows' orientation misfit after the registration (deg)
        for s, rows in enumerate(self.groups):
            Rm = None if self.data.rotations is None else np.asarray(self.data.rotations)[rows]
            try:
                X = rigid_fit_poses(T[rows, :3, 3], np.asarray(self.data.xyz)[rows],
                                    T[rows, :3, :3], Rm)
            except InputError as exc:
                raise InputError(f"{self.name}: station {self.names[s]}: {exc.message}"
                                 ) from None
            self._R0[s] = X[:3, :3]
            out.append(np.r_[X[:3, 3], 0.0, 0.0, 0.0])
            if Rm is not None:
                turn.append(np.degrees(rotation_angle(
                    np.swapaxes(Rm, 1, 2) @ X[:3, :3] @ T[rows, :3, :3])))
        self._turn = float(np.median(np.concatenate(turn))) if turn else 0.0
        self._started = True
        return np.concatenate(out) if out else np.zeros(0)

    def station_frames(self, nuisance: Array) -> tuple[Array, Array, Array]:
        """Rotations ``(S, 3, 3)``, origins ``(S, 3)`` and the axes of the local rotations
        ``(S, 3, 3)`` (column k: the axis of ``rx, ry, rz`` in the station's frame)."""
        v = np.asarray(nuisance, dtype=float).reshape(-1, 6)
        t, w = v[:, :3], v[:, 3:]
        Rz, Ry, Rx = rot_z(w[:, 2]), rot_y(w[:, 1]), rot_x(w[:, 0])
        R = self._R0 @ Rz @ Ry @ Rx
        e = np.eye(3)
        axes = np.stack([self._R0 @ Rz @ Ry @ e[0], self._R0 @ Rz @ e[1], self._R0 @ e[2]],
                        axis=-1)
        return R, t, axes

    # ------------------------------------------------------------------ rows
    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points=None) -> BlockRows:
        if not self._started:
            raise InputError(f"{self.name}: start() sets the stations' reference frames "
                             "before rows are evaluated")
        R, t, axes = self.station_frames(nuisance)
        n, rows = len(self.data), self.rows
        k = 0 if columns is None else len(columns)
        e = np.empty((n, rows))
        arm = np.zeros((n, rows, k)) if jacobian else None
        nuis = np.zeros((n, rows, self.n_nuisance)) if jacobian else None
        for a in range(0, n, SWEEP_POSES):
            sel = slice(a, min(a + SWEEP_POSES, n))
            self._rows(model, params, columns, jacobian, sel, R, t, axes, e, arm, nuis)
        if self._scale is not None:
            e *= self._scale
            if jacobian:
                arm *= self._scale[:, :, None]
                nuis *= self._scale[:, :, None]
        r = e.ravel()
        if not jacobian:
            return BlockRows(r)
        return BlockRows(r, arm.reshape(r.size, k), nuis.reshape(r.size, self.n_nuisance))

    def _rows(self, model, params, columns, jacobian, sel, R, t, axes, e, arm, nuis) -> None:
        """Rows of the poses `sel` into `e`, `arm` and `nuis` (in place)."""
        st = self.station[sel]
        marker = None if self.marker is None else self.marker[sel]
        sweep = model.sweep(self.q[sel], params, marker)
        Rs, ts = R[st], t[st]
        P = np.einsum("nij,nj->ni", Rs, sweep.positions) + ts
        e[sel, :3] = P - np.asarray(self.data.xyz)[sel]
        Jl = None
        if self.rows == 6:
            Rm = np.asarray(self.data.rotations)[sel]
            rot = axis_angle_from_matrix(Rs @ sweep.rotations @ np.swapaxes(Rm, 1, 2))
            e[sel, 3:] = self.rotation_weight * rot
            Jl = self.rotation_weight * left_jacobian_inverse(rot)
        if not jacobian:
            return
        if columns is not None and len(columns):
            Jt = sweep.jacobian_t("pose" if self.rows == 6 else "position", columns=columns)
            Ja = np.einsum("nij,kjn->nik", Rs, Jt[:, :3])
            arm[sel, :3] = Ja
            if Jl is not None:
                arm[sel, 3:] = np.einsum("nij,njl,kln->nik", Jl, Rs, Jt[:, 3:])
        idx = np.arange(sel.stop - sel.start)
        u = axes[st]  # (n, 3, 3): the local rotation axes
        lever = P - ts
        for c in range(3):
            nuis[sel.start + idx, c, 6 * st + c] = 1.0
            col = np.cross(u[:, :, c], lever)
            nuis[sel.start + idx, :3, 6 * st + 3 + c] = col
            if Jl is not None:
                nuis[sel.start + idx, 3:, 6 * st + 3 + c] = np.einsum("nij,nj->ni", Jl,
                                                                     u[:, :, c])

    def observation_errors(self, r: Array) -> Array:
        """Distance error per measured point (length unit; the position rows, unweighted)."""
        e = np.asarray(r).reshape(-1, self.rows)[:, :3]
        if self._scale is not None:
            e = e / self._scale[:, :3]
        return np.sqrt(np.einsum("ij,ij->i", e, e))

    # ------------------------------------------------------------------ report
    def station_poses(self, nuisance: Array) -> Array:
        """Each station's base frame (the robot base seen from it) ``(S, 6)``: ``x, y, z,
        rx, ry, rz`` (length unit, rad; ``R = Rz Ry Rx``), the model's held base included."""
        R, t, _ = self.station_frames(nuisance)
        out = np.empty((len(self.names), 6))
        for s in range(len(self.names)):
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = R[s], t[s]
            M = M @ self._base
            out[s] = np.r_[M[:3, 3], rpy_from_matrix(M[:3, :3])]
        return out

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict]:
        poses = self.station_poses(nuisance)
        v = np.asarray(nuisance, dtype=float).reshape(-1, 6)
        S = np.asarray(std, dtype=float).reshape(-1, 6)
        out = []
        for s, name in enumerate(self.names):
            names = station_parameter_names(name)
            out.append({"station": name, "rows": int(self.groups[s].size),
                        "pose": poses[s].tolist(),
                        "parameters": dict(zip(names, v[s].tolist(), strict=True)),
                        "std": dict(zip(names, S[s].tolist(), strict=True)),
                        "reference_rpy": rpy_from_matrix(self._R0[s]).tolist()})
        return out

    def check_data(self, model: SerialModel, params: Array, nuisance: Array) -> None:
        """A station of fewer rows than its six unknowns need is refused; measured
        orientations far from the model's tool frame after each station's registration
        warn ``tool-orientation``."""
        for s, rows in enumerate(self.groups):
            if rows.size * self.rows < 7:
                raise InputError(f"{self.name}: station {self.names[s]} has {rows.size} "
                                 f"row(s): its base frame needs more (at least 3 points)")
        if self._turn > TOOL_TURN:
            warn("tool-orientation",
                 f"{self.name}: the measured orientations differ from the model's tool frame "
                 f"by {self._turn:.3g} deg (median, each station registered on its points): "
                 "the tool frame's nominal orientation (tool: x, y, z, rx, ry, rz of the "
                 "model) is not the instrument's; give it within a few degrees (the fit may "
                 "not converge from this far)")

