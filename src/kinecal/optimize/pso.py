"""Particle swarm optimization with linearly decreasing inertia (papers/004, section 3).

Liu, Liu, Wei (2008) solve the forward kinematics of a Stewart-platform CMM with the global-best
PSO of Kennedy and Eberhart plus Shi and Eberhart's inertia weight:

- velocity (papers/004 eq. 7): ``v = w v + c1 r1 (pbest - x) + c2 r2 (gbest - x)``, with ``r1``,
  ``r2`` uniform in ``(0, 1)``, drawn per particle and per dimension;
- position (eq. 8): ``x = x + v``;
- inertia decreasing linearly with the iteration ``k`` (eq. 9):
  ``w = w_max - k (w_max - w_min) / k_max``;
- speeds limited to ``vmax`` and positions to the search box (section 3.2).

Defaults are the paper's Table 1: 80 particles, ``w_max = 0.5``, ``w_min = 0.1``,
``c1 = c2 = 1.8``, ``vmax = 1``, ``k_max = 500``.

Scaling: kinecal searches the unit hypercube, so ``vmax`` is a fraction of each variable's range
(``vmax = 1``: one full range per iteration). The paper's ``vmax = 1`` is in its own units (m and
degrees over a box of about a metre), so the unit-cube default keeps its value, not its unit.
A particle leaving the box is put back on its face (position limit); its velocity is kept.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.optimize._common import Optimizer, as_int, as_positive, clip_unit

__all__ = ["PSO"]


class PSO(Optimizer):
    """Global-best PSO with linearly decreasing inertia weight (papers/004 eq. 7-9).

    Options
    -------
    popsize : int
        Number of particles M (papers/004 Table 1: 80).
    w_max, w_min : float
        Initial and final inertia weight (eq. 9; Table 1: 0.5 and 0.1).
    c1, c2 : float
        Cognitive and social learning factors (eq. 7; Table 1: 1.8 and 1.8).
    vmax : float
        Speed limit per dimension, as a fraction of the variable's range (Table 1: 1).

    Notes
    -----
    The horizon ``k_max`` of eq. 9 is ``maxiter`` (default 500, Table 1). Initial velocities are
    uniform in ``[-vmax, vmax]``.
    """

    name: ClassVar[str] = "pso"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 80,
        "w_max": 0.5,
        "w_min": 0.1,
        "c1": 1.8,
        "c2": 1.8,
        "vmax": 1.0,
    }
    default_maxiter: ClassVar[int] = 500

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 1)
        self.w_max = as_positive("w_max", options["w_max"], allow_zero=True)
        self.w_min = as_positive("w_min", options["w_min"], allow_zero=True)
        self.c1 = as_positive("c1", options["c1"], allow_zero=True)
        self.c2 = as_positive("c2", options["c2"], allow_zero=True)
        self.vmax = as_positive("vmax", options["vmax"])

    def inertia(self, k: int) -> float:
        """Inertia weight at iteration ``k`` (papers/004 eq. 9), ``k = 0 .. maxiter``."""
        kmax = max(self.maxiter, 1)
        return self.w_max - min(k, kmax) * (self.w_max - self.w_min) / kmax

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, P, n = self.rng, self.popsize, self.n
        x = self.initial_population(P)
        v = rng.uniform(-self.vmax, self.vmax, (P, n))
        f = yield x
        pbest, pbest_f = x.copy(), f.copy()
        self.population, self.energies = pbest, pbest_f
        g = int(np.argmin(pbest_f))
        c = np.array([self.c1, self.c2]).reshape(2, 1, 1)
        vmax = self.vmax
        while True:
            w = self.inertia(self.nit)
            r = rng.random((2, P, n))
            r *= c  # c1 r1, c2 r2
            # eq. 7
            v *= w
            v += r[0] * (pbest - x)
            v += r[1] * (pbest[g] - x)
            np.maximum(v, -vmax, out=v)
            np.minimum(v, vmax, out=v)
            # eq. 8 and the position limits of section 3.2
            x = x + v
            clip_unit(x)
            f = yield x
            better = f < pbest_f
            np.copyto(pbest, x, where=better[:, None])
            np.copyto(pbest_f, f, where=better)
            g = int(np.argmin(pbest_f))
            self.nit += 1
