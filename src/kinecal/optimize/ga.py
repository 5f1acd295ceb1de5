"""Real-coded genetic algorithms: Deb's SBX GA (default) and the GA of papers/000.

``ga`` (:class:`SBXGA`): the real-coded GA of Deb's school. Binary tournament selection;
simulated binary crossover (SBX, Deb and Agrawal 1995, "Simulated binary crossover for continuous
search space", Complex Systems 9:115-148) in its bounded form, each variable of a pair crossed
with probability 1/2, distribution index ``eta_c``; polynomial mutation in its bounded form (Deb
and Goyal 1996, "A combined genetic adaptive search (GeneAS) for engineering design", Computer
Science and Informatics 26:30-45; the bounded form as in Deb's NSGA-II, Deb et al. 2002, IEEE
Trans. Evol. Comput. 6(2):182-197), each gene with probability ``pm`` (default ``1 / n``),
index ``eta_m``; elitist survival of the best ``L`` of parents and children together (the
``(mu + lambda)`` truncation of NSGA-II with one objective). See :func:`sbx` and
:func:`polynomial_mutation` for the formulas.

``ga-hu2005`` (:class:`ArithmeticGA`): the real-coded GA of papers/000 section 4.2 (Hu, Xiao, Li
2005), gene by gene (section 4.2, items 1-7):

1. real coding: one float gene per parameter, the chromosome is the parameter vector (here in the
   unit cube, i.e. each gene spans its parameter's range);
2. initial population: ``L`` random individuals (the hybrid of section 4.2 item 2 centres the
   ranges on the least-squares solution; that is ``optimize/hybrid.py``'s job);
3. fitness ``f = 1 / (s + 1)`` with ``s`` the cost;
4. roulette selection, ``p_i = f_i / sum f_j``;
5. arithmetic crossover of each selected pair with probability ``Pc``:
   ``X' = r X + (1 - r) Y``, ``Y' = (1 - r) X + r Y``, ``r`` uniform in ``[0, 1]`` per pair;
   then each gene mutates with probability ``Pm`` to a uniform random value of its range;
6. elitism: the best individual does not undergo crossover and mutation; it replaces the worst
   individual of the new generation (it can still be selected as a parent, like any other);
7. stop when the best cost reaches the threshold ``eps`` (kinecal's ``target``).

Defaults: ``L = 30``, ``Pc = 0.95``, ``Pm = 0.01`` (section 5).

Selection pressure: ``1 / (s + 1)`` makes the roulette nearly uniform once the costs are small
or similar (costs 0.10 and 0.12 give fitness 0.909 and 0.893, a 2 % difference), so the
population drifts and converges slowly near the optimum; this is the paper's GA needing ~29 000
generations in its Table 2. ``selection="rank"`` (linear ranking, weight ``L - rank``) and
``selection="tournament"`` (``tournament_size`` contestants, the best wins) keep the pressure
independent of the cost scale. ``kinecal reproduce hu2005`` uses this variant.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._common import Optimizer, as_int, as_positive, as_probability, clip_unit

__all__ = [
    "SBXGA",
    "SELECTIONS",
    "ArithmeticGA",
    "polynomial_mutation",
    "roulette_weights",
    "sbx",
    "tournament",
]

#: Selection schemes by name.
SELECTIONS = ("roulette", "rank", "tournament")


def roulette_weights(s: np.ndarray) -> np.ndarray:
    """Fitness ``1 / (s + 1)`` of papers/000 sec. 4.2 item 3, shape ``(L,)``.

    Costs are shifted to start at 0 when some are negative (the paper's costs are mean distances,
    never negative); infinite costs get fitness 0.
    """
    lo = float(np.min(s))
    if lo < 0.0:
        s = s - lo
    return 1.0 / (s + 1.0)


def tournament(rng: np.random.Generator, f: np.ndarray, m: int, k: int) -> np.ndarray:
    """Indices ``(m,)`` of ``m`` tournament winners: ``k`` contestants drawn with replacement
    from the ``L = f.size`` individuals, the lowest cost wins (ties: the first drawn)."""
    contestants = rng.integers(0, f.size, size=(m, k))
    winner = np.argmin(f[contestants], axis=1)
    return contestants[np.arange(m), winner]


_BOUNDS = np.array([[0.0], [1.0]])


def sbx(
    a: np.ndarray, b: np.ndarray, eta: float, pc: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Bounded simulated binary crossover in the unit cube (Deb and Agrawal 1995).

    Each pair crosses with probability ``pc``, and then each variable with probability 1/2 (and
    only where the parents differ by more than 1e-14). For parents ``y1 < y2`` and ``u``
    uniform in ``[0, 1)``: ``beta = 1 + 2 (y1 - 0) / (y2 - y1)`` (``1 + 2 (1 - y2) / (y2 - y1)``
    for the second child), ``alpha = 2 - beta^-(eta + 1)``, ``beta_q = (u alpha)^(1 / (eta + 1))``
    if ``u <= 1 / alpha`` else ``(1 / (2 - u alpha))^(1 / (eta + 1))``; children
    ``(y1 + y2 -+ beta_q (y2 - y1)) / 2``, inside ``[0, 1]`` by construction, given to the two
    parents' slots in random order.

    Parameters
    ----------
    a, b : numpy.ndarray, shape (H, n)
        Parent pairs in the unit cube.
    eta : float
        Distribution index ``eta_c`` (large: children close to the parents).
    pc : float
        Crossover probability per pair.
    rng : numpy.random.Generator

    Returns
    -------
    c1, c2 : numpy.ndarray, shape (H, n)
    """
    H, n = a.shape
    do = rng.random((H, n)) < 0.5
    do &= rng.random((H, 1)) < pc
    do &= np.abs(a - b) > 1e-14
    c1, c2 = a.copy(), b.copy()
    if not np.count_nonzero(do):
        return c1, c2
    p, q = a[do], b[do]
    r = rng.random((2, p.size))  # u, and the order of the two children
    y = np.empty((2, p.size))  # both children at once: y1 = min, y2 = max of the parents
    np.minimum(p, q, out=y[0])
    np.maximum(p, q, out=y[1])
    half = 0.5 * (y[1] - y[0])
    beta = np.subtract(_BOUNDS, y)  # distance to the near bound: y1 - 0, 1 - y2
    np.abs(beta, out=beta)
    beta /= half  # 2 (distance) / (y2 - y1)
    beta += 1.0
    alpha = 2.0 - beta ** -(eta + 1.0)
    ua = alpha
    ua *= r[0]  # u alpha
    bq = np.where(ua <= 1.0, ua, 1.0 / (2.0 - ua)) ** (1.0 / (eta + 1.0))  # u <= 1 / alpha
    bq *= half
    bq[0] *= -1.0
    bq += 0.5 * (y[0] + y[1])  # children: mid -+ beta_q (y2 - y1) / 2
    clip_unit(bq)
    swap = r[1] < 0.5
    c1[do] = np.where(swap, bq[1], bq[0])
    c2[do] = np.where(swap, bq[0], bq[1])
    return c1, c2


