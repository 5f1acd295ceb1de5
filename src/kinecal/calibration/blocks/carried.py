"""Points carried by a moving link: ``p_tip(q) - T_link(q) c_g`` (3 rows per touch).

A probe on an arm touches a point of a workpiece clamped on a positioner's table: the
point is fixed in the table's link frame, not in the measurement frame, and the row gives
the joints of both chains (the arm's and the positioner's). Its unknown ``c_g`` is the
point in the carrier link's frame; the residual involves the probe's chain through the tip
point and the carrier's chain through the link pose (`SystemModel.link_points`), so the
touches identify the positioner's geometry relative to the arm. Groups whose rows carry no
carrier are ordinary fixed points (`PointBlock`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, point_constraint, tool_points
from kinecal.calibration.blocks.point import PointBlock
from kinecal.data import GaugeMeasurements
from kinecal.errors import InputError

__all__ = ["CarriedPointBlock"]

Array = NDArray[np.float64]


class CarriedPointBlock(PointBlock):
    """Touches of points fixed in the measurement frame or in a moving link (a ``point``
    file with a ``carrier`` column, on a robot system)."""

    def __init__(self, data: GaugeMeasurements, sigma: float | None = None) -> None:
        super().__init__(data, sigma)
        carrier = np.asarray(data.carrier, dtype=np.intp)
        self.carrier = carrier
        self.group_carrier = np.full(len(self.groups), -1, dtype=np.intp)
        for g, rows in enumerate(self.groups):
            found = np.unique(carrier[rows])
            if found.size > 1:
                names = ["(fixed)" if c < 0 else data.carrier_names[c] for c in found]
                raise InputError(f"{self.name}: point {data.group_names[g]!r} is carried by "
                                 f"{' and '.join(names)}: expected one carrier per point id",
                                 file=self.source, row=int(rows[0]) + 1)
            if found.size:
                self.group_carrier[g] = found[0]

    def _carried(self) -> list[tuple[str, NDArray[np.intp]]]:
        """Each carrier link with the rows it carries."""
        out = []
        for c, link in enumerate(self.data.carrier_names):
            rows = np.flatnonzero(self.carrier == c)
            if rows.size:
                out.append((link, rows))
        return out

    def start(self, model, params: Array) -> Array:
        """Each unknown point as the centroid of its touches, in its carrier's frame."""
        P = model.positions(self.q, params, self.marker)
        local = P.copy()
        for link, rows in self._carried():
            T = model.link_poses(self.q[rows], link, params)
            local[rows] = np.einsum("nji,nj->ni", T[:, :3, :3], P[rows] - T[:, :3, 3])
        out = [local[self.groups[g]].mean(axis=0) for g in self.solved_groups]
        return np.concatenate(out) if out else np.zeros(0)

    def blind_constraints(self) -> Array:
        """A known point fixed in the measurement frame stays when the system moves (a
        carried one moves with its link)."""
        rows = [super(PointBlock, self).blind_constraints()]
        for g in self.live_groups:
            if self.known_mask[g] and self.group_carrier[g] < 0:
                rows.append(point_constraint(self.known[g]))
        return np.concatenate(rows)

    def evaluate(self, model, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        cols = columns if jacobian else None
        P, Jt = points if points is not None else tool_points(
            model, self.q, params, self.marker, cols)
        g = np.asarray(self.data.group)
        X = self.centres(nuisance)[g]
        n = len(self.q)
        R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        JX = None if cols is None else np.zeros((len(cols), 3, n))
        for link, rows in self._carried():
            X[rows], Jr, R[rows] = model.link_points(self.q[rows], link, X[rows], params, cols)
            if JX is not None:
                JX[:, :, rows] = Jr
        r = (P - X).ravel()
        if not jacobian:
            return BlockRows(r)
        arm = (Jt - JX).transpose(2, 1, 0).reshape(r.size, Jt.shape[0])
        nuis = np.zeros((r.size, self.n_nuisance))
        pos = np.full(len(self.groups), -1, dtype=np.intp)
        pos[self.solved_groups] = np.arange(len(self.solved_groups))
        rows = np.flatnonzero(pos[g] >= 0)  # touches of the unknown points
        for a in range(3):
            for b in range(3):
                nuis[3 * rows + a, 3 * pos[g[rows]] + b] = -R[rows, a, b]
        return BlockRows(r, arm, nuis)

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict]:
        out = super().nuisance_report(nuisance, std)
        for entry, g in zip(out, self.live_groups, strict=True):
            c = self.group_carrier[g]
            entry["frame"] = "measurement" if c < 0 else self.data.carrier_names[c]
        return out
