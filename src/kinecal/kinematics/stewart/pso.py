"""The paper's forward kinematics of the Stewart-platform CMM: particle swarm optimisation
(Liu, Liu and Wei 2008, papers/004 sec. 3).

:func:`forward_pso` minimises eq. 6, ``F = sum_i |l_i - l'_i|``, with linearly decreasing
inertia (eq. 7-9, settings of Table 1 in `PSO_SETTINGS`), one leg set at a time, driven by
:func:`kinecal.optimize.minimize` over the box of :func:`pso_bounds`. The exact batched
Newton solver is in `kinecal.kinematics.stewart.forward`.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.stewart.forward import ForwardResult, StewartGeometry

__all__ = ["PSO_SETTINGS", "forward_pso", "pso_bounds"]

Array = NDArray[np.float64]

#: papers/004 Table 1: k_max 500, 80 particles, w 0.5 -> 0.1, c1 = c2 = 1.8,
#: convergence precision 0.5 um (here: target of eq. 6 in m). The paper's v_max = 1 is in
#: its units (m and deg): over the box of `pso_bounds` that is no limit on the position
#: and 1/60 of the range on the angles. kinecal's PSO takes one v_max for all dimensions
#: as a fraction of each range, so 0.2 is used (measured on the Table 3 legs, 60 seeds,
#: tip within 0.5 um: v_max 1.0 -> 50/60, 0.5 -> 60/60, 0.2 -> 60/60; docs/stewart.md).
PSO_SETTINGS: dict[str, float | int] = {
    "popsize": 80,
    "maxiter": 500,
    "w_max": 0.5,
    "w_min": 0.1,
    "c1": 1.8,
    "c2": 1.8,
    "vmax": 0.2,
    "target": 0.5e-6,
}


def pso_bounds(geom: StewartGeometry) -> Array:
    """Search box of the PSO solver, shape (6, 2), in (m, m, m, deg, deg, deg).

    The box is centred on the neutral pose: ``x, y`` within +-R_p (the platform radius),
    ``z`` within +-(l_max - l_min) / 2 of the neutral height, and each angle within
    +-30 deg. papers/004 does not print its box; this one holds the whole reachable
    workspace of Table 2's machine (legs 0.75-0.97 m) and keeps the unit-hypercube
    velocity limit ``v_max = 1`` meaningful (docs/stewart.md).
    """
    x0 = geom.neutral_pose()
    lo, hi = geom.leg_range
    rp = float(np.linalg.norm(geom.platform_joints[:, :2], axis=1).max())
    dz = 0.5 * (hi - lo) if np.isfinite(hi) else rp
    half = np.array([rp, rp, dz, 30.0, 30.0, 30.0])
    centre = np.array([x0[0], x0[1], x0[2], 0.0, 0.0, 0.0])
    return np.stack([centre - half, centre + half], axis=1)


def forward_pso(
    geom: StewartGeometry,
    legs: Array,
    *,
    rng: np.random.Generator | int | None = None,
    bounds: ArrayLike | None = None,
    **settings: float,
) -> ForwardResult:
    """The paper's forward kinematics: minimise eq. 6 by PSO, one leg set at a time.

    Parameters
    ----------
    geom : StewartGeometry
    legs : ndarray, shape (N, 6)
        Leg readings (length unit).
    rng : Generator or int, optional
        Random generator or seed (same seed -> same result).
    bounds : array_like, shape (6, 2), optional
        Search box in (length unit x3, deg x3); default :func:`pso_bounds`.
    **settings
        Overrides of `PSO_SETTINGS` (papers/004 Table 1): popsize, maxiter, w_max, w_min,
        c1, c2, vmax, target (objective value of eq. 6 at which to stop, length unit).

    Returns
    -------
    ForwardResult
        ``residual`` is the max abs leg error of the best particle; ``converged`` is eq. 6
        at or below ``target``; ``iterations`` the generations used.
    """
    from kinecal.optimize import minimize

    unknown = set(settings) - set(PSO_SETTINGS)
    if unknown:
        raise InputError(f"unknown PSO settings {sorted(unknown)}", option="options")
    cfg = {**PSO_SETTINGS, **settings}
    box = pso_bounds(geom) if bounds is None else np.asarray(bounds, dtype=float)
    gen = np.random.default_rng(rng)
    t0 = time.perf_counter()
    L = np.asarray(legs, dtype=float)
    n = L.shape[0]
    poses = np.zeros((n, 6))
    res = np.zeros(n)
    its = np.zeros(n, dtype=np.int64)
    nfev = np.zeros(n, dtype=np.int64)
    converged = np.zeros(n, dtype=bool)
    history = []
    options = {k: cfg[k] for k in ("popsize", "w_max", "w_min", "c1", "c2", "vmax")}
    for i in range(n):  # one optimisation per reading; each one evaluates its swarm at once

        def cost(X: Array, Li: Array = L[i]) -> Array:
            x = np.array(X, dtype=float)
            x[:, 3:] = np.deg2rad(x[:, 3:])
            return np.abs(geom.inverse(x) - Li).sum(axis=1)  # papers/004 eq. 6

        out = minimize(
            cost,
            box,
            method="pso-liu2008",  # the paper's PSO (kinecal's "pso" is the constriction PSO)
            rng=gen,
            maxiter=int(cfg["maxiter"]),
            target=float(cfg["target"]),
            options=options,
        )
        x = np.array(out.x, dtype=float)
        x[3:] = np.deg2rad(x[3:])
        poses[i] = x
        res[i] = np.abs(geom.inverse(x) - L[i]).max()
        its[i] = int(out.nit)
        nfev[i] = int(out.nfev)
        converged[i] = float(out.fun) <= float(cfg["target"])
        history.append(np.asarray(out.history, dtype=float))
    elapsed = time.perf_counter() - t0
    return ForwardResult(poses, converged, res, its, elapsed, "pso", nfev, history)
