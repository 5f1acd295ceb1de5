"""Real-coded genetic algorithm of papers/000 section 4.2 (Hu, Xiao, Li 2005).

The paper's GA, gene by gene (section 4.2, items 1-7):

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
independent of the cost scale.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._common import Optimizer, as_int, as_probability

__all__ = ["GA", "SELECTIONS", "roulette_weights"]

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


class GA(Optimizer):
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

    name: ClassVar[str] = "ga"
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
            contestants = rng.integers(0, L, size=(L, self.tournament_size))
            winner = np.argmin(f[contestants], axis=1)
            return contestants[np.arange(L), winner]
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
