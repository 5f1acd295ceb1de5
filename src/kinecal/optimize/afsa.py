"""Artificial fish swarm: canonical AFSA and the adaptive-step SA-IAFSA of papers/002.

Canonical AFSA (Li Xiaolei 2002, "An optimizing method based on autonomous animats: fish-swarm
algorithm"), written for minimisation. Each fish ``X_i`` with cost ``Y_i`` sees the fish within
``visual`` (its ``nf`` neighbours) and, every iteration:

- swarm: moves a step toward the centre ``X_c`` of its neighbours if ``Y_c < Y_i`` and the place
  is not crowded (``nf / N < delta``);
- follow: moves a step toward its best neighbour ``X_best`` if ``Y_best < Y_i`` and ``X_best``'s
  neighbourhood is not crowded (``nf_best / N < delta``);
- the better of the swarm and follow moves is kept; a fish for which neither applies preys: up to
  ``try_number`` random points ``X_j = X_i + visual rand(-1, 1)`` are tried and the fish moves a
  step toward the first acceptable one (``Y_j < Y_i``), else it makes a random move
  ``X_i + visual rand(-1, 1)``;
- the bulletin board keeps the best fish ever seen (the result ``x``).

A step toward a point ``T`` is ``X + rand step (T - X) / ||T - X||`` with one ``rand`` in
``[0, 1)`` per fish.

SA-IAFSA (papers/002, Zhao and Yang, sec. 1.3) changes two things:

- adaptive step (eq. 6, 7, 10): ``Step = rand ||T - X||``, i.e. a fish moves to
  ``X + rand (T - X)``, never past its target;
- prey acceptance (eq. 8): with ``dY = Y_i - Y_j``, accept ``X_j`` if ``dY > 0`` or
  (``dY < 0`` and ``exp(C k dY) > alpha``), ``k`` the iteration (1, 2, ...): worse points are
  accepted early and less and less later, like simulated annealing; the random move (eq. 11)
  remains the fallback.

Batching: per iteration the swarm centres, then all swarm and follow moves, then all fish's
``try_number`` prey tries, then all prey and random moves are evaluated, each as one call of
the objective (so a fish's later tries are evaluated even when an earlier one was accepted; the
first accepted one is used, which is what the sequential loop would pick).

Defaults: ``N = 100`` fish and 200 iterations (papers/002 Table 2). The paper's Table 2 values
of Visual, Step, delta, Trynum, alpha and C are not in our copy of the text; the defaults
below (unit cube: ``visual = 0.25``, ``step = 0.1``; ``delta = 0.618``, ``try_number = 5``,
``alpha = 0.5``, ``C = 1``) are kinecal's, and ``C`` is in 1/cost units.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.optimize._common import Optimizer, as_int, as_positive, as_probability, clip_unit

__all__ = ["AFSA", "SAIAFSA"]


class AFSA(Optimizer):
    """Canonical artificial fish swarm algorithm (Li Xiaolei 2002), minimising.

    Options
    -------
    popsize : int
        Number of fish N (papers/002: 100).
    visual : float
        Visual range, fraction of each variable's range (unit-cube distance).
    step : float
        Maximal step length (unit-cube distance).
    delta : float
        Crowding factor: a place with more than ``delta N`` fish in view is crowded.
    try_number : int
        Prey tries per fish and iteration.
    """

    name: ClassVar[str] = "afsa"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 100,
        "visual": 0.05,
        "step": 0.05,
        "delta": 0.618,
        "try_number": 10,
    }
    default_maxiter: ClassVar[int] = 200

    def _configure(self, options: dict[str, Any]) -> None:
        self.popsize = as_int("popsize", options["popsize"], 2)
        self.visual = as_positive("visual", options["visual"])
        self.step = as_positive("step", options["step"])
        self.delta = as_probability("delta", options["delta"])
        self.try_number = as_int("try_number", options["try_number"], 1)

    # -- the two rules SA-IAFSA changes -----------------------------------------------------
    def move_toward(self, X: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Step of each fish ``X`` ``(m, n)`` toward its target ``T`` ``(m, n)``, in the cube."""
        d = T - X
        norm = np.sqrt(np.einsum("ij,ij->i", d, d))
        scale = self.rng.random(X.shape[0]) * self.step / np.where(norm > 0.0, norm, 1.0)
        return clip_unit(X + scale[:, None] * d)

    def accept(self, Y: np.ndarray, Yj: np.ndarray, k: int) -> np.ndarray:
        """Accept tries of costs ``Yj`` ``(m, T)`` better than their fish ``Y`` ``(m,)``."""
        return Yj < Y[:, None]

    # -- the iteration ------------------------------------------------------------------------
    def random_points(self, X: np.ndarray) -> np.ndarray:
        """Points ``X + visual rand(-1, 1)`` ``(m, n)``, clipped to the cube."""
        return clip_unit(X + self.visual * self.rng.uniform(-1.0, 1.0, X.shape))

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        from scipy.spatial.distance import cdist  # scipy.spatial loads scipy.special: 0.2 s

        N, n = self.popsize, self.n
        X = self.initial_population(N)
        Y = yield X
        Y = Y.copy()  # X and Y are updated in place below
        self.population, self.energies = X, Y
        v2 = self.visual**2
        rows = np.arange(N)
        crowd = self.delta * N
        while True:
            k = self.nit + 1
            view = cdist(X, X, "sqeuclidean") < v2
            view[rows, rows] = False
            nf = np.add.reduce(view, axis=1, dtype=np.intp)
            has = nf > 0
            # swarm: evaluate the centres of the fish that see others
            swarm_ok = np.zeros(N, dtype=bool)
            targets_c = np.zeros_like(X)
            if has.any():
                Xc = (view[has] @ X) / nf[has, None]
                Yc = yield Xc
                swarm_ok[has] = (Yc < Y[has]) & (nf[has] < crowd)
                targets_c[has] = Xc
            # follow: best neighbour, not crowded around it
            Ynb = np.where(view, Y[None, :], np.inf)
            jb = np.argmin(Ynb, axis=1)
            follow_ok = has & (Ynb[rows, jb] < Y) & (nf[jb] < crowd)
            s_idx = np.flatnonzero(swarm_ok)
            f_idx = np.flatnonzero(follow_ok)
            if s_idx.size + f_idx.size:
                goals = np.concatenate([targets_c[s_idx], X[jb[f_idx]]])
                moves = self.move_toward(X[np.concatenate([s_idx, f_idx])], goals)
                Ym = yield moves
                new_f = np.full(N, np.inf)
                new_x = np.zeros_like(X)
                new_f[s_idx], new_x[s_idx] = Ym[: s_idx.size], moves[: s_idx.size]
                fm, xm = Ym[s_idx.size :], moves[s_idx.size :]
                take = fm < new_f[f_idx]  # the better of swarm and follow
                new_f[f_idx[take]], new_x[f_idx[take]] = fm[take], xm[take]
                moved = swarm_ok | follow_ok
                X[moved], Y[moved] = new_x[moved], new_f[moved]
            # prey for the others: all tries of all fish in one batch
            p_idx = np.flatnonzero(~(swarm_ok | follow_ok))
            if p_idx.size:
                m, T = p_idx.size, self.try_number
                Xp = X[p_idx]
                tries = self.random_points(np.repeat(Xp, T, axis=0))
                Yt = yield tries
                with np.errstate(invalid="ignore", over="ignore"):
                    acc = self.accept(Y[p_idx], Yt.reshape(m, T), k)
                ok = acc.any(axis=1)
                first = np.argmax(acc, axis=1)
                goal = tries.reshape(m, T, n)[np.arange(m), first]
                nxt = np.empty_like(Xp)
                nxt[ok] = self.move_toward(Xp[ok], goal[ok])
                nxt[~ok] = self.random_points(Xp[~ok])
                Yn = yield nxt
                X[p_idx], Y[p_idx] = nxt, Yn
            self.population, self.energies = X, Y
            self.nit += 1


