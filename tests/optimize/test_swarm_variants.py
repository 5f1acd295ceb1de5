"""The default PSO, DE and GA (issue 29): their operators one by one, and a quality check."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.errors import InputError
from kinecal.optimize import get_method, minimize
from kinecal.optimize.de import AdaptiveDE, lehmer_mean, other_than
from kinecal.optimize.ga import SBXGA, polynomial_mutation, sbx, tournament
from kinecal.optimize.pso import ConstrictionPSO, constriction, global_best, ring_best


# -- PSO (Clerc and Kennedy 2002) ---------------------------------------------------------------
def test_constriction_coefficient():
    # phi = 4.1, kappa = 1: chi = 2 / |2 - 4.1 - sqrt(4.1^2 - 16.4)| = 0.729843788...
    assert np.isclose(constriction(2.05, 2.05), 0.7298437881283576, rtol=0, atol=1e-15)
    assert np.isclose(constriction(2.05, 2.05) * 2.05, 1.4962, atol=1e-4)  # the usual c of w-PSO
    assert np.isclose(constriction(2.05, 2.05, 0.5), 0.5 * constriction(2.05, 2.05))
    with pytest.raises(InputError, match="c1 \\+ c2 > 4"):
        constriction(2.0, 2.0)
    with pytest.raises(InputError, match="topology"):
        ConstrictionPSO(3, options={"topology": "star"})
    with pytest.raises(InputError, match="kappa"):
        ConstrictionPSO(3, options={"kappa": 1.5})


def test_ring_and_global_neighbourhoods():
    rng = np.random.default_rng(0)
    f = rng.random(9)
    ring = ring_best(f)
    for i in range(9):
        hood = [(i - 1) % 9, i, (i + 1) % 9]
        assert ring[i] == hood[int(np.argmin(f[hood]))]
    assert int(global_best(f)) == int(np.argmin(f))
    # a ring spreads the best slowly: particle 4 does not see the best at 0
    f = np.array([0.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0])
    assert ring_best(f).tolist() == [0, 0, 2, 3, 4, 5, 6, 7, 0]  # ties: the particle itself


def test_constriction_pso_absorbing_walls():
    # optimum far outside the box: particles reaching the face stay on it (velocity zeroed),
    # instead of being carried back and forth
    opt = ConstrictionPSO(3, rng=1, options={"popsize": 10})
    for _ in range(60):
        X = opt.ask().copy()
        assert np.all((X >= 0.0) & (X <= 1.0))
        opt.tell(X, np.sum((X - 3.0) ** 2, axis=1))
    assert np.allclose(opt.best_x, 1.0)
    assert np.mean(opt.ask() == 1.0) > 0.9


# -- DE (JADE, Zhang and Sanderson 2009) ------------------------------------------------------
def test_jade_parameter_sampling_and_adaptation():
    opt = AdaptiveDE(5, rng=0, options={"mu_F": 0.6, "mu_CR": 0.3})
    F, CR = opt.sample_parameters(20000)
    assert np.all((F > 0.0) & (F <= 1.0)) and np.all((CR >= 0.0) & (CR <= 1.0))
    # Cauchy(0.6, 0.1) redrawn while <= 0 (the quantiles below the cut at 1 are those of the
    # Cauchy law conditioned on F > 0)
    p0 = 0.5 + np.arctan(-6.0) / np.pi
    q = np.array([0.25, 0.5, 0.75])
    expect = 0.6 + 0.1 * np.tan(np.pi * (p0 + q * (1.0 - p0) - 0.5))
    assert np.allclose(np.quantile(F, q), expect, atol=0.005)
    assert abs(np.mean(F == 1.0) - (0.5 - np.arctan(4.0) / np.pi) / (1.0 - p0)) < 0.005
    assert abs(np.mean(CR) - 0.3) < 0.005 and abs(np.std(CR) - 0.1) < 0.005
    assert np.isclose(lehmer_mean(np.array([0.2, 0.8])), 0.68 / 1.0)
    opt.adapt(np.array([0.2, 0.8]), np.array([0.9, 0.7]))
    assert np.isclose(opt.mu_F, 0.9 * 0.6 + 0.1 * 0.68)
    assert np.isclose(opt.mu_CR, 0.9 * 0.3 + 0.1 * 0.8)
    opt.adapt(np.empty(0), np.empty(0))  # no success: unchanged
    assert np.isclose(opt.mu_CR, 0.9 * 0.3 + 0.1 * 0.8)


def test_other_than_avoids_and_covers():
    rng = np.random.default_rng(1)
    a = np.arange(6)
    b = (a + 1) % 6
    seen = np.zeros((6, 9))
    for _ in range(2000):
        r = other_than(rng, 9, a, b)
        assert np.all((r != a) & (r != b)) and np.all((r >= 0) & (r < 9))
        seen[a, r] += 1
    allowed = np.ones((6, 9), dtype=bool)
    allowed[a, a] = allowed[a, b] = False
    assert np.all(seen[~allowed] == 0)
    assert np.all(np.abs(seen[allowed] - 2000 / 7) < 6 * np.sqrt(2000 / 7))  # uniform over 7


def test_jade_generation_structure():
    opt = AdaptiveDE(4, rng=2, options={"popsize": 10, "mu_CR": 1.0, "archive": 0.5})
    X0 = opt.ask().copy()
    opt.tell(X0, np.arange(10.0))
    U = opt.ask().copy()
    assert U.shape == (10, 4) and np.all((U >= 0.0) & (U <= 1.0))
    assert np.all(np.any(U != X0, axis=1))  # j_rand: every trial differs from its parent
    fu = np.where(np.arange(10) % 2 == 0, -1.0, 100.0)  # even trials win
    opt.tell(U, fu)
    won = np.arange(10) % 2 == 0
    assert np.array_equal(opt.population[won], U[won])
    assert np.array_equal(opt.population[~won], X0[~won])
    assert np.array_equal(opt.energies, np.where(won, -1.0, np.arange(10.0)))
    assert opt.mu_F != 0.5 and opt.mu_CR != 1.0  # adapted toward the winners' draws


# -- GA (Deb: tournament, SBX, polynomial mutation) -------------------------------------------
def test_tournament_prefers_better():
    rng = np.random.default_rng(3)
    f = np.arange(10.0)
    w = tournament(rng, f, 100000, 2)
    # binary tournament with replacement: P(win = i) = ((10 - i)^2 - (9 - i)^2) / 100
    expect = ((10 - f) ** 2 - (9 - f) ** 2) / 100.0
    assert np.allclose(np.bincount(w, minlength=10) / 1e5, expect, atol=0.005)


def test_sbx_spread_bounds_and_rate():
    rng = np.random.default_rng(4)
    H, n = 20000, 3
    a, b = np.full((H, n), 0.45), np.full((H, n), 0.55)
    c1, c2 = sbx(a, b, 2.0, 1.0, rng)
    crossed = (c1 != a) | (c2 != b)
    assert abs(crossed.mean() - 0.5) < 0.01  # each variable with probability 1/2
    # far from the bounds SBX is symmetric: the children keep the parents' mean, and they fall
    # between the parents (spread factor beta <= 1) half of the time
    assert np.allclose((c1 + c2)[crossed], 1.0, atol=1e-6)
    lo = np.minimum(c1, c2)[crossed]
    assert abs(np.mean(lo >= 0.45) - 0.5) < 0.01
    # eta = 2: P(beta > 2) = 0.5 * 2^-(eta + 1) = 1/16 (children more than twice as far apart)
    assert abs(np.mean(np.abs(c1 - c2)[crossed] > 0.2) - 1 / 16) < 0.01
    # parents at the faces: children stay in the unit cube; pc = 0: no change
    a, b = rng.random((H, n)) * 1e-3, 1.0 - rng.random((H, n)) * 1e-3
    c1, c2 = sbx(a, b, 0.5, 1.0, rng)
    assert np.all((c1 >= 0) & (c1 <= 1) & (c2 >= 0) & (c2 <= 1))
    c1, c2 = sbx(a, b, 2.0, 0.0, rng)
    assert np.array_equal(c1, a) and np.array_equal(c2, b)


def test_polynomial_mutation_distribution():
    rng = np.random.default_rng(5)
    Y = np.full((20000, 5), 0.5)
    out = polynomial_mutation(Y.copy(), 20.0, 0.3, rng)
    moved = out != 0.5
    assert abs(moved.mean() - 0.3) < 0.01
    # mid-range gene: delta has density 0.5 (eta + 1)(1 - |delta|)^eta, E|delta| = 1 / (eta + 2)
    assert abs(np.mean(np.abs(out[moved] - 0.5)) * 22.0 - 1.0) < 0.03
    edge = polynomial_mutation(np.full((5000, 4), 0.999), 1.0, 1.0, rng)
    assert np.all((edge >= 0.0) & (edge <= 1.0))


def test_sbx_ga_keeps_the_best_of_parents_and_children():
    ga = SBXGA(3, rng=6, options={"popsize": 6})
    assert ga.pm == 1.0 / 3.0
    X0 = ga.ask().copy()
    f0 = np.array([5.0, 1.0, 7.0, 3.0, 9.0, 2.0])
    ga.tell(X0, f0)
    Y = ga.ask().copy()
    fy = np.array([4.0, 8.0, 0.5, 6.0, 10.0, 2.5])
    ga.tell(Y, fy)
    assert np.array_equal(ga.energies, [0.5, 1.0, 2.0, 2.5, 3.0, 4.0])
    assert np.array_equal(ga.population, np.array([Y[2], X0[1], X0[5], Y[5], X0[3], Y[0]]))


# -- quality at an equal budget (issue 29) ------------------------------------------------------
def ellipsoid10(X):
    shift = np.linspace(-3.0, 2.5, 10)
    return ((X - shift) ** 2) @ (10.0 ** (6.0 * np.arange(10) / 9))  # condition number 1e6


@pytest.mark.parametrize(
    ("new", "paper", "reach", "paper_above"),
    [("pso", "pso-liu2008", 1e-6, 1.0), ("de", "de-storn1997", 1e-6, 1e-5),
     ("ga", "ga-hu2005", 1e-1, 10.0)],
)
def test_default_beats_paper_variant_on_ellipsoid(new, paper, reach, paper_above):
    # 10-D ellipsoid, condition 1e6, 20 000 evaluations: the defaults reach costs the papers'
    # variants do not (bench_swarm.py has the medians over seeds and functions)
    b = [(-5.0, 5.0)] * 10
    res = minimize(ellipsoid10, b, new, rng=0, maxiter=10**6, maxfev=20000)
    old = minimize(ellipsoid10, b, paper, rng=0, maxiter=10**6, maxfev=20000)
    assert res.nfev <= 20000 + get_method(new)(10).popsize
    assert res.fun < reach < paper_above < old.fun
