"""Fixed points: ``p(q) - c_g`` (3 rows per touch), one unknown point ``c_g`` per ``point`` id.

A sphere tip seated in a fixed socket or cone, touched in many arm configurations (MUKCa's
printed plate with two sockets). The touches see the arm's angles and the differences of
its lengths, not where the arm stands nor its scale: a rigid motion or a uniform scaling
of the whole arm moves the points with it. Mix with a distance (a ballbar, a bar's pair)
to fix the scale.

A point whose position in the base frame is known (a calibration block's socket,
`kinecal.io.fixtures`) is no unknown: it stays where it is when the arm moves, so its
touches see the motions that move it (`blind_constraints`): one known point, the
translation of the base frame; three not on a line, the whole base frame and the scale.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, point_constraint, tool_points
from kinecal.calibration.blocks.gauge import GaugeBlock
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["PointBlock"]

Array = NDArray[np.float64]


class PointBlock(GaugeBlock):
    """Touches of unknown fixed points (``q1..qn,point`` files); the stated noise is per
    coordinate of a touch."""

    kind = "point"
    blind_to = frozenset({"translation", "rotation", "scale"})
    obs_dof = 3
    noise_of = "each coordinate of a touch"
    group_word = "point"
    per_group = 3
    min_rows = 2
    min_reason = "one touch only locates the point; the second and later ones inform the arm"
    spread_code = "point-spread"
    spread_advice = ("a socket that moved, a tip that did not seat, or two sockets under one "
                     "id; check the touches of that point")
    nuisance_components = ("x", "y", "z")

    def group_residual_rows(self, g: int) -> NDArray[np.intp]:
        rows = self.groups[g]
        return (3 * rows[:, None] + np.arange(3)).ravel()

    def start(self, model: SerialModel, params: Array) -> Array:
        """Each unknown point as the centroid of its touches."""
        P = model.positions(self.q, params, self.marker)
        out = [P[self.groups[g]].mean(axis=0) for g in self.solved_groups]
        return np.concatenate(out) if out else np.zeros(0)

    def centres(self, nuisance: Array) -> Array:
        """Every point ``(G, 3)``: the known ones, the solved ones from `nuisance`."""
        C = np.zeros((len(self.groups), 3))
        if self.known is not None:
            C[self.known_mask] = self.known[self.known_mask]
        C[self.solved_groups] = np.asarray(nuisance, dtype=float).reshape(-1, 3)
        return C

    def blind_constraints(self) -> Array:
        """A known point ``c`` stays: ``t + w x c + s c = 0`` (3 rows per known point)."""
        rows = [super().blind_constraints()]
        for g in self.live_groups:
            if self.known_mask[g]:
                rows.append(point_constraint(self.known[g]))
        return np.concatenate(rows)

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        P, Jt = points if points is not None else tool_points(
            model, self.q, params, self.marker, columns if jacobian else None)
        g = np.asarray(self.data.group)
        r = (P - self.centres(nuisance)[g]).ravel()
        if not jacobian:
            return BlockRows(r)
        arm = Jt.transpose(2, 1, 0).reshape(r.size, Jt.shape[0])
        nuis = np.zeros((r.size, self.n_nuisance))
        pos = np.full(len(self.groups), -1, dtype=np.intp)
        pos[self.solved_groups] = np.arange(len(self.solved_groups))
        rows = np.flatnonzero(pos[g] >= 0)  # touches of the unknown points
        for c in range(3):
            nuis[3 * rows + c, 3 * pos[g[rows]] + c] = -1.0
        return BlockRows(r, arm, nuis)

    def observation_errors(self, r: Array) -> Array:
        e = np.asarray(r).reshape(-1, 3)
        return np.sqrt(np.einsum("ij,ij->i", e, e))

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict]:
        C = self.centres(nuisance)
        S = np.zeros((len(self.groups), 3))
        S[self.solved_groups] = np.asarray(std, dtype=float).reshape(-1, 3)
        return [{"point": self.data.group_names[g], "touches": int(self.groups[g].size),
                 "xyz": C[g].tolist(), "std": S[g].tolist(),
                 "known": bool(self.known_mask[g])} for g in self.live_groups]
