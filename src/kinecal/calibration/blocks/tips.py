"""Which chain each observation of a robot system belongs to: errors per tip, and the
residual rows each tip's data make (for the identifiability of the system).

A system's measurement rows name their tip (`kinecal.kinematics.tree.SystemModel`: the
per-row point index of the data). An observation belongs to the tips of its rows: a
tracker point, a touch or a ballbar reading to its row's tip, a ``pair`` (a bar between
two hands) to both of its ends' tips. A carried point's touch (a probe touching a
workpiece on a positioner) belongs to the probe's tip and also involves the carrier's
chain.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.pair import PairBlock
from kinecal.metrology.stats import error_stats

__all__ = ["by_tip", "column_groups", "observation_tips", "row_tips"]

Bool = NDArray[np.bool_]


def _row_tip(block: ResidualBlock) -> NDArray[np.intp] | None:
    data = getattr(block, "data", None)
    marker = getattr(data, "marker", None)
    return None if marker is None else np.asarray(marker, dtype=np.intp)


def observation_tips(block: ResidualBlock, n_tips: int) -> Bool | None:
    """``(n_tips, n_obs)``: whether each observation belongs to each tip (module
    docstring); None for a block whose rows name no tip."""
    tip = _row_tip(block)
    if tip is None:
        return None
    out = np.zeros((n_tips, block.n_obs), dtype=bool)
    if isinstance(block, PairBlock):
        for end in (block.a, block.b):
            out[tip[end], np.arange(block.n_obs)] = True
        return out
    if tip.size != block.n_obs:
        return None
    out[tip, np.arange(block.n_obs)] = True
    return out


def row_tips(block: ResidualBlock, system, tip: int) -> Bool:
    """Residual rows ``(m,)`` of `block` made by the data of chain `tip` alone: the
    observation's rows are all of that tip, and a carried point's carrier link is on its
    chain (else the row needs another chain too)."""
    obs = observation_tips(block, len(system.tips))
    if obs is None:
        return np.zeros(block.n_rows, dtype=bool)
    alone = obs[tip] & (obs.sum(axis=0) == 1)
    carrier = getattr(getattr(block, "data", None), "carrier", None)
    if carrier is not None:
        names = block.data.carrier_names
        own = set(system.chain_links(system.tips[tip]))
        on_chain = np.array([c < 0 or names[c] in own for c in np.asarray(carrier)])
        alone &= on_chain
    return alone[block.obs_index]


def by_tip(tips: Sequence[str], blocks: Sequence[ResidualBlock],
           before: Sequence[np.ndarray], after: Sequence[np.ndarray]) -> dict:
    """``{TIP: {"n", "before": {mean, rms, max, ...}, "after": {...}}}`` over the length
    errors of the observations of each tip (module docstring)."""
    out = {}
    for t, name in enumerate(tips):
        e0, e1 = [], []
        for b, x0, x1 in zip(blocks, before, after, strict=True):
            obs = observation_tips(b, len(tips))
            if obs is None or b.unit != "length":
                continue
            e0.append(np.asarray(x0)[obs[t]])
            e1.append(np.asarray(x1)[obs[t]])
        a0 = np.concatenate(e0) if e0 else np.zeros(0)
        a1 = np.concatenate(e1) if e1 else np.zeros(0)
        out[name] = {"n": int(a0.size), "before": error_stats(a0), "after": error_stats(a1)}
    return out


def column_groups(model, block: ResidualBlock, index: np.ndarray
                  ) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """The residual rows of `block` grouped by the chains they involve, each group with
    the positions in `index` (the free arm parameters) of the columns those chains reach:
    the other columns of the group's rows are zero, so the normal equations and factors
    of a robot system are built per group (``n_g k_g^2`` instead of ``m k^2``). None for a
    model that is no system, or a block whose rows name no tip."""
    chains = getattr(model, "_chains", None)
    obs = observation_tips(block, len(chains)) if chains is not None else None
    if obs is None:
        return None
    reach = [np.isin(index, c.reach) for c in chains]
    key = (obs.T.astype(np.int64) << np.arange(len(chains))).sum(axis=1)  # tips as bits
    carrier = getattr(getattr(block, "data", None), "carrier", None)
    links = []
    if carrier is not None and obs.shape[1] == len(carrier):
        names = block.data.carrier_names
        links = [np.isin(index, model._link_chain(n).reach) for n in names]
        key = key + ((np.asarray(carrier, dtype=np.int64) + 1) << len(chains))
    rows_key = key[block.obs_index]
    out = []
    for k in np.unique(rows_key):
        rows = np.flatnonzero(rows_key == k)
        cols = np.zeros(len(index), dtype=bool)
        for t in range(len(chains)):
            if (k >> t) & 1:
                cols |= reach[t]
        c = (int(k) >> len(chains)) - 1
        if c >= 0:
            cols |= links[c]
        out.append((rows, np.flatnonzero(cols)))
    if len(out) == 1 and out[0][1].size == len(index):
        return None
    return out
