"""Planes: ``n_g . p(q) - d_g`` per touch, one unknown plane ``(n_g, d_g)`` per ``plane`` id.

A touch probe (or a sphere tip) on a flat surface: the tool point is on the plane of the
ball centres, parallel to the surface. Each touch sees only the tool point's motion along
the plane's normal; several planes at different angles see the arm's angles and the
differences of its lengths, not where the arm stands nor its scale (a rigid motion or a
uniform scaling of the arm moves the planes with it). Mix with a distance for the scale.

The plane's unknowns are a small tilt ``(a, b)`` of the normal about its start value ``n0``
(from an SVD fit) and the offset ``d``: ``n = (n0 + a t1 + b t2) / sqrt(1 + a^2 + b^2)``
with ``t1, t2`` orthonormal to ``n0``; no constraint, no singularity near the start.

A plane whose position in the base frame is known (a fixture's face, FIGAROH's MATE
planes at known x, y and z; `kinecal.io.fixtures`) is no unknown, and its touches see the
motions that move it (`blind_constraints`): a translation along its normal, a rotation
about an axis in it. Three known planes with independent normals see the whole base frame;
the scale about their common point stays unseen without a distance.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, plane_constraint, tool_points
from kinecal.calibration.blocks.gauge import GaugeBlock
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["PlaneBlock", "plane_fit"]

Array = NDArray[np.float64]

#: touches that span less than this fraction of their extent across a line do not locate
#: a plane
THIN = 1e-3


def plane_fit(P: Array) -> tuple[Array, float, float]:
    """Unit normal ``(3,)``, offset ``d`` (``n . x = d``) and RMS distance of the
    least-squares plane through points ``(n, 3)`` (SVD). `ValueError` on a line."""
    P = np.asarray(P, dtype=float)
    c = P.mean(axis=0)
    _, s, Vt = np.linalg.svd(P - c, full_matrices=False)
    if len(P) < 3 or s[1] <= THIN * max(s[0], 1e-300):
        raise ValueError("the points lie on a line")
    n = Vt[-1]
    return n, float(n @ c), float(s[-1] / np.sqrt(len(P))) if len(s) > 2 else 0.0


def _tangents(n: Array) -> tuple[Array, Array]:
    """Two unit vectors orthonormal to `n` and to each other."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


class PlaneBlock(GaugeBlock):
    """Touches of unknown planes (``q1..qn,plane`` files); the stated noise is along the
    plane's normal."""

    kind = "plane"
    blind_to = frozenset({"translation", "rotation", "scale"})
    noise_of = "each touch, along the plane's normal"
    group_word = "plane"
    per_group = 3
    min_rows = 4
    min_reason = "three touches fit any plane; the fourth and later ones inform the arm"
    spread_code = "plane-not-flat"
    spread_advice = ("a surface that is not flat to the noise, a probe that slipped, or two "
                     "faces under one id; check the touches of that plane")
    nuisance_components = ("tilt_u", "tilt_v", "offset")

    def __init__(self, data, sigma=None) -> None:
        super().__init__(data, sigma)
        self.normals = np.zeros((len(self.groups), 3))
        self.tangents = np.zeros((len(self.groups), 2, 3))

    def nuisance_scale(self, length: float) -> Array:
        return np.tile([1.0 / length, 1.0 / length, 1.0], len(self.solved_groups))

    def start(self, model: SerialModel, params: Array) -> Array:
        """Each unknown plane by an SVD fit; the fitted normal becomes the reference
        ``n0``."""
        P = model.positions(self.q, params, self.marker)
        out = []
        for g in self.solved_groups:
            rows = self.groups[g]
            try:
                n, d, _ = plane_fit(P[rows])
            except ValueError:
                raise InputError(
                    f"{self.name}: the touches of plane {self.data.group_names[g]!r} lie on "
                    "one line: the plane is not determined; touch it at points spread over "
                    "its face", file=self.source, row=int(rows[0]) + 1) from None
            self.normals[g] = n
            self.tangents[g] = _tangents(n)
            out.append([0.0, 0.0, d])
        return np.concatenate(out) if out else np.zeros(0)

    def planes(self, nuisance: Array) -> tuple[Array, Array]:
        """Unit normals ``(G, 3)`` and offsets ``(G,)`` of every plane: the known ones, the
        solved ones from `nuisance` (zeros for ids without rows)."""
        N, d = np.zeros((len(self.groups), 3)), np.zeros(len(self.groups))
        if self.known is not None:
            k = self.known_mask
            N[k] = self.known[k, 3:]
            d[k] = np.einsum("ij,ij->i", self.known[k, 3:], self.known[k, :3])
        solved = self.solved_groups
        v = np.asarray(nuisance, dtype=float).reshape(-1, 3)
        m = (self.normals[solved] + v[:, :1] * self.tangents[solved, 0]
             + v[:, 1:2] * self.tangents[solved, 1])
        N[solved] = m / np.linalg.norm(m, axis=1)[:, None]
        d[solved] = v[:, 2]
        return N, d

    def blind_constraints(self) -> Array:
        """A known plane maps onto itself: a rotation about its normal only and
        ``n . t + s d = 0`` (4 rows per known plane)."""
        rows = [super().blind_constraints()]
        for g in self.live_groups:
            if self.known_mask[g]:
                rows.append(plane_constraint(self.known[g, :3], self.known[g, 3:]))
        return np.concatenate(rows)

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        P, Jt = points if points is not None else tool_points(
            model, self.q, params, self.marker, columns if jacobian else None)
        g = np.asarray(self.data.group)
        N, d = self.planes(nuisance)
        r = np.einsum("ij,ij->i", N[g], P) - d[g]
        if not jacobian:
            return BlockRows(r)
        arm = np.einsum("kin,ni->nk", Jt, N[g])
        solved = self.solved_groups
        pos = np.full(len(self.groups), -1, dtype=np.intp)
        pos[solved] = np.arange(len(solved))
        v = np.asarray(nuisance, dtype=float).reshape(-1, 3)
        s = np.sqrt(1.0 + v[:, 0] ** 2 + v[:, 1] ** 2)
        nuis = np.zeros((len(r), self.n_nuisance))
        rows = np.flatnonzero(pos[g] >= 0)  # touches of the unknown planes
        k, gr = pos[g[rows]], g[rows]
        m = N[gr] * s[k][:, None]  # unnormalised normals
        mp = np.einsum("ij,ij->i", m, P[rows])
        for c in range(2):  # d n / d a = t / s - m a / s^3
            tp = np.einsum("ij,ij->i", self.tangents[gr, c], P[rows])
            nuis[rows, 3 * k + c] = tp / s[k] - mp * v[k, c] / s[k] ** 3
        nuis[rows, 3 * k + 2] = -1.0
        return BlockRows(r, arm, nuis)

    def observation_errors(self, r: Array) -> Array:
        return np.abs(np.asarray(r))

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict]:
        N, d = self.planes(nuisance)
        S = np.zeros((len(self.groups), 3))
        S[self.solved_groups] = np.asarray(std, dtype=float).reshape(-1, 3)
        return [{"plane": self.data.group_names[g], "touches": int(self.groups[g].size),
                 "normal": N[g].tolist(), "offset": float(d[g]),
                 "std_tilt_rad": float(np.hypot(S[g, 0], S[g, 1])),
                 "std_offset": float(S[g, 2]), "known": bool(self.known_mask[g])}
                for g in self.live_groups]
