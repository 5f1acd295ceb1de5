"""Grey wolf optimizers: canonical GWO and the dimension-learning IGWO.

- ``gwo``: Mirjalili, Mirjalili, Lewis (2014), "Grey Wolf Optimizer", Adv. Eng. Softw. 69:46-61.
  The three best wolves found so far (alpha, beta, delta) lead; every wolf moves to the mean of
  ``X_k = X_leader - A |C X_leader - X|`` (their eq. 3.1-3.7) with ``A = 2 a r1 - a``,
  ``C = 2 r2`` and ``a`` decreasing linearly from 2 to 0 over ``maxiter``. Canonical: a wolf
  always moves (no greedy replacement); the leaders keep the best positions ever seen.
- ``igwo``: Nadimi-Shahraki, Taghian, Mirjalili (2021), "An improved grey wolf optimizer for
  solving engineering problems", Expert Syst. Appl. 166:113917 (the IGWO of papers/001 ref. [11]).
  Each wolf proposes the GWO candidate and a dimension-learning-hunting (DLH) candidate: radius
  ``R_i = ||X_i - X_i,GWO||`` (eq. 10), neighbourhood ``N_i = {X_j : ||X_i - X_j|| <= R_i}``
  (eq. 11), ``X_i,DLH,d = X_i,d + rand (X_n,d - X_r,d)`` with a random neighbour ``n`` and a
  random wolf ``r`` drawn per dimension (eq. 12); the better candidate (eq. 13) replaces the wolf
  only if it improves it (greedy selection). The leaders are the three best wolves.

All positions are kept in the unit cube (candidates are clipped onto its faces).
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.optimize._common import Optimizer, as_int, clip_unit

__all__ = ["GWO", "IGWO", "dlh_candidates", "gwo_candidates", "update_leaders"]


def gwo_candidates(
    X: np.ndarray, leaders: np.ndarray, a: float, rng: np.random.Generator
) -> np.ndarray:
    """Hunting step of GWO (Mirjalili 2014, eq. 3.3-3.7) for the whole pack.

    Parameters
    ----------
    X : numpy.ndarray, shape (P, n)
        Current wolves (unit cube).
    leaders : numpy.ndarray, shape (3, n)
        Alpha, beta and delta positions.
    a : float
        Control parameter, decreasing from 2 to 0.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (P, n)
        ``(X1 + X2 + X3) / 3`` clipped to the unit cube.
    """
    P, n = X.shape
    r = rng.random((2, 3, P, n))
    A = (2.0 * a) * r[0] - a  # eq. 3.3, one per leader, wolf and dimension
    C = 2.0 * r[1]  # eq. 3.4
    L = leaders[:, None, :]
    Xk = L - A * np.abs(C * L - X)  # eq. 3.5-3.6
    out = np.add.reduce(Xk, axis=0)
    out /= 3.0  # eq. 3.7
    return clip_unit(out)


def dlh_candidates(X: np.ndarray, X_gwo: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Dimension-learning-based hunting of IGWO (Nadimi-Shahraki et al. 2021, eq. 10-12).

    Parameters
    ----------
    X : numpy.ndarray, shape (P, n)
        Current wolves.
    X_gwo : numpy.ndarray, shape (P, n)
        Their GWO candidates (which set the neighbourhood radii, eq. 10).
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (P, n)
        DLH candidates clipped to the unit cube.
    """
    from scipy.spatial.distance import cdist  # scipy.spatial loads scipy.special: 0.2 s

    P, n = X.shape
    R2 = np.einsum("ij,ij->i", X - X_gwo, X - X_gwo)  # eq. 10 (squared)
    D2 = cdist(X, X, "sqeuclidean")
    mask = D2 <= R2[:, None]  # eq. 11; wolf i is its own neighbour, so N_i is never empty
    count = np.add.reduce(mask, axis=1, dtype=np.intp)
    _, members = np.nonzero(mask)  # neighbour lists of all wolves, concatenated in row order
    start = np.cumsum(count) - count
    u = rng.random((3, P, n))
    pick = (u[0] * count[:, None]).astype(np.intp)
    neigh = members[start[:, None] + pick]  # a random neighbour per wolf and dimension
    rand_wolf = (u[1] * P).astype(np.intp)  # random wolf of the pack per dimension
    cols = np.arange(n)
    out = X + u[2] * (X[neigh, cols] - X[rand_wolf, cols])  # eq. 12
    return clip_unit(out)


def update_leaders(
    leaders: np.ndarray, leader_f: np.ndarray, X: np.ndarray, f: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return the three best of ``leaders`` ``(3, n)`` and the batch ``X`` ``(P, n)``, sorted."""
    allx = np.concatenate([leaders, X])
    allf = np.concatenate([leader_f, f])
    k = min(3, allf.size)
    idx = np.argpartition(allf, k - 1)[:k] if allf.size > k else np.arange(allf.size)
    idx = idx[np.argsort(allf[idx], kind="stable")]
    if idx.size < 3:
        idx = np.resize(idx, 3)
    return allx[idx], allf[idx]


class GWO(Optimizer):
    """Canonical grey wolf optimizer (Mirjalili et al. 2014).

    Options
    -------
    popsize : int
        Number of wolves (Mirjalili 2014 used 30).

    Notes
    -----
    ``a = 2 - 2 t / maxiter`` (eq. 3.3), ``maxiter`` default 500 (Mirjalili 2014). One batch of
    ``popsize`` evaluations per iteration.
    """

    name: ClassVar[str] = "gwo"
    defaults: ClassVar[dict[str, Any]] = {"popsize": 30}
    default_maxiter: ClassVar[int] = 500

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 1)

    def control(self, t: int) -> float:
        """Control parameter ``a`` at iteration ``t``: linear from 2 to 0 (eq. 3.3)."""
        return 2.0 - 2.0 * min(t, self.maxiter) / max(self.maxiter, 1)

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        X = self.initial_population(self.popsize)
        f = yield X
        self.population, self.energies = X, f
        leaders, leader_f = update_leaders(np.empty((0, self.n)), np.empty(0), X, f)
        while True:
            X = gwo_candidates(X, leaders, self.control(self.nit), self.rng)
            f = yield X
            self.population, self.energies = X, f
            leaders, leader_f = update_leaders(leaders, leader_f, X, f)
            self.nit += 1


class IGWO(GWO):
    """Improved grey wolf optimizer with dimension-learning hunting (Nadimi-Shahraki et al. 2021).

    Options
    -------
    popsize : int
        Number of wolves (default 30).

    Notes
    -----
    Each iteration evaluates the GWO and the DLH candidates of every wolf in one batch of
    ``2 popsize`` points, then applies eq. 13 and the greedy update.
    """

    name: ClassVar[str] = "igwo"

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        P = self.popsize
        X = self.initial_population(P)
        f = yield X
        self.population, self.energies = X, f
        while True:
            leaders = X[np.argsort(f, kind="stable")[:3]]
            if leaders.shape[0] < 3:
                leaders = np.resize(leaders, (3, self.n))
            X_gwo = gwo_candidates(X, leaders, self.control(self.nit), self.rng)
            X_dlh = dlh_candidates(X, X_gwo, self.rng)
            fc = yield np.concatenate([X_gwo, X_dlh])
            use_gwo = fc[:P] < fc[P:]  # eq. 13
            cand = np.where(use_gwo[:, None], X_gwo, X_dlh)
            cand_f = np.where(use_gwo, fc[:P], fc[P:])
            better = cand_f < f  # greedy selection
            X = np.where(better[:, None], cand, X)
            f = np.where(better, cand_f, f)
            self.population, self.energies = X, f
            self.nit += 1
