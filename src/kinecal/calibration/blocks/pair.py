"""Pair distances: ``|p(q_a) - p(q_b)| - L`` for the two rows ``a, b`` of each ``pair`` id.

An artifact bar (a calibrated length between two sockets or spheres) touched at both ends,
or a known step: two tool points a known distance apart. No unknowns of its own. The
distances see the arm's scale and angles; a rigid motion of the whole arm leaves them
unchanged, so the base frame is not identified.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, tool_points
from kinecal.calibration.blocks.gauge import GaugeBlock, check_distance_rows
from kinecal.calibration.diagnostics.kinds import check_distance_units
from kinecal.data import GaugeMeasurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["PairBlock"]

Array = NDArray[np.float64]


class PairBlock(GaugeBlock):
    """Known distances between two tool points (``q1..qn,pair,distance`` files).

    The stated noise of a pair is that of its distance: the ``sigma`` of its two rows in
    quadrature divided by sqrt(2) (equal rows: that value), i.e. their RMS.
    """

    kind = "pair"
    blind_to = frozenset({"translation", "rotation"})
    noise_of = "each pair's distance"
    group_word = "pair"
    min_rows = 2
    min_reason = "a pair is two tool points"

    def __init__(self, data: GaugeMeasurements, sigma: float | None = None) -> None:
        super().__init__(data, sigma)
        live = self.live_groups
        self.a = np.array([self.groups[g][0] for g in live], dtype=np.intp)
        self.b = np.array([self.groups[g][-1] for g in live], dtype=np.intp)
        L = np.asarray(data.distance, dtype=float)
        check_distance_rows(self, L, "pair distance")
        differ = np.abs(L[self.a] - L[self.b]) > 1e-9 * np.maximum(L[self.a], L[self.b])
        if differ.any():
            i = int(np.argmax(differ))
            raise InputError(f"{self.name}: pair {data.group_names[live[i]]!r}: distances "
                             f"{L[self.a[i]]:.10g} and {L[self.b[i]]:.10g} differ; expected the "
                             "same known distance on both rows", file=self.source,
                             row=int(self.b[i]) + 1)
        self.length = L[self.a]
        if sigma is None and data.sigma is not None:
            s = np.asarray(data.sigma, dtype=float)
            self.obs_sigma = np.sqrt(0.5 * (s[self.a] ** 2 + s[self.b] ** 2))

    def _check_groups(self) -> None:
        super()._check_groups()
        sizes = np.array([rows.size for rows in self.groups], dtype=np.intp)
        if (sizes > 2).any():
            g = int(np.argmax(sizes > 2))
            name, rows = self.data.group_names[g], self.groups[g]
            raise InputError(f"{self.name}: pair {name!r} has {rows.size} rows: expected "
                             "2 (the two ends of one known distance); give each "
                             "measurement of a bar its own pair id", file=self.source,
                             row=int(rows[2]) + 1)

    def _obs_sigma(self, data: GaugeMeasurements) -> Array | None:
        return None  # set per pair in __init__

    @property
    def n_obs(self) -> int:
        return int(self.a.size)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        return np.arange(self.a.size, dtype=np.intp)

    def observation_poses(self) -> tuple[NDArray[np.intp], int]:
        """Each pair its own observation (two configurations)."""
        return np.arange(self.n_obs, dtype=np.intp), self.n_obs

    def observation_labels(self) -> list[str]:
        stem = Path(self.source).name or self.source
        return [f"{stem}:{a + 1}+{b + 1}" for a, b in zip(self.a, self.b, strict=True)]

    def start(self, model: SerialModel, params: Array) -> Array:
        return np.zeros(0)

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        P, Jt = points if points is not None else tool_points(
            model, self.q, params, self.marker, columns if jacobian else None)
        D = P[self.a] - P[self.b]
        dist = np.sqrt(np.einsum("ij,ij->i", D, D))
        r = dist - self.length
        if not jacobian:
            return BlockRows(r)
        u = D / np.maximum(dist, 1e-300)[:, None]
        arm = (np.einsum("kin,ni->nk", Jt[:, :, self.a], u)
               - np.einsum("kin,ni->nk", Jt[:, :, self.b], u))
        return BlockRows(r, arm, np.zeros((len(r), 0)))

    def observation_errors(self, r: Array) -> Array:
        return np.abs(np.asarray(r))

    def check_data(self, model: SerialModel, params: Array, nuisance: Array) -> None:
        """``scale-mismatch``: the known distances against the nominal model's."""
        P = model.positions(self.q, params, self.marker)
        check_distance_units(self.name, self.length,
                             np.linalg.norm(P[self.a] - P[self.b], axis=1),
                             model.length_unit, "pair distances")
