"""`optimize.hybrid`: least squares, then a metaheuristic in a shrunk box (papers/000 sec. 4.2)."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.simulate import simulate
from kinecal.errors import InputError
from kinecal.io.models import load_model
from kinecal.optimize.hybrid import hybrid_methods, hybrid_minimize


def residual(x):
    """Rosenbrock residuals (2,): minimum 0 at (1, 1)."""
    return np.array([x[0] - 1.0, 10.0 * (x[1] - x[0] ** 2)])


def jacobian(x):
    return np.array([[1.0, 0.0], [-20.0 * x[0], 10.0]])


def cost(X):
    """Norm of the residual of each row of X (P, 2) -> (P,)."""
    X = np.atleast_2d(X)
    return np.hypot(X[:, 0] - 1.0, 10.0 * (X[:, 1] - X[:, 0] ** 2))


X0 = np.array([-1.2, 1.0])
HALF = np.array([1.0, 1.0])


def test_one_gauss_newton_step_then_ga_in_the_third_box():
    res = hybrid_minimize(cost, residual, jacobian, X0, HALF, "ga", ls_maxiter=1, rng=0,
                          maxiter=60)
    # one Gauss-Newton step from (-1.2, 1): x0 = 1 exactly, x1 = 2 (-1.2) - 1.44 = -3.84
    np.testing.assert_allclose(res.ls_result.x, [1.0, -3.84], atol=1e-12)
    assert res.ls_iterations == 1
    lo, hi = res.ls_result.x - HALF / 3, res.ls_result.x + HALF / 3
    assert np.all(res.x >= lo - 1e-12) and np.all(res.x <= hi + 1e-12)
    # the LS solution is seeded and the GA is elitist: never worse than the LS start
    assert res.history[0] == pytest.approx(cost(res.ls_result.x)[0])
    assert res.fun <= res.history[0]
    assert np.all(np.diff(res.history[1:]) <= 0)
    assert res.nfev > res.ls_result.nfev and res.nit == 60


def test_shrink_is_an_option():
    narrow = hybrid_minimize(cost, residual, jacobian, X0, HALF, "pso", ls_maxiter=1, rng=1,
                             maxiter=200)
    wide = hybrid_minimize(cost, residual, jacobian, X0, HALF, "pso", ls_maxiter=1, rng=1,
                           maxiter=200, shrink=6.0)
    # the 1/3 box around (1, -3.84) excludes the optimum; a box of 6 half-widths contains it
    assert narrow.fun > 10.0
    assert wide.fun < 1e-3 and np.allclose(wide.x, [1.0, 1.0], atol=1e-2)


def test_same_seed_same_result_and_seed_ls_off():
    a = hybrid_minimize(cost, residual, jacobian, X0, HALF, "de", ls_maxiter=1, rng=5,
                        maxiter=30)
    b = hybrid_minimize(cost, residual, jacobian, X0, HALF, "de", ls_maxiter=1, rng=5,
                        maxiter=30)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.history == b.history
    c = hybrid_minimize(cost, residual, jacobian, X0, HALF, "de", ls_maxiter=1, rng=5,
                        maxiter=30, seed_ls=False)
    assert c.history != a.history  # the LS point is (only) in the seeded population
    assert a.history[1] <= a.history[0]


def test_lm_first_stage_reaches_the_optimum():
    res = hybrid_minimize(cost, residual, jacobian, X0, HALF, "gwo", least_squares="lm",
                          rng=0, maxiter=5, target=1e-9)
    assert res.fun <= 1e-9 and res.nit == 0  # the seeded LS point already meets the target


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [({"method": "simplex"}, "simplex"), ({"shrink": 0.0}, "shrink"),
     ({"least_squares": "qr"}, "least_squares")],
)
def test_bad_options(kwargs, word):
    with pytest.raises(InputError, match=word):
        hybrid_minimize(cost, residual, jacobian, X0, HALF, **{"method": "ga", **kwargs})


def test_calibrate_hybrid_pso_on_the_scanner():
    """papers/000 setting: LS stopped after one iteration, PSO in the 1/3 box improves on it."""
    assert "hybrid-ga" in hybrid_methods() and "hybrid-sa-iafsa" in hybrid_methods()
    model = load_model("hu2005-scanner")
    sim = simulate(model, 15, errors="random", rng=3)
    ls1 = calibrate(model, sim.data, "householder", free="all", maxiter=1)
    res = calibrate(model, sim.data, "hybrid-pso", free="all", rng=0, maxiter=150,
                    options={"ls_maxiter": 1, "popsize": 40})
    assert res.history[0] == pytest.approx(ls1.errors_after.mean())
    assert res.errors_after.mean() < 0.5 * ls1.errors_after.mean()
    # every parameter stays in the box: LS solution +- tolerance / 3
    lo_hi = np.abs(res.params - ls1.params)
    tol = np.where(model.is_angle(), model.tolerances["angle"], model.tolerances["length"])
    assert np.all(lo_hi <= tol / 3 + 1e-9)
