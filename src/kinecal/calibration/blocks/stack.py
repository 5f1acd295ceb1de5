"""`StackedProblem`: the arm's free parameters and every block's nuisance in one vector.

Unknowns ``x = [arm free (k) | nuisance of block 1 | nuisance of block 2 | ...]``; residual
rows ``r_b / sigma_b`` of every block, stacked (unitless: each row divided by the noise of
its observation). The normal equations are assembled block by block (the arm columns are
shared, each block's nuisance columns are its own), never as the dense stacked Jacobian;
`jacobian` forms it for the robust losses and the tests.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import ResidualBlock, tool_points
from kinecal.calibration.blocks.tips import column_groups
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.lsq import levenberg_marquardt

__all__ = ["NormalPart", "StackedProblem", "fit_nuisance"]

Array = NDArray[np.float64]

#: points whose `StackedProblem.normal_parts` are kept (a solver's last accepted point and
#: the trial points after it)
PARTS_KEPT = 3


class NormalPart(NamedTuple):
    """One block's weighted residual rows and share of the normal equations
    (`StackedProblem.normal_parts`)."""

    r: Array  #: weighted residual rows (m_b,)
    aa: Array  #: J_a^T J_a (k, k)
    an: Array  #: J_a^T J_n (k, n_b)
    nn: Array  #: J_n^T J_n (n_b, n_b)
    ga: Array  #: J_a^T r (k,)
    gn: Array  #: J_n^T r (n_b,)
    dense: bool = False  #: formed from the block's dense rows (not `arm_normal`)


class StackedProblem:
    """Least-squares view of a calibration from several residual blocks.

    Parameters
    ----------
    model : SerialModel
        Nominal model (start point; values of the parameters held).
    blocks : sequence of ResidualBlock
        The measurement sets, each `start`-ed (their references set).
    free : sequence of str
        The arm's free parameters.
    sigma : sequence of ndarray
        Noise per observation ``(n_obs,)`` of each block (block unit).
    params : ndarray, shape (n_params,), optional
        Values of the held parameters (default nominal).
    """

    #: the solution does not change when every block's noise is scaled by one factor (no
    #: rows of other weight, such as a prior's)
    scale_free: bool = True

    def __init__(self, model: SerialModel, blocks: Sequence[ResidualBlock],
                 free: Sequence[str], sigma: Sequence[Array],
                 params: Array | None = None) -> None:
        self.model = model
        self.blocks = list(blocks)
        self.free = list(free)
        self.index = model.index(self.free)
        self.k = len(self.free)
        self.base_params = model.nominal if params is None else np.asarray(params, float).copy()
        sizes = [b.n_nuisance for b in self.blocks]
        ends = self.k + np.cumsum([0, *sizes])
        self.slices = [slice(int(a), int(b)) for a, b in pairwise(ends)]
        self.n = int(ends[-1])
        rows = np.cumsum([0, *[b.n_rows for b in self.blocks]])
        self.row_slices = [slice(int(a), int(b)) for a, b in pairwise(rows)]
        self.m = int(rows[-1])
        #: observations left out of the fit (weight zero): ``(block, observation)``
        self.excluded: list[tuple[int, int]] = []
        #: the last `normal_parts` at the problem's own weights: ``(x, weights, parts)``
        self._parts_cache: list[tuple] = []
        self.set_sigma(sigma)
        # a robot system's rows reach their chains' columns only (`tips.column_groups`)
        self.groups = [column_groups(model, b, self.index) for b in self.blocks]
        # the blocks whose tool points one shared sweep computes
        self._shared = [i for i, b in enumerate(self.blocks) if b.shares_tool_points]
        if self._shared:
            qs = [self.blocks[i].configurations() for i in self._shared]
            self._q = np.concatenate([q for q, _ in qs])
            self._marker = (np.concatenate([np.zeros(len(q), np.intp) if mk is None else mk
                                            for q, mk in qs]) if model.marker_names else None)
            ends = np.cumsum([0, *[len(q) for q, _ in qs]])
            self._point_slices = dict(zip(self._shared, (slice(int(a), int(b))
                                                           for a, b in pairwise(ends)),
                                          strict=True))

    def set_sigma(self, sigma: Sequence[Array]) -> None:
        """Set the noise per observation of each block (the row weights ``1 / sigma``;
        zero for the `excluded` observations)."""
        self.sigma = [np.asarray(s, dtype=float) for s in sigma]
        self.row_weight = [1.0 / s[b.obs_index] for s, b in zip(self.sigma, self.blocks,
                                                                strict=True)]
        for i, j in self.excluded:
            self.row_weight[i][self.blocks[i].obs_index == j] = 0.0

    def exclude(self, observations: Sequence[tuple[int, int]]) -> None:
        """Leave the observations ``(block, observation)`` out of the fit (their rows
        weigh zero; their residuals are still computed), replacing those left out
        before."""
        self.excluded = [(int(i), int(j)) for i, j in observations]
        self.set_sigma(self.sigma)

    @property
    def used_rows(self) -> list[int]:
        """Residual rows of each block that enter the fit (not `excluded`)."""
        return [int(np.count_nonzero(w)) if self.excluded else b.n_rows
                for w, b in zip(self.row_weight, self.blocks, strict=True)]

    @property
    def m_used(self) -> int:
        """Residual rows that enter the fit."""
        return int(sum(self.used_rows)) if self.excluded else self.m

    # ------------------------------------------------------------------ layout
    @property
    def names(self) -> list[str]:
        """Names of ``x``: the arm's free parameters, then every block's nuisance."""
        return self.free + [n for b in self.blocks for n in b.nuisance_names]

    def params(self, x: Array) -> Array:
        """Full arm parameter vector ``(n_params,)`` at `x`."""
        p = self.base_params.copy()
        p[self.index] = np.asarray(x, dtype=float)[:self.k]
        return p

    def nuisance(self, x: Array) -> list[Array]:
        """Each block's nuisance at `x`."""
        x = np.asarray(x, dtype=float)
        return [x[s] for s in self.slices]

    def pack(self, params: Array, nuisance: Sequence[Array]) -> Array:
        """``x`` from a full parameter vector and the blocks' nuisance."""
        x = np.empty(self.n)
        x[:self.k] = np.asarray(params, dtype=float)[self.index]
        for s, v in zip(self.slices, nuisance, strict=True):
            x[s] = v
        return x

    # ------------------------------------------------------------------ rows
    def _points(self, p: Array, jacobian: bool) -> dict[int, tuple]:
        """Tool points (and their Jacobian) of the sharing blocks, one sweep for all."""
        if not self._shared:
            return {}
        P, Jt = tool_points(self.model, self._q, p, self._marker,
                            self.index if jacobian else None)
        return {i: (P[s], None if Jt is None else Jt[:, :, s])
                for i, s in self._point_slices.items()}

    def block_residuals(self, x: Array) -> list[Array]:
        """Unweighted residuals of each block at `x` (block units)."""
        p = self.params(x)
        pts = self._points(p, False)
        return [b.evaluate(self.model, p, v, points=pts.get(i)).r
                for i, (b, v) in enumerate(zip(self.blocks, self.nuisance(x), strict=True))]

    def residuals(self, x: Array) -> Array:
        """Weighted residual vector ``(m,)``."""
        r = self.block_residuals(x)
        return np.concatenate([ri * w for ri, w in zip(r, self.row_weight, strict=True)]
                              ) if r else np.zeros(0)

    def _weighted_rows(self, x: Array, only: Sequence[bool] | None = None):
        """Each block's weighted ``(r, J_arm, J_nuisance, columns)`` at `x` (dense rows;
        `only`: the blocks wanted, None yielded for the others)."""
        p = self.params(x)
        pts = self._points(p, True)
        for i, (b, v, w, s) in enumerate(zip(self.blocks, self.nuisance(x), self.row_weight,
                                             self.slices, strict=True)):
            if only is not None and not only[i]:
                yield None
                continue
            rows = b.evaluate(self.model, p, v, self.index, jacobian=True, points=pts.get(i))
            yield rows.r * w, rows.arm * w[:, None], rows.nuisance * w[:, None], s

    def jacobian(self, x: Array) -> Array:
        """Dense weighted Jacobian ``(m, n)`` of `residuals`."""
        J = np.zeros((self.m, self.n))
        for (_, Ja, Jn, s), rs in zip(self._weighted_rows(x), self.row_slices, strict=True):
            J[rs, :self.k] = Ja
            J[rs, s] = Jn
        return J

    def arm_gram(self, i: int, Ja: Array) -> Array:
        """``Ja^T Ja`` ``(k, k)`` of block `i`'s weighted arm rows, group by group where the
        rows of a robot system's chains reach some columns only (`groups`)."""
        groups = self.groups[i]
        if groups is None:
            return Ja.T @ Ja
        G = np.zeros((self.k, self.k))
        for rows, cols in groups:
            Jg = Ja[np.ix_(rows, cols)]
            G[np.ix_(cols, cols)] += Jg.T @ Jg
        return G

    def normal_parts(self, x: Array, weights: Sequence[Array] | None = None
                     ) -> list[NormalPart]:
        """Each block's weighted residual and share of the normal equations at `x`.

        A block without unknowns of its own that accumulates them itself
        (`ResidualBlock.arm_normal`: a tracker's rows, chunk by chunk and chain by chain)
        never forms its rows; the others' are formed from `ResidualBlock.evaluate`.
        `weights`: per block, row weights replacing `row_weight` (zero leaves a row out).
        The parts at the problem's own weights are kept for the last `PARTS_KEPT` points
        (the blocks must not change meanwhile: a block changed is a new problem).
        """
        own = weights is None
        weights = self.row_weight if own else weights
        x = np.asarray(x, dtype=float)
        if own:  # the solver's last points: the noise estimate asks again where it stopped
            for cx, cw, parts in self._parts_cache:
                if np.array_equal(cx, x) and all(np.array_equal(a, b) for a, b in
                                                 zip(cw, weights, strict=True)):
                    return list(parts)
        p = self.params(x)
        out: list[NormalPart] = []
        dense = []
        for i, (b, w) in enumerate(zip(self.blocks, weights, strict=True)):
            got = (b.arm_normal(self.model, p, self.index, w, self.groups[i])
                   if b.n_nuisance == 0 else None)
            out.append(None if got is None else NormalPart(
                got[0], got[1], np.zeros((self.k, 0)), np.zeros((0, 0)), got[2], np.zeros(0)))
            dense.append(got is None)
        if any(dense):
            pts = self._points(p, True)
            for i, (b, v, w) in enumerate(zip(self.blocks, self.nuisance(x), weights,
                                              strict=True)):
                if not dense[i]:
                    continue
                share = (b.normal_parts(self.model, p, v, self.index, w)
                         if self.groups[i] is None else None)
                if share is not None:  # block-sparse: the block sums its own share
                    out[i] = NormalPart(*share)
                    continue
                rows = b.evaluate(self.model, p, v, self.index, jacobian=True,
                                  points=pts.get(i))
                r, Ja, Jn = rows.r * w, rows.arm * w[:, None], rows.nuisance * w[:, None]
                out[i] = NormalPart(r, self.arm_gram(i, Ja), Ja.T @ Jn, Jn.T @ Jn, Ja.T @ r,
                                    Jn.T @ r, True)
        if own:
            self._parts_cache = [(x.copy(), [w.copy() for w in weights], out),
                                 *self._parts_cache][:PARTS_KEPT]
        return list(out)

    def assemble(self, parts: Sequence[NormalPart], x: Array) -> tuple[Array, Array, Array]:
        """``(residuals, J^T J, J^T r)`` at `x` from the blocks' `normal_parts` there (a
        subclass adds further rows: a prior's)."""
        A = np.zeros((self.n, self.n))
        g = np.zeros(self.n)
        k = self.k
        for part, s in zip(parts, self.slices, strict=True):
            A[:k, :k] += part.aa
            A[:k, s] = part.an
            A[s, :k] = part.an.T
            A[s, s] = part.nn
            g[:k] += part.ga
            g[s] = part.gn
        r = np.concatenate([p.r for p in parts]) if parts else np.zeros(0)
        return r, A, g

    def normal_equations(self, x: Array) -> tuple[Array, Array, Array]:
        """``(residuals, J^T J, J^T r)`` at `x`, assembled block by block."""
        return self.assemble(self.normal_parts(x), x)

    def block_grams(self, x: Array) -> list[Array]:
        """Each block's share ``J_b^T J_b`` ``(n, n)`` of the normal matrix (weighted)."""
        out = []
        k = self.k
        for part, s in zip(self.normal_parts(x), self.slices, strict=True):
            G = np.zeros((self.n, self.n))
            G[:k, :k] = part.aa
            G[:k, s] = part.an
            G[s, :k] = part.an.T
            G[s, s] = part.nn
            out.append(G)
        return out

    def monitor(self, r: Array) -> float:
        """RMS of the weighted residual (1 when the noise is what was stated)."""
        return float(np.sqrt(np.mean(np.square(r)))) if r.size else 0.0


