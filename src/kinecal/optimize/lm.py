"""kinecal's Levenberg-Marquardt on the normal equations (the default solver of
`kinecal.optimize.lsq.levenberg_marquardt`).

Marquardt-scaled damping ``(J^T J + mu diag(J^T J)) h = -J^T r`` with Nielsen's damping
update (Madsen, Nielsen, Tingleff 2004, "Methods for non-linear least squares problems",
alg. 3.16). `solve_normal_equations` returns an `LMSolution`, not scipy's
``OptimizeResult``: callers that run the solver inside their own loop (the hand-eye bundle
adjustment of `kinecal handeye-images`) then never import `scipy.optimize`, whose import
costs 0.1-0.2 s, more than such a command's solve. `levenberg_marquardt` turns it into the
``OptimizeResult`` every public solver returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal._blas import small_products

__all__ = ["LMSolution", "NormalEquations", "solve_normal_equations"]

Array = NDArray[np.float64]
Residual = Callable[[Array], Array]
Jacobian = Callable[[Array], Array]
#: ``normal_equations(x) -> (r, J^T J, J^T r)``
NormalEquations = Callable[[Array], tuple[Array, Array, Array]]
#: ``linear_solver(A, damp, g) -> h`` with ``(A + diag(damp)) h = -g``
LinearSolver = Callable[[Array, Array, Array], Array]
#: ``linearize(x, r) -> (J^T J, J^T r, J or None)``
Linearize = Callable[[Array, Array], tuple[Array, Array, Array | None]]


@dataclass
class LMSolution:
    """Where the LM stopped.

    Attributes
    ----------
    x : numpy.ndarray, shape (n,)
        Solution.
    fun : float
        ``0.5 ||r||^2`` at `x`.
    residual : numpy.ndarray, shape (m,)
        ``r`` at `x`.
    normal_matrix, gradient : numpy.ndarray, shapes (n, n) and (n,)
        ``J^T J`` and ``J^T r`` at `x`.
    jac : numpy.ndarray, shape (m, n), or None
        ``J`` at `x` when the solver was given residual and Jacobian functions.
    nit, nfev, njev : int
        Accepted steps, residual evaluations, linearisations.
    status : int
        1 gradient or zero residual, 2 step below xtol, 3 cost reduction below ftol,
        4 no decrease at round-off level, 0 evaluation budget spent.
    message : str
        The reason in words.
    damping : float
        The last damping ``mu`` (relative to ``diag(J^T J)``).
    history : list of float
        Monitored cost at the start and after each accepted step.
    elapsed : float
        Wall time in seconds.
    """

    x: Array
    fun: float
    residual: Array
    normal_matrix: Array
    gradient: Array
    jac: Array | None = None
    nit: int = 0
    nfev: int = 1
    njev: int = 1
    status: int = 0
    message: str = "maximum number of function evaluations reached"
    damping: float = 1e-3
    history: list[float] = field(default_factory=list)
    elapsed: float = 0.0

    @property
    def success(self) -> bool:
        """True unless the evaluation budget ran out."""
        return self.status > 0


def cholesky_step(A: Array, damp: Array, g: Array) -> Array:
    """``h`` with ``(A + diag(damp)) h = -g`` by dense Cholesky (LAPACK's, through scipy,
    imported here: a caller with its own `linear_solver` does not load scipy.linalg)."""
    import scipy.linalg

    c = scipy.linalg.cho_factor(A + np.diag(damp), check_finite=False)
    return -scipy.linalg.cho_solve(c, g, check_finite=False)


def plain_normal_equations(residual: Residual, jacobian: Jacobian
                           ) -> tuple[Residual, Linearize]:
    """``evaluate(x) -> r`` and ``linearize(x, r) -> (A, g, J)`` from plain callables."""

    def linearize(x: Array, r: Array):
        J = jacobian(x)
        return J.T @ J, J.T @ r, J

    return residual, linearize


def cached_normal_equations(normal_equations: NormalEquations) -> tuple[Residual, Linearize]:
    """``evaluate`` / ``linearize`` from one call that returns r, A and g together."""
    last: dict = {}

    def evaluate(x: Array) -> Array:
        r, A, g = normal_equations(x)
        last.update(x=x.copy(), A=A, g=g)
        return r

    def linearize(x: Array, r: Array):
        if "x" in last and np.array_equal(last["x"], x):
            return last["A"], last["g"], None
        _, A, g = normal_equations(x)
        return A, g, None

    return evaluate, linearize


def solve_normal_equations(
    normal_equations: NormalEquations, x0: Array, *, max_nfev: int | None = None,
    ftol: float = 1e-12, xtol: float = 1e-12, gtol: float = 1e-12,
    damping: float | tuple[float, float] = 1e-3, linear_solver: LinearSolver | None = None,
    monitor: Callable[[Array], float] | None = None,
) -> LMSolution:
    """kinecal's LM on normal equations accumulated by the caller.

    Parameters
    ----------
    normal_equations : callable
        ``normal_equations(x) -> (r (m,), J^T J (n, n), J^T r (n,))``.
    x0 : numpy.ndarray, shape (n,)
        Start point.
    max_nfev : int, optional
        Evaluation budget (default ``200 (n + 1)``).
    ftol, xtol, gtol, damping, linear_solver, monitor
        As `kinecal.optimize.lsq.levenberg_marquardt`.

    Returns
    -------
    LMSolution
        ``jac`` is None (the caller never formed ``J``).
    """
    x = np.asarray(x0, dtype=float)
    evaluate, linearize = cached_normal_equations(normal_equations)
    return iterate(evaluate, linearize, x, max_nfev=max_nfev or 200 * (x.size + 1),
                   ftol=ftol, xtol=xtol, gtol=gtol, monitor=monitor or rms,
                   damping=damping, linear_solver=linear_solver or cholesky_step)


def rms(r: Array) -> float:
    """RMS of the residual vector (the default monitored cost)."""
    return float(np.sqrt(np.mean(np.square(r))))


class _State:
    """The iterate of `iterate`: point, residual, cost, normal equations and counters."""

    def __init__(self, x: Array, r: Array, A: Array, g: Array, J: Array | None,
                 monitor: Callable[[Array], float]):
        self.x, self.r, self.A, self.g, self.J = x, r, A, g, J
        self.F = 0.5 * float(r @ r)
        self.monitor = monitor
        self.nfev, self.njev, self.nit = 1, 1, 0
        self.history = [monitor(r)]

    def accept(self, x: Array, r: Array, F: float, linearize: Linearize) -> None:
        self.x, self.r, self.F = x, r, F
        self.A, self.g, self.J = linearize(x, r)
        self.njev += 1
        self.nit += 1
        self.history.append(self.monitor(r))


@small_products
def iterate(
    evaluate: Residual, linearize: Linearize, x: Array, *, max_nfev: int, ftol: float,
    xtol: float, gtol: float, monitor: Callable[[Array], float],
    start: tuple[Array, Array, Array] | None = None,
    damping: float | tuple[float, float] = 1e-3,
    linear_solver: LinearSolver = cholesky_step,
) -> LMSolution:
    """Levenberg-Marquardt on the normal equations (stopping rules: the Notes of
    `kinecal.optimize.lsq.levenberg_marquardt`).

    ``evaluate(x) -> r`` at every trial point, ``linearize(x, r) -> (J^T J, J^T r, J or
    None)`` at accepted points (right after `evaluate` at the same point).
    """
    t0 = time.perf_counter()
    if start is not None:
        s = _State(x, *start, None, monitor)
    else:
        r = evaluate(x)
        s = _State(x, r, *linearize(x, r), monitor)
    # dimensionless: the damping is mu * diag(J^T J) (Marquardt scaling)
    mu, fallback = (damping, None) if np.isscalar(damping) else damping
    trusted = False  # the last accepted step agreed with the quadratic model
    nu = 2.0
    status, message = 0, "maximum number of function evaluations reached"
    while s.nfev < max_nfev:
        if s.F == 0.0:
            status, message = 1, "zero residual"
            break
        if np.max(np.abs(s.g), initial=0.0) <= gtol * max(np.sqrt(2 * s.F), 1e-300):
            status, message = 1, "gradient below gtol"
            break
        d = np.diag(s.A).copy()
        d = np.maximum(d, 1e-12 * max(d.max(), 1e-300))  # Marquardt scaling, kept positive
        try:
            h = linear_solver(s.A, mu * d, s.g)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        if np.linalg.norm(h) <= xtol * (np.linalg.norm(s.x) + xtol):
            status, message = 2, "step below xtol"
            break
        predicted = 0.5 * float(h @ (mu * d * h - s.g))
        if trusted and 0.0 <= predicted <= ftol * s.F:
            # the quadratic model, just confirmed by an accepted step, promises less than
            # ftol: converged without spending an evaluation to confirm it
            status, message = 3, "predicted reduction of the cost below ftol"
            break
        x_new = s.x + h
        r_new = evaluate(x_new)
        s.nfev += 1
        F_new = 0.5 * float(r_new @ r_new)
        rho = (s.F - F_new) / predicted if predicted > 0 else -1.0
        if predicted <= ftol * s.F and abs(s.F - F_new) <= ftol * s.F:
            # both reductions at round-off level (MINPACK's ftol test): converged; a
            # further step would only trade round-off for evaluations
            if F_new < s.F:
                s.accept(x_new, r_new, F_new, linearize)
            status, message = 3, "relative reduction of the cost below ftol"
            break
        if rho > 0 and np.isfinite(F_new):
            reduction = s.F - F_new
            s.accept(x_new, r_new, F_new, linearize)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu, fallback, trusted = 2.0, None, rho > 0.75
            if reduction <= ftol * F_new:
                status, message = 3, "relative reduction of the cost below ftol"
                break
        else:
            mu *= nu
            nu *= 2.0
            if fallback is not None:  # the near Gauss-Newton first step failed
                mu, fallback = max(mu, fallback), None
            if mu > 1e30:
                status, message = 4, "no further decrease possible (round-off level)"
                break
    return LMSolution(s.x, s.F, s.r, s.A, s.g, s.J, s.nit, s.nfev, s.njev, status, message,
                      mu, s.history, time.perf_counter() - t0)
