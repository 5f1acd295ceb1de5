"""Differential evolution: JADE-style adaptive DE (default) and classic DE/rand/1/bin.

``de`` (:class:`AdaptiveDE`): Zhang, J., Sanderson, A. C. (2009), "JADE: Adaptive Differential
Evolution With Optional External Archive", IEEE Trans. Evol. Comput. 13(5):945-958.
Per generation and target vector ``x_i``:

- mutation "current-to-pbest/1" with archive:
  ``v_i = x_i + F_i (x_pbest - x_i) + F_i (x_r1 - x~_r2)``, ``x_pbest`` drawn from the
  ``100 p %`` best (at least two), ``r1 != i`` from the population, ``x~_r2`` (``!= i, r1``)
  from the population joined with the archive of recently replaced parents;
- a mutant component outside the box is put halfway between the parent and the bound;
- binomial crossover with ``CR_i`` and a forced ``j_rand``; selection ``f(u_i) <= f(x_i)``;
- adaptation: ``CR_i ~ N(mu_CR, 0.1)`` clipped to ``[0, 1]``, ``F_i ~ Cauchy(mu_F, 0.1)``
  (redrawn while ``<= 0``, cut at 1); after each generation
  ``mu_CR = (1 - c) mu_CR + c mean(S_CR)`` and ``mu_F = (1 - c) mu_F + c lehmer(S_F)`` over the
  ``F, CR`` of the trials that beat their parent (``lehmer = sum F^2 / sum F``);
- the archive keeps the parents beaten by their trial, at most ``archive * NP`` of them (once
  it is full, each newcomer replaces a random member).

``de-storn1997`` (:class:`ClassicDE`): Storn, R., Price, K. (1997), "Differential Evolution - A
Simple and Efficient Heuristic for Global Optimization over Continuous Spaces", J. Global Optim.
11:341-359. Per generation and target vector ``x_i``:

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
from kinecal.optimize._common import (
    Optimizer,
    as_int,
    as_positive,
    as_probability,
    clip_unit,
    distinct_others,
)

__all__ = ["STRATEGIES", "AdaptiveDE", "ClassicDE", "lehmer_mean", "other_than"]

#: Mutation strategies by name.
STRATEGIES = ("rand1bin", "best1bin")


class ClassicDE(Optimizer):
    """Differential evolution with fixed ``F`` and ``CR`` (Storn and Price 1997).

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

    name: ClassVar[str] = "de-storn1997"
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


def lehmer_mean(F: np.ndarray) -> float:
    """Lehmer mean ``sum F^2 / sum F`` of the successful scale factors (Zhang and Sanderson)."""
    return float(np.dot(F, F) / np.sum(F))


def other_than(
    rng: np.random.Generator, size: int, a: np.ndarray, b: np.ndarray
) -> np.ndarray:
    """One index per row, uniform in ``0 .. size - 1`` and different from ``a`` and ``b``.

    Rows that hit ``a`` or ``b`` are redrawn (``size >= 3``), vectorized over rows.

    Parameters
    ----------
    rng : numpy.random.Generator
    size : int
        Number of candidates (population plus archive).
    a, b : numpy.ndarray of int, shape (m,)
        Indices each row must avoid.

    Returns
    -------
    numpy.ndarray of int, shape (m,)
    """
    r = (rng.random(a.size) * size).astype(np.intp)
    bad = (r == a) | (r == b)
    while k := np.count_nonzero(bad):
        r[bad] = (rng.random(k) * size).astype(np.intp)
        bad = (r == a) | (r == b)
    return r