def fit_nuisance(block: ResidualBlock, model: SerialModel, params: Array, start: Array,
                 sigma: Array | None = None) -> tuple[Array, Array]:
    """A block's nuisance fitted with the arm held at `params` (start values, validation).

    Returns
    -------
    nuisance : ndarray, shape (n_b,)
    r : ndarray, shape (m_b,)
        Unweighted residuals there.
    """
    start = np.asarray(start, dtype=float)
    w = 1.0 if sigma is None else 1.0 / np.asarray(sigma, float)[block.obs_index]
    if start.size == 0:
        return start, block.evaluate(model, params, start).r
    if block.n_rows < start.size:
        raise InputError(f"{block.name}: {block.n_rows} residual rows for {start.size} "
                         "unknowns of its own")

    none = np.zeros(0, dtype=np.intp)
    points = None
    if block.shares_tool_points:  # the arm is held: its tool points once, not per step
        q, marker = block.configurations()
        points = (model.positions(q, params, marker), np.zeros((0, 3, len(q))))

    def residual(v: Array) -> Array:
        return block.evaluate(model, params, v, points=points).r * w

    def jacobian(v: Array) -> Array:
        rows = block.evaluate(model, params, v, none, jacobian=True, points=points)
        return rows.nuisance * (w[:, None] if np.ndim(w) else w)

    normal = None
    cols = np.zeros(0, dtype=np.intp)
    wr = np.broadcast_to(np.asarray(w, dtype=float), (block.n_rows,))
    if block.normal_parts(model, params, start, cols, wr) is not None:

        def normal(v: Array) -> tuple[Array, Array, Array]:  # block-sparse, no dense rows
            r, _, _, A, _, g = block.normal_parts(model, params, v, cols, wr)
            return r, A, g

    res = levenberg_marquardt.fit(residual, jacobian, start, max_nfev=200,
                              normal_equations=normal)
    v = np.asarray(res.x, dtype=float)
    return v, block.evaluate(model, params, v, points=points).r
