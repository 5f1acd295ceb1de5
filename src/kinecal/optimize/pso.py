"""Particle swarm optimization: constriction PSO (default) and the linear-inertia PSO of papers/004.

``pso`` (:class:`ConstrictionPSO`): Clerc and Kennedy (2002), "The particle swarm - explosion,
stability, and convergence in a multidimensional complex space", IEEE Trans. Evol. Comput.
6(1):58-73. Velocity ``v = chi (v + c1 r1 (pbest - x) + c2 r2 (lbest - x))``, position
``x = x + v``, with the constriction coefficient of their type 1'' model,
``chi = 2 kappa / |2 - phi - sqrt(phi^2 - 4 phi)|``, ``phi = c1 + c2 > 4`` (``c1 = c2 = 2.05``,
``kappa = 1`` give ``chi = 0.7298``). ``lbest`` is the best personal best of the particle's
neighbourhood (:data:`TOPOLOGIES`): the whole swarm (``"global"``, Kennedy and Eberhart's gbest)
or the particle and its two ring neighbours (``"ring"``, lbest with k = 2; Kennedy and Mendes
2002, "Population structure and particle swarm performance", CEC 2002). Speeds are limited to
``vmax = Xmax`` (Eberhart and Shi 2000, "Comparing inertia weights and constriction factors in
particle swarm optimization", CEC 2000), here half of each range. A particle leaving the box is
put on its face and its velocity along that axis is set to 0 (absorbing walls).

``pso-liu2008`` (:class:`LinearInertiaPSO`): Liu, Liu, Wei (2008) solve the forward kinematics of
a Stewart-platform CMM with the global-best PSO of Kennedy and Eberhart plus Shi and Eberhart's
inertia weight:

- velocity (papers/004 eq. 7): ``v = w v + c1 r1 (pbest - x) + c2 r2 (gbest - x)``, with ``r1``,
  ``r2`` uniform in ``(0, 1)``, drawn per particle and per dimension;
- position (eq. 8): ``x = x + v``;
- inertia decreasing linearly with the iteration ``k`` (eq. 9):
  ``w = w_max - k (w_max - w_min) / k_max``;
- speeds limited to ``vmax`` and positions to the search box (section 3.2).

Defaults are the paper's Table 1: 80 particles, ``w_max = 0.5``, ``w_min = 0.1``,
``c1 = c2 = 1.8``, ``vmax = 1``, ``k_max = 500``. ``kinecal reproduce liu2008`` and
:func:`kinecal.kinematics.stewart.pso.forward_pso` use this variant.

Scaling: kinecal searches the unit hypercube, so ``vmax`` is a fraction of each variable's range
(``vmax = 1``: one full range per iteration). The paper's ``vmax = 1`` is in its own units (m and
degrees over a box of about a metre), so the unit-cube default keeps its value, not its unit.
In the paper's PSO a particle leaving the box is put back on its face; its velocity is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._common import Optimizer, as_int, as_positive, clip_unit

__all__ = [
    "TOPOLOGIES",
    "ConstrictionPSO",
    "LinearInertiaPSO",
    "constriction",
    "global_best",
    "ring_best",
]


def global_best(f: np.ndarray) -> np.ndarray:
    """Neighbourhood best of the gbest topology: the swarm's best index, a 0-d array."""
    return np.argmin(f)


def ring_best(f: np.ndarray) -> np.ndarray:
    """Neighbourhood best of the ring (lbest, k = 2): per particle ``i`` the best of
    ``i - 1, i, i + 1`` (mod P), indices of shape ``(P,)``."""
    P = f.size
    idx = np.arange(P)
    left, right = (idx - 1) % P, (idx + 1) % P
    best = np.where(f[left] < f, left, idx)
    return np.where(f[right] < f[best], right, best)


#: neighbourhood topologies: name -> function of the personal-best costs giving the index of
#: each particle's neighbourhood best
TOPOLOGIES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "global": global_best,
    "ring": ring_best,
}


