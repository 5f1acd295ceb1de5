"""Algorithm-level checks of kinecal.optimize: the papers' rules, one by one."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from kinecal.errors import InputError
from kinecal.optimize import METHODS, get_method, methods, minimize, register
from kinecal.optimize._common import Optimizer, distinct_others
from kinecal.optimize.afsa import AFSA, SAIAFSA
from kinecal.optimize.de import ClassicDE
from kinecal.optimize.ga import ArithmeticGA, roulette_weights
from kinecal.optimize.gwo import GWO, IGWO, dlh_candidates, gwo_candidates
from kinecal.optimize.gwo_de import DLHGWODE, best1_bin
from kinecal.optimize.pso import LinearInertiaPSO


def sphere(X):
    return np.sum((X - 0.3) ** 2, axis=1)


# -- helpers of _common -------------------------------------------------------------------------
@pytest.mark.parametrize(("size", "k"), [(3, 2), (4, 3), (7, 3), (30, 2)])
def test_distinct_others_valid_and_uniform(size, k):
    rng = np.random.default_rng(0)
    counts = np.zeros((size, size))
    rows = np.arange(size)
    for _ in range(400):
        idx = distinct_others(rng, size, k)
        assert idx.shape == (size, k)
        assert np.all(idx != rows[:, None]) and np.all((idx >= 0) & (idx < size))
        assert all(len(set(r)) == k for r in idx.tolist())
        for j in range(k):
            np.add.at(counts, (rows, idx[:, j]), 1)
    off = counts[~np.eye(size, dtype=bool)]
    expected = 400 * k / (size - 1)
    assert np.all(np.abs(off - expected) < 6 * np.sqrt(expected))  # every other index, evenly


# -- pso-liu2008 (papers/004) ----------------------------------------------------------------------
def test_pso_inertia_linear_schedule():
    opt = LinearInertiaPSO(3, rng=0, maxiter=500)
    assert opt.inertia(0) == 0.5 and np.isclose(opt.inertia(500), 0.1)
    assert np.isclose(opt.inertia(250), 0.3)  # eq. 9
    assert opt.popsize == 80 and opt.c1 == opt.c2 == 1.8 and opt.vmax == 1.0


def test_pso_without_learning_flies_straight():
    # papers/004 sec. 3.2: with c1 = c2 = 0 a particle keeps its velocity (w = 1)
    opt = LinearInertiaPSO(
        4, rng=1, options={"c1": 0.0, "c2": 0.0, "w_max": 1.0, "w_min": 1.0, "vmax": 0.01}
    )
    xs = []
    for _ in range(4):
        X = opt.ask().copy()
        xs.append(X)
        opt.tell(X, sphere(X))
    d1, d2, d3 = xs[1] - xs[0], xs[2] - xs[1], xs[3] - xs[2]
    inside = np.all((xs[3] > 0) & (xs[3] < 1), axis=1)
    assert inside.sum() > 40
    assert np.allclose(d1[inside], d2[inside]) and np.allclose(d2[inside], d3[inside])
    assert np.all(np.abs(d1) <= 0.01 + 1e-15)  # vmax


def test_pso_velocity_limit():
    opt = LinearInertiaPSO(5, rng=2, options={"vmax": 0.05})
    X0 = opt.ask().copy()
    opt.tell(X0, sphere(X0))
    X1 = opt.ask()
    assert np.max(np.abs(X1 - X0)) <= 0.05 + 1e-15


# -- GWO family ---------------------------------------------------------------------------------
def test_gwo_control_parameter():
    opt = GWO(2, rng=0, maxiter=100)
    assert opt.control(0) == 2.0 and opt.control(50) == 1.0 and opt.control(100) == 0.0


def test_gwo_candidates_collapse_on_leaders_when_a_is_zero():
    rng = np.random.default_rng(0)
    X = rng.random((20, 3))
    leaders = np.full((3, 3), 0.4)
    # a = 0 -> A = 0 -> every wolf moves onto the (common) leader position (eq. 3.5-3.7)
    assert np.allclose(gwo_candidates(X, leaders, 0.0, rng), 0.4)


def test_gwo_is_not_greedy_but_igwo_is():
    seen = {}
    for opt in (GWO(3, rng=0), IGWO(3, rng=0)):
        X0 = opt.ask().copy()
        opt.tell(X0, sphere(X0))
        X1 = opt.ask().copy()
        opt.tell(X1, np.full(X1.shape[0], 1e9))  # every move is much worse
        seen[opt.name] = (opt, X0, X1)
    gwo, X0g, X1g = seen["gwo"]
    igwo, X0i, _ = seen["igwo"]
    assert np.array_equal(gwo.population, X1g)  # canonical: the wolves moved anyway
    assert np.array_equal(igwo.population, X0i)  # greedy: nobody accepted a worse place
    assert gwo.best_f == sphere(X0g).min() and igwo.best_f == sphere(X0i).min()


def test_dlh_uses_only_neighbours_within_radius():
    # 1-D pack: wolf 0 at 0.1 with radius 0.15 sees wolves 0 (0.1) and 1 (0.2), not 2 (0.9)
    X = np.array([[0.1], [0.2], [0.9]])
    X_gwo = np.array([[0.25], [0.2], [0.9]])
    rng = np.random.default_rng(3)
    out = np.array([dlh_candidates(X, X_gwo, rng)[0, 0] for _ in range(3000)])
    # X_n - X_r in [0.1 - 0.9, 0.2 - 0.1] = [-0.8, 0.1]: never above 0.1 + 0.1
    assert out.max() <= 0.2 + 1e-12
    assert (out > 0.1 + 1e-9).mean() > 0.05  # neighbour 1 is really used
    # neighbour and random wolf in {0, 1} give X_n - X_r >= -0.1, so 0.1 + u (..) > 0: a value
    # clipped to 0 needs the random wolf 2, which is drawn from the whole pack
    assert out.min() == 0.0 and (out == 0.0).mean() > 0.05


def test_igwo_picks_better_candidate_eq13():
    opt = IGWO(2, rng=5, options={"popsize": 6})
    X0 = opt.ask().copy()
    f0 = np.full(6, 10.0)
    opt.tell(X0, f0)
    C = opt.ask().copy()  # 6 GWO then 6 DLH candidates
    fc = np.array([5.0, 20.0, 1.0, 30.0, 9.0, 11.0, 6.0, 4.0, 2.0, 40.0, 12.0, 13.0])
    opt.tell(C, fc)
    expect = np.array([C[0], C[7], C[2], X0[3], C[4], X0[5]])
    assert np.array_equal(opt.population, expect)
    assert np.array_equal(opt.energies, [5.0, 4.0, 1.0, 10.0, 9.0, 10.0])


def test_best1_bin_structure():
    rng = np.random.default_rng(4)
    P, n = 8, 5
    pack = rng.random((P, n))
    targets = rng.random((P, n))
    best = np.full(n, 0.5)
    # CR = 1: the trial is the mutant best + F (X_p1 - X_p2), p1 != p2 != i (before clipping)
    U = best1_bin(targets, pack, best, 0.1, 1.0, rng)
    diffs = (pack[:, None, :] - pack[None, :, :]) * 0.1
    for i in range(P):
        hits = [
            (a, b)
            for a in range(P)
            for b in range(P)
            if a != b and i not in (a, b) and np.allclose(U[i], best + diffs[a, b])
        ]
        assert hits
    # CR = 0: exactly one coordinate (j_rand) comes from the mutant
    U0 = best1_bin(targets, pack, best, 0.1, 0.0, rng)
    assert np.all(np.sum(U0 != targets, axis=1) == 1)


def test_dlh_gwo_de_best_of_four_then_greedy():
    opt = DLHGWODE(2, rng=6, options={"popsize": 4})
    X0 = opt.ask().copy()
    opt.tell(X0, np.full(4, 10.0))
    C = opt.ask().copy()
    assert C.shape == (16, 2)
    fc = np.full(16, 50.0)
    fc[[0, 5, 10, 15]] = [3.0, 2.0, 1.0, 0.5]  # wolf 0: X_GWO, 1: X_DLH, 2: V_GWO, 3: V_DLH
    fc[3] = 60.0
    opt.tell(C, fc)
    assert np.array_equal(opt.population, C[[0, 5, 10, 15]])
    assert np.array_equal(opt.energies, [3.0, 2.0, 1.0, 0.5])
    assert np.all(np.isfinite(opt.population))


# -- ga-hu2005 (papers/000 sec. 4.2) ---------------------------------------------------------------
def test_roulette_fitness_and_pressure():
    s = np.array([0.0, 1.0, 3.0])
    assert np.allclose(roulette_weights(s), [1.0, 0.5, 0.25])  # f = 1 / (s + 1)
    w = roulette_weights(np.array([0.10, 0.12]))
    assert w[0] / w[1] < 1.02  # nearly uniform: the loss of selection pressure


def test_ga_selection_schemes_prefer_better():
    f = np.linspace(0.0, 0.05, 30)  # similar small costs
    share = {}
    for sel in ("roulette", "rank", "tournament"):
        ga = ArithmeticGA(2, rng=0, options={"selection": sel})
        picks = np.concatenate([ga.select(f) for _ in range(300)])
        share[sel] = np.mean(picks < 10)  # how often the best third is chosen
    assert 0.32 < share["roulette"] < 0.36  # ~1/3: no pressure
    assert share["rank"] > 0.5 and share["tournament"] > 0.5


def test_ga_arithmetic_crossover_keeps_pair_sums_and_elite():
    ga = ArithmeticGA(3, rng=7, options={"pc": 1.0, "pm": 0.0, "popsize": 10})
    X0 = ga.ask().copy()
    f0 = sphere(X0)
    ga.tell(X0, f0)
    Y = ga.ask().copy()
    # children are convex combinations of the selected parents: inside the parents' hull
    assert np.all(Y >= X0.min(axis=0) - 1e-12) and np.all(Y <= X0.max(axis=0) + 1e-12)
    fy = sphere(Y)
    ga.tell(Y, fy)
    worst = np.argmax(fy)
    assert np.array_equal(ga.population[worst], X0[np.argmin(f0)])  # elite replaced the worst
    assert ga.energies[worst] == f0.min()


def test_ga_mutation_rate():
    ga = ArithmeticGA(50, rng=8, options={"pc": 0.0, "pm": 0.2, "popsize": 40})
    X0 = ga.ask().copy()
    ga.tell(X0, np.zeros(40))  # equal costs: uniform roulette, children = copies + mutation
    Y = ga.ask()
    changed = ~np.any(np.all(Y[:, None, :] == X0[None, :, :], axis=2), axis=1)
    assert changed.mean() > 0.9
    # per gene: compare each child with its closest parent
    close = np.min(np.sum(Y[:, None, :] != X0[None, :, :], axis=2), axis=1)
    assert abs(close.mean() / 50 - 0.2) < 0.04


# -- AFSA / SA-IAFSA (papers/002) ---------------------------------------------------------------
def test_sa_iafsa_acceptance_eq8():
    fish = SAIAFSA(2, rng=0, options={"C": 1.0, "alpha": 0.5})
    Y = np.array([1.0])
    Yj = np.array([[0.9, 1.0, 1.1, 2.0]])
    # dY = 0.1 accepted, 0 not, -0.1: exp(-0.1 k) > 0.5 for k = 1 but not k = 10, -1.0 never
    assert fish.accept(Y, Yj, 1).tolist() == [[True, False, True, False]]
    assert fish.accept(Y, Yj, 10).tolist() == [[True, False, False, False]]
    plain = AFSA(2, rng=0)
    assert plain.accept(Y, Yj, 1).tolist() == [[True, False, False, False]]


def test_afsa_steps():
    rng = np.random.default_rng(1)
    X = rng.random((200, 3)) * 0.5
    T = X + rng.normal(size=X.shape) * 0.2
    T = np.clip(T, 0, 1)
    a = AFSA(3, rng=2, options={"step": 0.05}).move_toward(X, T)
    assert np.all(np.linalg.norm(a - X, axis=1) <= 0.05 + 1e-12)
    s = SAIAFSA(3, rng=2).move_toward(X, T)
    # adaptive step: on the segment from X to T, never past the target
    t = np.einsum("ij,ij->i", s - X, T - X) / np.einsum("ij,ij->i", T - X, T - X)
    assert np.all((t >= 0) & (t <= 1))
    assert np.allclose(X + t[:, None] * (T - X), s)


@pytest.mark.parametrize("method", ["afsa", "sa-iafsa"])
def test_afsa_batches_all_fish(method):
    calls = []

    def f(X):
        calls.append(len(X))
        return sphere(X)

    res = minimize(f, [(0, 1)] * 5, method, rng=3, maxiter=10)
    assert len(calls) <= 1 + 4 * 10  # at most four batches per iteration, never one per fish
    assert res.nfev > 100 * 10 * 5  # every fish tried try_number points per iteration
    assert max(calls) >= 100


def test_afsa_swarm_and_follow_happen():
    # a tight school: everyone sees everyone, so swarm/follow replace prey for most fish
    opt = AFSA(2, rng=4, options={"visual": 2.0, "delta": 1.0})
    X0 = opt.ask().copy()
    opt.tell(X0, sphere(X0))
    centres = opt.ask()  # the first batch of an iteration is the swarm centres
    assert centres.shape == (100, 2)
    assert np.allclose(centres, (X0.sum(axis=0) - X0) / 99)


# -- de-storn1997 ----------------------------------------------------------------------------------
def test_de_strategies_and_selection():
    assert ClassicDE(4, rng=0).popsize == 40
    with pytest.raises(InputError, match="rand1bin, best1bin"):
        ClassicDE(4, options={"strategy": "current-to-best"})
    opt = ClassicDE(3, rng=1, options={"popsize": 10})
    X0 = opt.ask().copy()
    opt.tell(X0, np.full(10, 5.0))
    U = opt.ask().copy()
    assert np.all((U >= 0) & (U <= 1))
    fu = np.array([4.0, 6.0] * 5)
    opt.tell(U, fu)
    keep = fu <= 5.0
    assert np.array_equal(opt.population[keep], U[keep])
    assert np.array_equal(opt.population[~keep], X0[~keep])
    r = [
        minimize(sphere, [(0, 1)] * 4, "de-storn1997", rng=2, maxiter=30, options={"strategy": s})
        for s in ("rand1bin", "best1bin")
    ]
    assert r[1].fun < r[0].fun  # best/1 converges faster on a sphere


# -- registry -------------------------------------------------------------------------------------
def test_register_custom_method():
    class RandomSearch(Optimizer):
        name = "random-search"
        defaults: ClassVar[dict] = {"popsize": 20}
        default_maxiter = 5

        def _steps(self):
            X = self.rng.random((self.options["popsize"], self.n))
            f = yield X
            self.population, self.energies = X, f
            while True:
                X = self.rng.random((self.options["popsize"], self.n))
                f = yield X
                self.population, self.energies = X, f
                self.nit += 1

    register("random-search", RandomSearch)
    try:
        assert get_method("Random-Search") is RandomSearch
        res = minimize(sphere, [(0, 1)] * 2, "random-search", rng=0)
        assert res.nit == 5 and res.nfev == 20 * 6
        assert METHODS == methods()[: len(METHODS)]
    finally:
        from kinecal.optimize import _REGISTRY

        _REGISTRY.pop("random-search", None)
    with pytest.raises(TypeError):
        register("bad", sphere)
