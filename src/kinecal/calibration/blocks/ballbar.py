"""Ballbar distances: ``|p(q) - c_g| - L`` per row, one unknown pivot ``c_g`` per ``pivot`` id.

A telescoping ballbar (or a laser interferometer on a ball) reads the distance between a
ball fixed in the workspace (the pivot) and the ball on the tool. The distances see the
arm's lengths (scale) and its angles, not where the arm stands: a rigid motion of the arm
with its pivots leaves every distance unchanged, so the base frame is not identified.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, tool_points
from kinecal.calibration.blocks.gauge import GaugeBlock, check_distance_rows
from kinecal.calibration.diagnostics.kinds import check_distance_units
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["BallbarBlock", "sphere_fit"]

Array = NDArray[np.float64]

#: rows that span less than this fraction of their extent out of a plane do not locate a
#: pivot (the mirror image across the plane fits as well)
FLAT = 1e-3


def sphere_fit(P: Array, radius: Array | None = None) -> tuple[Array, float]:
    """Centre ``(3,)`` and radius of the sphere through points ``(n, 3)`` (linear least
    squares; with known `radius` per point ``(n,)``, the centre alone).

    Raises `ValueError` when the points lie on a plane (or a line): the centre is then
    not determined (mirror images).
    """
    P = np.asarray(P, dtype=float)
    c0 = P.mean(axis=0)
    X = P - c0
    sv = np.linalg.svd(X, compute_uv=False) if len(X) >= 3 else np.zeros(3)
    if len(X) < 4 or sv[-1] <= FLAT * max(sv[0], 1e-300):
        raise ValueError("the points lie on a plane")
    # |x - c|^2 = R^2  ->  2 x.c + (R^2 - |c|^2) = |x|^2 (unknowns c, k)
    A = np.column_stack([2.0 * X, np.ones(len(X))])
    b = (X * X).sum(axis=1)
    if radius is not None:  # R known per point: the k column becomes R^2 - |c|^2 = w
        b = b - np.asarray(radius, dtype=float) ** 2
        A[:, 3] = -1.0  # 2 x.c - |c|^2 = |x|^2 - R^2  ->  unknowns c, |c|^2
    sol = np.linalg.lstsq(A, b, rcond=None)[0]
    c = sol[:3]
    R = float(np.sqrt(max(sol[3] + c @ c, 0.0))) if radius is None else float(
        np.sqrt(np.mean(np.asarray(radius) ** 2)))
    return c + c0, R


class BallbarBlock(GaugeBlock):
    """Distances from unknown pivots (``q1..qn,pivot,distance`` files)."""

    kind = "ballbar"
    blind_to = frozenset({"translation", "rotation"})
    noise_of = "each distance reading"
    group_word = "pivot"
    per_group = 3
    min_rows = 4
    min_reason = "a pivot has 3 unknown coordinates; the rows beyond them inform the arm"
    spread_code = "pivot-moved"
    spread_advice = ("a pivot that moved or a ball that slipped during the test; check "
                     "the mounts, or give each set-up its own pivot id")
    nuisance_components = ("x", "y", "z")

    def start(self, model: SerialModel, params: Array) -> Array:
        """Each pivot by a sphere fit with the stated distances as radii."""
        L = np.asarray(self.data.distance, dtype=float)
        check_distance_rows(self, L, "distance")
        P = model.positions(self.q, params, self.marker)
        out = []
        for g in self.live_groups:
            rows = self.groups[g]
            try:
                c, _ = sphere_fit(P[rows], L[rows])
            except ValueError:
                raise InputError(
                    f"{self.name}: the tool points of pivot {self.data.group_names[g]!r} lie "
                    "on one plane (a circle about the pivot): the pivot is not determined "
                    "(it could sit on either side); move more than one joint while on the "
                    "ballbar", file=self.source, row=int(rows[0]) + 1) from None
            out.append(c)
        return np.concatenate(out) if out else np.zeros(0)

    def _centres(self, nuisance: Array) -> Array:
        """Pivot of each row ``(N, 3)``."""
        C = np.zeros((len(self.groups), 3))
        C[self.live_groups] = np.asarray(nuisance, dtype=float).reshape(-1, 3)
        return C[self.data.group]

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        P, Jt = points if points is not None else tool_points(
            model, self.q, params, self.marker, columns if jacobian else None)
        D = P - self._centres(nuisance)
        dist = np.sqrt(np.einsum("ij,ij->i", D, D))
        r = dist - np.asarray(self.data.distance)
        if not jacobian:
            return BlockRows(r)
        u = D / np.maximum(dist, 1e-300)[:, None]
        arm = np.einsum("kin,ni->nk", Jt, u)
        nuis = np.zeros((len(r), self.n_nuisance))
        pos = {g: i for i, g in enumerate(self.live_groups)}
        for g, rows in enumerate(self.groups):
            if rows.size:
                nuis[rows, 3 * pos[g]:3 * pos[g] + 3] = -u[rows]
        return BlockRows(r, arm, nuis)

    def observation_errors(self, r: Array) -> Array:
        return np.abs(np.asarray(r))

    def check_data(self, model: SerialModel, params: Array, nuisance: Array) -> None:
        """``scale-mismatch``: the distances against a free-radius sphere through each
        pivot's tool points of the nominal arm."""
        P = model.positions(self.q, params, self.marker)
        L = np.asarray(self.data.distance, dtype=float)
        stated, fitted = [], []
        for g in self.live_groups:
            rows = self.groups[g]
            try:
                _, R = sphere_fit(P[rows])
            except ValueError:
                continue
            stated.append(float(np.median(L[rows])))
            fitted.append(R)
        check_distance_units(self.name, np.array(stated), np.array(fitted),
                             model.length_unit, "ballbar distances")

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict]:
        C = np.asarray(nuisance, dtype=float).reshape(-1, 3)
        S = np.asarray(std, dtype=float).reshape(-1, 3)
        return [{"pivot": self.data.group_names[g], "rows": int(self.groups[g].size),
                 "xyz": C[i].tolist(), "std": S[i].tolist()}
                for i, g in enumerate(self.live_groups)]