def constriction(c1: float, c2: float, kappa: float = 1.0) -> float:
    """Constriction coefficient ``2 kappa / |2 - phi - sqrt(phi^2 - 4 phi)|`` (Clerc, Kennedy 2002).

    Parameters
    ----------
    c1, c2 : float
        Acceleration coefficients, ``phi = c1 + c2 > 4``.
    kappa : float
        In ``(0, 1]``; smaller values slow the swarm down (more exploitation).
    """
    phi = c1 + c2
    if not phi > 4.0:
        raise InputError(f"expected c1 + c2 > 4 (constriction), got {phi!r}", option="c1")
    return 2.0 * kappa / abs(2.0 - phi - np.sqrt(phi * phi - 4.0 * phi))


class ConstrictionPSO(Optimizer):
    """PSO with Clerc and Kennedy's constriction coefficient and a neighbourhood topology.

    Options
    -------
    popsize : int
        Number of particles (default 40).
    c1, c2 : float
        Cognitive and social acceleration coefficients (default 2.05 each, Clerc and Kennedy
        2002; ``c1 + c2 > 4``).
    kappa : float
        Constriction parameter in ``(0, 1]`` (default 1): ``chi = constriction(c1, c2, kappa)``.
    topology : {"global", "ring"}
        Neighbourhood whose best attracts each particle (:data:`TOPOLOGIES`; default global).
    vmax : float
        Speed limit per dimension as a fraction of the range (default 0.5, i.e. ``Xmax``, the
        half-range, as recommended by Eberhart and Shi 2000).

    Notes
    -----
    ``maxiter`` default 1000. Initial velocities ``(u - x) / 2`` with ``u`` uniform in the box
    (the half-difference initialisation of the 2006 standard PSO); the population reported is
    the personal bests.
    """

    name: ClassVar[str] = "pso"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 40,
        "c1": 2.05,
        "c2": 2.05,
        "kappa": 1.0,
        "topology": "global",
        "vmax": 0.5,
    }
    default_maxiter: ClassVar[int] = 1000

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 2)
        self.c1 = as_positive("c1", options["c1"], allow_zero=True)
        self.c2 = as_positive("c2", options["c2"], allow_zero=True)
        self.kappa = as_positive("kappa", options["kappa"])
        if self.kappa > 1.0:
            raise InputError(f"expected a number in (0, 1], got {self.kappa!r}", option="kappa")
        self.chi = constriction(self.c1, self.c2, self.kappa)
        topology = options["topology"]
        if topology not in TOPOLOGIES:
            raise InputError(
                f"unknown topology {topology!r}; valid: {', '.join(TOPOLOGIES)}",
                option="topology",
            )
        self.topology = topology
        self.neighbourhood_best = TOPOLOGIES[topology]
        self.vmax = as_positive("vmax", options["vmax"])

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, P, n = self.rng, self.popsize, self.n
        x = self.initial_population(P)
        v = rng.random((P, n))
        v -= x
        v *= 0.5
        f = yield x
        pbest, pbest_f = x.copy(), f.copy()
        self.population, self.energies = pbest, pbest_f
        c = np.array([self.c1, self.c2]).reshape(2, 1, 1)
        chi, vmax = self.chi, self.vmax
        while True:
            nb = self.neighbourhood_best(pbest_f)
            r = rng.random((2, P, n))
            r *= c
            v += r[0] * (pbest - x)
            v += r[1] * (pbest[nb] - x)
            v *= chi
            np.maximum(v, -vmax, out=v)
            np.minimum(v, vmax, out=v)
            x = x + v
            wall = (x < 0.0) | (x > 1.0)
            if wall.any():  # absorbing walls: onto the face, stop along that axis
                clip_unit(x)
                v[wall] = 0.0
            f = yield x
            better = f < pbest_f
            np.copyto(pbest, x, where=better[:, None])
            np.copyto(pbest_f, f, where=better)
            self.nit += 1


class LinearInertiaPSO(Optimizer):
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

    name: ClassVar[str] = "pso-liu2008"
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