class SAIAFSA(AFSA):
    """Adaptive-step improved AFSA with annealing-like acceptance (papers/002).

    Options
    -------
    popsize, visual, delta, try_number
        As :class:`AFSA` (``step`` is replaced by the adaptive step, eq. 6, 7, 10).
    alpha : float
        Probability factor of the acceptance rule eq. 8, in ``(0, 1)``.
    C : float
        Constant of eq. 8 (1/cost units): worse tries are accepted while
        ``exp(C k dY) > alpha``.
    """

    name: ClassVar[str] = "sa-iafsa"
    defaults: ClassVar[dict[str, Any]] = {
        "popsize": 100,
        "visual": 0.05,
        "delta": 0.618,
        "try_number": 10,
        "alpha": 0.5,
        "C": 1.0,
    }

    def _configure(self, options: dict[str, Any]) -> None:
        super()._configure({**options, "step": 1.0})
        self.alpha = as_probability("alpha", options["alpha"])
        self.C = as_positive("C", options["C"], allow_zero=True)

    def move_toward(self, X: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Adaptive step ``Step = rand ||T - X||`` (papers/002 eq. 6, 7, 10): ``X + rand (T-X)``."""
        r = self.rng.random(X.shape[0])
        return clip_unit(X + r[:, None] * (T - X))

    def accept(self, Y: np.ndarray, Yj: np.ndarray, k: int) -> np.ndarray:
        """papers/002 eq. 8: ``dY > 0`` or (``dY < 0`` and ``exp(C k dY) > alpha``)."""
        dY = Y[:, None] - Yj
        return (dY > 0.0) | ((dY < 0.0) & (np.exp(self.C * k * dY) > self.alpha))
