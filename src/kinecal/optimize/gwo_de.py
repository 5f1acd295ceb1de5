"""DLH-GWO-DE: grey wolves with dimension learning and differential evolution (papers/001, sec. 4).

Li, Xiao, Lai, Hu (2024) refine a hand-eye solution with this hybrid of IGWO and DE. Each
iteration has the six stages of their section 4:

1. moving (4.2): every wolf gets a GWO candidate ``X_i,GWO`` (group hunting led by alpha, beta,
   delta) and a DLH candidate ``X_i,DLH`` (dimension learning in the neighbourhood of radius
   ``||X_i - X_i,GWO||``), exactly as in IGWO (:mod:`kinecal.optimize.gwo`);
2. mutation (4.3): each candidate population is mutated with DE/best/1,
   ``V_i = X_best + F (X_p1 - X_p2)``, ``p1 != p2 != i`` drawn from the current pack;
3. crossover (4.4): binomial, ``U_ij = V_ij`` if ``rand <= CR`` or ``j = j_rand``, else the
   candidate's ``j``-th value; the two trial populations are ``V_i,GWO`` and ``V_i,DLH``;
4. selection (4.5): the best of the four proposals ``X_i,GWO``, ``X_i,DLH``, ``V_i,GWO``,
   ``V_i,DLH`` per wolf;
5. update (4.6): it replaces ``X_i`` only if it is better (greedy, as IGWO).

Reading of the paper: its equations are not in the text we have; "from the current pack" is
read as the pack ``X(t)`` (``X_best`` its alpha) and the crossover partner of each mutant as the
candidate it mutates. The paper gives ``F`` and ``CR`` only as ranges ``[0, 1]``; the defaults are
Storn and Price's common ``F = 0.5``, ``CR = 0.9``. All ``4 popsize`` proposals of an iteration
are evaluated in one batch.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._common import as_positive, as_probability, clip_unit, distinct_others
from kinecal.optimize.gwo import IGWO, dlh_candidates, gwo_candidates

__all__ = ["DLHGWODE", "best1_bin"]


def best1_bin(
    targets: np.ndarray,
    pack: np.ndarray,
    best: np.ndarray,
    F: float,
    CR: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """DE/best/1 mutation and binomial crossover (papers/001 sec. 4.3-4.4; Storn and Price 1997).

    Parameters
    ----------
    targets : numpy.ndarray, shape (m, n)
        Vectors crossed with the mutants; row ``i`` belongs to wolf ``i mod P`` (so several
        candidate sets can be stacked).
    pack : numpy.ndarray, shape (P, n)
        Population the difference vectors come from (``p1 != p2 != i``), ``P >= 3``.
    best : numpy.ndarray, shape (n,)
        Base vector ``X_best``.
    F : float
        Scale factor.
    CR : float
        Crossover probability.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (m, n)
        Trial vectors, clipped to the unit cube.
    """
    m, n = targets.shape
    P = pack.shape[0]
    p = distinct_others(rng, P, 2, np.arange(m) % P)
    V = best + F * (pack[p[:, 0]] - pack[p[:, 1]])
    cross = rng.random((m, n)) <= CR
    cross[np.arange(m), rng.integers(0, n, size=m)] = True  # j_rand
    U = np.where(cross, V, targets)
    return clip_unit(U)


class DLHGWODE(IGWO):
    """DLH-GWO-DE of papers/001 section 4 (IGWO moves + DE/best/1/bin on both candidate sets).

    Options
    -------
    popsize : int
        Number of wolves N (default 30, at least 3).
    F : float
        DE scale factor (papers/001 eq. of sec. 4.3, ``F in [0, 1]``; default 0.5).
    CR : float
        Crossover probability (sec. 4.4, ``CR in [0, 1]``; default 0.9).
    """

    name: ClassVar[str] = "dlh-gwo-de"
    defaults: ClassVar[dict[str, Any]] = {"popsize": 30, "F": 0.5, "CR": 0.9}

    def _configure(self, options: dict[str, Any]) -> None:
        super()._configure(options)
        if self.popsize < 3:
            raise InputError(f"expected an integer >= 3, got {self.popsize}", option="popsize")
        self.F = as_positive("F", options["F"], allow_zero=True)
        self.CR = as_probability("CR", options["CR"])

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        P, rng = self.popsize, self.rng
        X = self.initial_population(P)
        f = yield X
        self.population, self.energies = X, f
        while True:
            order = np.argsort(f, kind="stable")
            leaders = X[order[:3]]
            X_gwo = gwo_candidates(X, leaders, self.control(self.nit), rng)  # sec. 4.2
            X_dlh = dlh_candidates(X, X_gwo, rng)
            cands = np.concatenate([X_gwo, X_dlh])
            trials = best1_bin(cands, X, leaders[0], self.F, self.CR, rng)  # sec. 4.3-4.4
            props = np.concatenate([cands, trials])  # X_GWO, X_DLH, V_GWO, V_DLH
            fc = yield props
            fc = fc.reshape(4, P)
            props = props.reshape(4, P, self.n)
            k = np.argmin(fc, axis=0)  # sec. 4.5: best of the four
            cols = np.arange(P)
            cand, cand_f = props[k, cols], fc[k, cols]
            better = cand_f < f  # sec. 4.6: greedy update
            X = np.where(better[:, None], cand, X)
            f = np.where(better, cand_f, f)
            self.population, self.energies = X, f
            self.nit += 1