def polynomial_mutation(
    Y: np.ndarray, eta: float, pm: float, rng: np.random.Generator
) -> np.ndarray:
    """Bounded polynomial mutation in the unit cube, in place (Deb and Goyal 1996; NSGA-II form).

    Each gene ``y`` mutates with probability ``pm``: with ``u`` uniform and ``e = eta + 1``,
    ``delta_q = (2 u + (1 - 2 u) (1 - y)^e)^(1 / e) - 1`` if ``u < 1/2`` else
    ``1 - (2 (1 - u) + 2 (u - 1/2) y^e)^(1 / e)``; ``y = y + delta_q`` stays in ``[0, 1]``
    (``delta_1 = y`` and ``delta_2 = 1 - y`` in the usual notation, range 1).

    Parameters
    ----------
    Y : numpy.ndarray, shape (L, n)
        Individuals in the unit cube, modified in place and returned.
    eta : float
        Distribution index ``eta_m``.
    pm : float
        Mutation probability per gene.
    rng : numpy.random.Generator
    """
    mask = rng.random(Y.shape) < pm
    k = np.count_nonzero(mask)
    if not k:
        return Y
    y = Y[mask]
    u = rng.random(k)
    e = eta + 1.0
    # u >= 1/2 is the mirror image (u -> 1 - u, y -> 1 - y, delta_q -> -delta_q) of u < 1/2
    upper = u >= 0.5
    sign = np.where(upper, -1.0, 1.0)
    u = np.where(upper, 1.0 - u, u)
    z = np.where(upper, y, 1.0 - y)  # 1 - (the distance to the bound moved toward)
    dq = (2.0 * u + (1.0 - 2.0 * u) * z**e) ** (1.0 / e)
    dq -= 1.0
    dq *= sign
    Y[mask] = clip_unit(y + dq)
    return Y


