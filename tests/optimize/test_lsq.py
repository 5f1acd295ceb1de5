"""kinecal's least-squares solvers: the LM core (`kinecal.optimize.lm`) against scipy's
MINPACK on a problem with a known solution, and the core without an OptimizeResult equal,
step for step, to the public `levenberg_marquardt` built on it."""

import numpy as np
import pytest
from scipy.optimize import OptimizeResult, least_squares

from kinecal.optimize.lm import LMSolution, solve_normal_equations
from kinecal.optimize.lsq import householder_gauss_newton, levenberg_marquardt

T = np.linspace(0.0, 4.0, 40)
TRUTH = np.array([2.5, -1.3, 0.7, 0.4])


def _model(x):
    return x[0] * np.exp(x[1] * T) + x[2] * np.sin(3.0 * T + x[3])


def _jac(x):
    e = np.exp(x[1] * T)
    return np.column_stack([e, x[0] * T * e, np.sin(3.0 * T + x[3]),
                            x[2] * np.cos(3.0 * T + x[3])])


def _problem(noise):
    y = _model(TRUTH) + noise * np.random.default_rng(4).standard_normal(T.size)
    return (lambda x: _model(x) - y), _jac


def _normal(residual, jac):
    def equations(x):
        r, J = residual(x), jac(x)
        return r, J.T @ J, J.T @ r
    return equations


X0 = np.array([1.0, -0.5, 1.0, 0.0])


def test_noise_free_truth_recovered_and_derivative_checked():
    residual, jac = _problem(0.0)
    h = 1e-6
    numeric = np.column_stack([(residual(X0 + h * e) - residual(X0 - h * e)) / (2 * h)
                               for e in np.eye(4)])
    np.testing.assert_allclose(jac(X0), numeric, atol=1e-7)
    res = levenberg_marquardt(residual, jac, X0)
    assert isinstance(res, OptimizeResult) and res.success
    np.testing.assert_allclose(res.x, TRUTH, atol=1e-10)


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_lm_matches_minpack(noise):
    residual, jac = _problem(noise)
    ours = levenberg_marquardt(residual, jac, X0, ftol=1e-15, xtol=1e-15, gtol=1e-15)
    ref = least_squares(residual, X0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15)
    np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-9)
    assert ours.fun == pytest.approx(ref.cost, rel=1e-10, abs=1e-20)


def test_core_without_optimize_result_is_the_public_solver():
    residual, jac = _problem(0.05)
    eq = _normal(residual, jac)
    public = levenberg_marquardt(None, None, X0, normal_equations=eq, damping=(1e-9, 1e-3))
    core = solve_normal_equations(eq, X0, damping=(1e-9, 1e-3))
    assert isinstance(core, LMSolution) and not isinstance(core, dict)
    assert np.array_equal(core.x, public.x) and core.fun == public.fun
    assert (core.nit, core.nfev, core.njev, core.status) == (public.nit, public.nfev,
                                                             public.njev, public.status)
    assert core.history == list(public.history) and core.success == public.success
    np.testing.assert_array_equal(core.normal_matrix, public.normal_matrix)
    assert core.jac is None and "jac" not in public


def test_budget_spent_is_not_success():
    residual, jac = _problem(0.05)
    core = solve_normal_equations(_normal(residual, jac), X0, max_nfev=2)
    assert core.status == 0 and not core.success and core.nfev == 2


def test_householder_gauss_newton_on_a_linear_problem_is_least_squares():
    rng = np.random.default_rng(2)
    A, b = rng.standard_normal((30, 5)), rng.standard_normal(30)
    res = householder_gauss_newton(lambda x: A @ x - b, lambda x: A, np.zeros(5))
    np.testing.assert_allclose(res.x, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-12)
