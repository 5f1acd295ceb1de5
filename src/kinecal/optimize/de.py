"""Differential evolution, DE/rand/1/bin and DE/best/1/bin (Storn and Price 1997).

Storn, R., Price, K. (1997), "Differential Evolution - A Simple and Efficient Heuristic for
Global Optimization over Continuous Spaces", J. Global Optim. 11:341-359.

Per generation and target vector ``x_i``:

- mutation: ``v_i = x_r1 + F (x_r2 - x_r3)`` (``rand1bin``) or ``v_i = x_best + F (x_r1 - x_r2)``
  (``best1bin``), with ``r1, r2, r3`` distinct and different from ``i``;
- binomial crossover: ``u_ij = v_ij`` if ``rand <= CR`` or ``j = j_rand``, else ``x_ij``;
- selection: ``u_i`` replaces ``x_i`` if ``f(u_i) <= f(x_i)``.

A mutant component outside the unit cube is redrawn uniformly inside it (the rule scipy's
``differential_evolution`` uses). The whole generation of trial vectors is one batch.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._common import Optimizer, as_int, as_positive, as_probability, distinct_others

__all__ = ["DE", "STRATEGIES"]

#: Mutation strategies by name.
STRATEGIES = ("rand1bin", "best1bin")


class DE(Optimizer):
    """Differential evolution (Storn and Price 1997).

    Options
    -------
    popsize : int or None
        Population size NP; ``None`` gives ``10 n`` (Storn and Price's rule of thumb, at least 5).
    F : float
        Differential weight (default 0.5, Storn and Price).
    CR : float
        Crossover probability (default 0.9).
    strategy : {"rand1bin", "best1bin"}
        Mutation strategy (default ``"rand1bin"``).

    Notes
    -----
    ``maxiter`` default 1000 generations.
    """

    name: ClassVar[str] = "de"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": None,
        "F": 0.5,
        "CR": 0.9,
        "strategy": "rand1bin",
    }
    default_maxiter: ClassVar[int] = 1000

    def _configure(self, options: dict[str, Any]) -> None:
        pop = options["popsize"]
        self.popsize = max(10 * self.n, 5) if pop is None else as_int("popsize", pop, 4)
        self.F = as_positive("F", options["F"], allow_zero=True)
        self.CR = as_probability("CR", options["CR"])
        if options["strategy"] not in STRATEGIES:
            raise InputError(
                f"unknown strategy {options['strategy']!r}; valid: {', '.join(STRATEGIES)}",
                option="strategy",
            )
        self.strategy = options["strategy"]

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, P, n = self.rng, self.popsize, self.n
        X = self.initial_population(P)
        f = yield X
        self.population, self.energies = X, f
        rows = np.arange(P)
        best_base = self.strategy == "best1bin"
        while True:
            if best_base:
                r = distinct_others(rng, P, 2)
                V = X[int(np.argmin(f))] + self.F * (X[r[:, 0]] - X[r[:, 1]])
            else:
                r = distinct_others(rng, P, 3)
                V = X[r[:, 0]] + self.F * (X[r[:, 1]] - X[r[:, 2]])
            out = (V < 0.0) | (V > 1.0)
            if out.any():
                V[out] = rng.random(int(out.sum()))
            cross = rng.random((P, n)) <= self.CR
            cross[rows, rng.integers(0, n, size=P)] = True
            U = np.where(cross, V, X)
            fu = yield U
            keep = fu <= f
            X = np.where(keep[:, None], U, X)
            f = np.where(keep, fu, f)
            self.population, self.energies = X, f
            self.nit += 1