class SBXGA(Optimizer):
    """Real-coded GA: binary tournament, SBX, polynomial mutation, (mu + lambda) survival (Deb).

    Options
    -------
    popsize : int
        Population size L (default 100).
    pc : float
        Crossover probability per pair (default 0.9).
    eta_c : float
        SBX distribution index (default 2: wide spread, chosen on the tuning instances of
        ``benchmarks/bench_swarm.py``; 15-20 are the usual multi-objective values).
    pm : float or None
        Mutation probability per gene; ``None`` gives ``1 / n`` (Deb's usual setting).
    eta_m : float
        Polynomial-mutation distribution index (default 20).
    tournament_size : int
        Contestants per tournament (default 2, binary tournament).

    Notes
    -----
    ``maxiter`` default 1000 generations; one batch of ``L`` children per generation.
    """

    name: ClassVar[str] = "ga"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 100,
        "pc": 0.9,
        "eta_c": 2.0,
        "pm": None,
        "eta_m": 20.0,
        "tournament_size": 2,
    }
    default_maxiter: ClassVar[int] = 1000

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 2)
        self.pc = as_probability("pc", options["pc"])
        self.eta_c = as_positive("eta_c", options["eta_c"], allow_zero=True)
        pm = options["pm"]
        self.pm = 1.0 / self.n if pm is None else as_probability("pm", pm)
        self.eta_m = as_positive("eta_m", options["eta_m"], allow_zero=True)
        self.tournament_size = as_int("tournament_size", options["tournament_size"], 1)

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, L = self.rng, self.popsize
        H = (L + 1) // 2
        X = self.initial_population(L)
        f = yield X
        self.population, self.energies = X, f
        while True:
            parents = tournament(rng, f, 2 * H, self.tournament_size)
            c1, c2 = sbx(X[parents[:H]], X[parents[H:]], self.eta_c, self.pc, rng)
            Y = np.concatenate([c1, c2])[:L]
            polynomial_mutation(Y, self.eta_m, self.pm, rng)
            fy = yield Y
            # elitist survival: the best L of parents and children
            Z, fz = np.concatenate([X, Y]), np.concatenate([f, fy])
            keep = np.argsort(fz, kind="stable")[:L]
            X, f = Z[keep], fz[keep]
            self.population, self.energies = X, f
            self.nit += 1


class ArithmeticGA(Optimizer):
    """Real-coded GA with roulette, arithmetic crossover, reset mutation, elitism (papers/000).

    Options
    -------
    popsize : int
        Population size L (papers/000 sec. 5: 30).
    pc : float
        Crossover probability Pc per selected pair (0.95).
    pm : float
        Mutation probability Pm per gene (0.01).
    selection : {"roulette", "rank", "tournament"}
        ``"roulette"`` is the paper's (fitness ``1 / (s + 1)``).
    tournament_size : int
        Contestants per tournament for ``selection="tournament"`` (default 2).

    Notes
    -----
    ``maxiter`` default 2000 generations; one batch of ``L`` evaluations per generation.
    """

    name: ClassVar[str] = "ga-hu2005"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 30,
        "pc": 0.95,
        "pm": 0.01,
        "selection": "roulette",
        "tournament_size": 2,
    }
    default_maxiter: ClassVar[int] = 2000

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 2)
        self.pc = as_probability("pc", options["pc"])
        self.pm = as_probability("pm", options["pm"])
        if options["selection"] not in SELECTIONS:
            raise InputError(
                f"unknown selection {options['selection']!r}; valid: {', '.join(SELECTIONS)}",
                option="selection",
            )
        self.selection = options["selection"]
        self.tournament_size = as_int("tournament_size", options["tournament_size"], 1)

    def select(self, f: np.ndarray) -> np.ndarray:
        """Indices ``(L,)`` of the parents chosen by the configured selection scheme."""
        L, rng = f.size, self.rng
        if self.selection == "tournament":
            return tournament(rng, f, L, self.tournament_size)
        if self.selection == "rank":
            w = np.empty(L)
            w[np.argsort(f, kind="stable")] = np.arange(L, 0, -1, dtype=float)
        else:
            w = roulette_weights(f)  # item 4
        cum = np.cumsum(w)
        if not cum[-1] > 0.0 or not np.isfinite(cum[-1]):
            return rng.integers(0, L, size=L)
        idx = np.searchsorted(cum, rng.random(L) * cum[-1], side="right")
        return np.minimum(idx, L - 1)

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, L, n = self.rng, self.popsize, self.n
        half = L // 2
        X = self.initial_population(L)
        f = yield X
        self.population, self.energies = X, f
        while True:
            elite = int(np.argmin(f))
            elite_x, elite_f = X[elite].copy(), f[elite]
            Y = X[self.select(f)]
            # item 5: arithmetic crossover of pairs (0, 1), (2, 3), ... with probability Pc
            a, b = Y[0 : 2 * half : 2].copy(), Y[1 : 2 * half : 2].copy()
            r = rng.random((half, 1))
            r = np.where(rng.random((half, 1)) < self.pc, r, 1.0)  # r = 1: no crossover
            Y[0 : 2 * half : 2] = r * a + (1.0 - r) * b
            Y[1 : 2 * half : 2] = (1.0 - r) * a + r * b
            # item 5: reset mutation with probability Pm per gene
            mut = rng.random((L, n)) < self.pm
            if mut.any():
                Y[mut] = rng.random(int(mut.sum()))
            fy = yield Y
            # item 6: the elite replaces the worst of the new generation
            worst = int(np.argmax(fy))
            Y[worst], fy = elite_x, fy.copy()
            fy[worst] = elite_f
            X, f = Y, fy
            self.population, self.energies = X, f
            self.nit += 1