class AdaptiveDE(Optimizer):
    """JADE: DE/current-to-pbest/1/bin, archive, adaptive ``F`` and ``CR`` (Zhang, Sanderson).

    Options
    -------
    popsize : int or None
        Population size NP; ``None`` gives ``max(20, 5 n)``.
    p : float
        Greediness: ``x_pbest`` is drawn from the best ``100 p %`` (default 0.05, at least two).
    c : float
        Adaptation rate of ``mu_F`` and ``mu_CR`` (default 0.1).
    mu_F, mu_CR : float
        Initial centres of the ``F`` and ``CR`` distributions (default 0.5 each).
    archive : float
        Archive capacity as a multiple of NP (default 1; 0: JADE without archive).

    Notes
    -----
    ``maxiter`` default 1000 generations. The current ``mu_F`` and ``mu_CR`` are attributes of
    the optimizer.
    """

    name: ClassVar[str] = "de"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": None,
        "p": 0.05,
        "c": 0.1,
        "mu_F": 0.5,
        "mu_CR": 0.5,
        "archive": 1.0,
    }
    default_maxiter: ClassVar[int] = 1000

    def _configure(self, options: dict[str, Any]) -> None:
        pop = options["popsize"]
        self.popsize = max(20, 5 * self.n) if pop is None else as_int("popsize", pop, 4)
        self.p = as_probability("p", options["p"])
        self.c = as_probability("c", options["c"])
        self.mu_F = as_probability("mu_F", options["mu_F"])
        self.mu_CR = as_probability("mu_CR", options["mu_CR"])
        self.archive = as_positive("archive", options["archive"], allow_zero=True)

    def sample_parameters(self, P: int) -> tuple[np.ndarray, np.ndarray]:
        """Draw ``F`` (Cauchy, redrawn while ``<= 0``, cut at 1) and ``CR`` (normal, clipped),
        each of shape ``(P,)``."""
        rng = self.rng
        CR = clip_unit(self.mu_CR + 0.1 * rng.standard_normal(P))
        F = self.mu_F + 0.1 * rng.standard_cauchy(P)
        low = F <= 0.0
        while k := np.count_nonzero(low):
            F[low] = self.mu_F + 0.1 * rng.standard_cauchy(k)
            low = F <= 0.0
        return np.minimum(F, 1.0, out=F), CR

    def adapt(self, F: np.ndarray, CR: np.ndarray) -> None:
        """Move ``mu_F`` and ``mu_CR`` toward the successful ``F`` and ``CR`` (if any)."""
        if F.size:
            c = self.c
            self.mu_CR = (1.0 - c) * self.mu_CR + c * float(np.mean(CR))
            self.mu_F = (1.0 - c) * self.mu_F + c * lehmer_mean(F)

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        rng, P, n = self.rng, self.popsize, self.n
        cap = int(self.archive * P)
        pool = np.empty((P + cap, n))  # the population, then the archive (na rows in use)
        X = pool[:P]
        X[:] = self.initial_population(P)
        f = np.array((yield X.copy()), dtype=float)
        self.population, self.energies = X, f
        rows = np.arange(P)
        top = max(2, round(self.p * P))
        na = 0
        while True:
            F, CR = self.sample_parameters(P)
            w = rng.random((3, P))  # floor(w k): uniform in 0 .. k - 1
            pb = np.argsort(f, kind="stable")[(w[0] * top).astype(np.intp)]
            r1 = rows + 1 + (w[1] * (P - 1)).astype(np.intp)  # uniform over the others
            r1[r1 >= P] -= P
            r2 = other_than(rng, P + na, rows, r1)
            V = X[pb]  # v = x + F (x_pbest - x) + F (x_r1 - x~_r2)
            V -= X
            V += X[r1]
            V -= pool[r2]
            V *= F[:, None]
            V += X
            out = V < 0.0  # halfway between the parent and the bound
            if np.count_nonzero(out):
                V[out] = 0.5 * X[out]
            out = V > 1.0
            if np.count_nonzero(out):
                V[out] = 0.5 * (1.0 + X[out])
            cross = rng.random((P, n)) < CR[:, None]
            cross[rows, (w[2] * n).astype(np.intp)] = True
            U = np.where(cross, V, X)
            fu = yield U
            won = fu < f
            if np.count_nonzero(won):
                if cap:
                    na = self._archive(pool, P, na, X[won])
                self.adapt(F[won], CR[won])
            keep = fu <= f
            np.copyto(X, U, where=keep[:, None])
            np.copyto(f, fu, where=keep)
            self.nit += 1

    def _archive(self, pool: np.ndarray, P: int, na: int, beaten: np.ndarray) -> int:
        """Add the beaten parents to the archive rows ``pool[P:]``; once full, each new one
        replaces a random member. Returns the archive's new size."""
        cap = pool.shape[0] - P
        k = beaten.shape[0]
        free = min(cap - na, k)
        if free:
            pool[P + na : P + na + free] = beaten[:free]
            na += free
        if k > free:
            pool[P + self.rng.integers(0, cap, size=k - free)] = beaten[free:]
        return na
