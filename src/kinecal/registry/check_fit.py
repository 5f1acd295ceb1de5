"""Today's residual rows of a check at the calibration: each set's own unknowns (and the
base frame, when it is registered again) fitted with the arm held at the calibration,
then the rows and their Jacobians w.r.t. the calibration's free parameters, the unknowns
and the drift directions (`kinecal.registry.check`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["BASE", "Rows", "fit_rows"]

Array = NDArray[np.float64]

#: the base frame's parameters (registered again with ``--register base``)
BASE = tuple(f"base.{c}" for c in ("x", "y", "z", "rx", "ry", "rz"))


@dataclass
class Rows:
    """Residual rows ``r`` (m,), their noise ``s`` (m,), Jacobians ``A`` (free
    parameters), ``N`` (fitted unknowns), ``D`` (directions), observation of each row
    ``obs`` and each block's rows ``block_r``."""

    r: Array
    s: Array
    A: Array
    N: Array
    D: Array
    obs: NDArray[np.intp]
    block_r: list[Array] = field(default_factory=list)


def _split(x: Array, sizes: list[int]) -> list[Array]:
    return np.split(x, np.cumsum(sizes)[:-1]) if sizes else []


def fit_rows(model: Any, cal: Any, blocks: list, noise: list[Array], directions: list[str],
             register_base: bool) -> Rows:
    """Fit the unknowns, then the rows and Jacobians there (module docstring)."""
    from kinecal.optimize.lm import solve_normal_equations

    base = model.index(list(BASE)) if register_base else np.zeros(0, dtype=np.intp)
    p0 = np.asarray(cal.params, dtype=float)
    starts = [np.asarray(b.start(model, p0), dtype=float) for b in blocks]
    sizes = [v.size for v in starts]
    weights = [1.0 / n[b.obs_index] for b, n in zip(blocks, noise, strict=True)]
    x0 = np.concatenate([np.zeros(base.size), *starts])

    def unpack(x: Array) -> tuple[Array, list[Array]]:
        p = p0.copy()
        p[base] += x[: base.size]
        return p, _split(x[base.size:], sizes)

    def normal_equations(x: Array) -> tuple[Array, Array, Array]:
        p, vs = unpack(x)
        r_parts, J_parts = [], []
        for k, (b, v, w) in enumerate(zip(blocks, vs, weights, strict=True)):
            rows = b.evaluate(model, p, v, base, jacobian=True)
            J = np.zeros((rows.r.size, x.size))
            J[:, : base.size] = rows.arm
            at = base.size + sum(sizes[:k])
            J[:, at: at + sizes[k]] = rows.nuisance
            r_parts.append(rows.r * w)
            J_parts.append(J * w[:, None])
        r = np.concatenate(r_parts)
        J = np.vstack(J_parts)
        return r, J.T @ J, J.T @ r

    x = x0
    if x0.size:
        x = np.asarray(solve_normal_equations(normal_equations, x0, max_nfev=400).x)
    p, vs = unpack(x)
    free = model.index(cal.free)
    dirs = model.index(directions) if directions else np.zeros(0, dtype=np.intp)
    # each column once (a block's Jacobian of repeated columns is not defined), then
    # the free parameters, the directions and the base taken from it
    cols, where = np.unique(np.concatenate([free, dirs, base]).astype(np.intp),
                            return_inverse=True)
    parts = [b.evaluate(model, p, v, cols, jacobian=True)
             for b, v in zip(blocks, vs, strict=True)]
    arm = np.vstack([pr.arm for pr in parts])[:, where]
    m = arm.shape[0]
    N = np.zeros((m, x.size))
    N[:, : base.size] = arm[:, free.size + dirs.size:]
    at = 0
    for k, pr in enumerate(parts):
        n = pr.r.size
        off = base.size + sum(sizes[:k])
        N[at: at + n, off: off + sizes[k]] = pr.nuisance
        at += n
    obs_parts, first = [], 0
    for b in blocks:
        obs_parts.append(b.obs_index + first)
        first += b.n_obs
    A = arm[:, : free.size].copy()
    unbounded = [cal.free.index(n) for n in cal.unbounded]
    if unbounded:  # not determined by the calibration: as unknown as today's unknowns
        N = np.hstack([N, A[:, unbounded]])
        A[:, unbounded] = 0.0
    return Rows(np.concatenate([pr.r for pr in parts]),
                np.concatenate([n[b.obs_index] for b, n in zip(blocks, noise, strict=True)]),
                A, N, arm[:, free.size: free.size + dirs.size], np.concatenate(obs_parts),
                [pr.r for pr in parts])
