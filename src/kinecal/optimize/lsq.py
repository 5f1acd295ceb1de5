"""Least-squares solvers for calibration: paper 000's Householder Gauss-Newton and LM.

Both take a residual function ``r(x) -> (m,)`` and its Jacobian ``J(x) -> (m, n)`` and
return the same `scipy.optimize.OptimizeResult` as the metaheuristics, with ``history``
holding a monitored cost after each iteration (``monitor(r)``, default the RMS residual).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, least_squares

from kinecal.errors import InputError
from kinecal.optimize._common import make_result

__all__ = ["LOSSES", "householder_gauss_newton", "levenberg_marquardt"]

Array = NDArray[np.float64]
Residual = Callable[[Array], Array]
Jacobian = Callable[[Array], Array]
#: ``normal_equations(x) -> (r, J^T J, J^T r)``
NormalEquations = Callable[[Array], tuple[Array, Array, Array]]

#: ``linear_solver(A, damp, g) -> h`` with ``(A + diag(damp)) h = -g``
LinearSolver = Callable[[Array, Array, Array], Array]

#: robust losses of `levenberg_marquardt` (scipy names)
LOSSES = ("linear", "huber", "soft_l1", "cauchy", "arctan")


def _rms(r: Array) -> float:
    return float(np.sqrt(np.mean(np.square(r))))


def householder_gauss_newton(
    residual: Residual,
    jacobian: Jacobian,
    x0: Array,
    *,
    maxiter: int = 1000,
    xtol: float = 1e-12,
    singular_tol: float = 1e-10,
    monitor: Callable[[Array], float] | None = None,
    callback: Callable[[OptimizeResult], bool | None] | None = None,
) -> OptimizeResult:
    """Gauss-Newton with the normal equations solved by Householder QR (papers/000 sec. 3-4.1).

    Each iteration linearises ``dP = J d`` (papers/000 eq. 7), and computes the update of
    eq. (10)-(11), ``d = (J^T J)^-1 J^T dP``, the way sec. 4.1 ("modified least squares")
    does: Householder QR of ``J`` (no pivoting), ``R d = Q^T dP``, without forming ``J^T J``.
    The paper notes that ``J^T J`` tends to become singular; here a diagonal element of
    ``R`` below ``singular_tol * max |R_kk|`` is that singularity: the step is then taken
    with those components set to zero (the update the paper could still compute), the
    result's ``singular`` lists their column indices and the message says so.

    Parameters
    ----------
    residual, jacobian : callable
        ``r(x) -> (m,)`` and ``J(x) -> (m, n)`` (``dr/dx``).
    x0 : ndarray, shape (n,)
        Start point.
    maxiter : int
        Iteration budget (papers/000 Table 2 runs the LS to 1000 iterations).
    xtol : float
        Stop when ``||d|| <= xtol * (||x|| + xtol)``.
    singular_tol : float
        Relative threshold on ``|R_kk|`` for a singular column.
    monitor : callable, optional
        ``monitor(r) -> float`` recorded in ``history`` (default RMS of r).
    callback : callable, optional
        Called with an intermediate result after each iteration; True stops.

    Returns
    -------
    OptimizeResult
        ``x, fun (0.5 ||r||^2), nit, nfev, njev, history, singular, success, status, message``.
    """
    monitor = monitor or _rms
    t0 = time.perf_counter()
    x = np.array(x0, dtype=float)
    r = residual(x)
    history = [monitor(r)]
    nfev, njev = 1, 0
    singular_seen: set[int] = set()
    status, message = 0, "maximum number of iterations reached"
    for it in range(1, maxiter + 1):
        J = jacobian(x)
        njev += 1
        Q, R = scipy.linalg.qr(J, mode="economic")  # LAPACK geqrf: Householder reflections
        diag = np.abs(np.diag(R))
        singular = diag <= singular_tol * diag.max()
        rhs = -(Q.T @ r)
        if singular.any():
            singular_seen.update(np.flatnonzero(singular).tolist())
            keep = ~singular
            d = np.zeros_like(x)
            d[keep] = scipy.linalg.solve_triangular(R[np.ix_(keep, keep)], rhs[keep])
        else:
            d = scipy.linalg.solve_triangular(R, rhs)
        x = x + d
        r = residual(x)
        nfev += 1
        history.append(monitor(r))
        if callback is not None:
            stop = callback(OptimizeResult(x=x.copy(), fun=0.5 * float(r @ r), nit=it, nfev=nfev))
            if stop:
                status, message = 3, "stopped by the callback"
                break
        if np.linalg.norm(d) <= xtol * (np.linalg.norm(x) + xtol):
            status, message = 4, "step below xtol"
            break
    nit = it
    if singular_seen:
        message += (
            f"; J^T J singular in {len(singular_seen)} direction(s) (columns "
            f"{sorted(singular_seen)}): those parameters are not identifiable and were not updated"
        )
    return make_result(
        x,
        0.5 * float(r @ r),
        nit=nit,
        nfev=nfev,
        success=status in (0, 4) and not singular_seen,
        status=status,
        message=message,
        history=history,
        elapsed=time.perf_counter() - t0,
        njev=njev,
        singular=sorted(singular_seen),
    )


def levenberg_marquardt(
    residual: Residual,
    jacobian: Jacobian,
    x0: Array,
    *,
    loss: str = "linear",
    f_scale: float = 1.0,
    max_nfev: int | None = None,
    ftol: float | None = None,
    xtol: float | None = None,
    gtol: float | None = None,
    solver: str = "kinecal",
    monitor: Callable[[Array], float] | None = None,
    normal_equations: NormalEquations | None = None,
    start: tuple[Array, Array, Array] | None = None,
    damping: float | tuple[float, float] = 1e-3,
    linear_solver: LinearSolver | None = None,
) -> OptimizeResult:
    """Levenberg-Marquardt with the analytic Jacobian.

    ``solver="kinecal"`` (default for ``loss="linear"``): Marquardt-scaled damping
    ``(J^T J + mu diag(J^T J)) h = -J^T r`` solved by Cholesky, with Nielsen's damping update
    (Madsen, Nielsen, Tingleff 2004, "Methods for non-linear least squares problems",
    alg. 3.16). Calibration Jacobians are tall and narrow (thousands of rows, tens of
    columns): forming ``J^T J`` once per iteration costs a fraction of MINPACK's QR, which
    matters once the residual and Jacobian themselves are cheap.
    ``solver="minpack"`` or a robust loss (``huber``, ``soft_l1``, ``cauchy``, ``arctan``,
    with scale `f_scale` in residual units): scipy `least_squares` (MINPACK LM for linear,
    trust-region reflective for robust losses) with the same analytic Jacobian.

    Parameters
    ----------
    residual, jacobian : callable
        ``r(x) -> (m,)`` and ``J(x) -> (m, n)``.
    x0 : ndarray, shape (n,)
        Start point.
    normal_equations : callable, optional
        ``normal_equations(x) -> (r, J^T J, J^T r)``: the kinecal solver then never asks
        for ``J`` itself, so a caller can accumulate the ``(n, n)`` normal equations over
        chunks of rows (memory linear in ``m`` with a small constant). Used only by the
        kinecal solver; `residual` and `jacobian` still serve MINPACK and robust losses.
    start : tuple of ndarray, optional
        ``(r, J^T J, J^T r)`` already known at `x0` (kinecal solver): saves one evaluation.
    damping : float or (float, float)
        Initial damping ``mu`` of the kinecal solver, relative to ``diag(J^T J)``. The
        default suits a start far from the solution. A pair ``(first, fallback)`` tries
        the first step with ``first`` and, if that step fails, continues from
        ``fallback``: a start where the linearisation is probably good (continuing a fit
        on more parameters) tries a near Gauss-Newton step (``first`` = 1e-9) at the risk
        of one evaluation. With weakly identifiable directions (condition ``c``) each
        accepted step divides ``mu`` by at most 3: a large ``mu`` costs about
        ``log3(c^2 mu)`` iterations before those directions move.
    linear_solver : callable, optional
        ``linear_solver(A, damp, g) -> h`` solving ``(A + diag(damp)) h = -g`` for the
        kinecal solver's steps (raising `numpy.linalg.LinAlgError` when the matrix is not
        positive definite), for normal matrices with structure (e.g. a Schur complement);
        default: dense Cholesky.

    Returns
    -------
    OptimizeResult
        ``x, fun (0.5 sum rho(r^2)), nit, nfev, njev, history, residual, jac, success,
        status, message``; the kinecal solver also returns ``normal_matrix`` (``J^T J``)
        and ``gradient`` (``J^T r``) at ``x`` and its last ``damping``, and ``jac`` only
        without `normal_equations`;
        ``history`` is the monitored cost (default RMS residual) after each accepted step,
        ``history[0]`` at `x0`.

    Notes
    -----
    Stopping (kinecal solver; defaults 1e-12): relative cost reduction of an accepted step
    ``<= ftol``, or predicted and actual relative reductions of a trial step both
    ``<= ftol`` (the cost's round-off floor), or a predicted relative reduction ``<= ftol``
    right after a step that the quadratic model predicted well (gain ratio > 0.75), step
    ``<= xtol (||x|| + xtol)``, gradient ``max |J^T r| <= gtol ||r||``, a zero residual,
    or no decrease possible at round-off level. MINPACK defaults: 1e-15.
    """
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if solver not in ("kinecal", "minpack"):
        raise InputError(f"solver: expected kinecal or minpack, got {solver!r}")
    monitor = monitor or _rms
    if loss == "linear" and solver == "kinecal":
        if normal_equations is not None:
            evaluate, linearize = _cached_normal_equations(normal_equations)
        else:
            evaluate, linearize = _plain_normal_equations(residual, jacobian)
        return _lm_normal_equations(evaluate, linearize, np.asarray(x0, dtype=float),
                                    start=start, damping=damping,
                                    max_nfev=max_nfev or 200 * (np.size(x0) + 1),
                                    ftol=1e-12 if ftol is None else ftol,
                                    xtol=1e-12 if xtol is None else xtol,
                                    gtol=1e-12 if gtol is None else gtol, monitor=monitor,
                                    linear_solver=linear_solver or _cholesky_step)
    ftol, xtol, gtol = (1e-15 if v is None else v for v in (ftol, xtol, gtol))
    history: list[float] = []

    def fun(x: Array) -> Array:
        r = residual(x)
        value = monitor(r)
        history.append(value if not history else min(value, history[-1]))
        return r

    t0 = time.perf_counter()
    method = "lm" if loss == "linear" else "trf"
    out = least_squares(fun, np.asarray(x0, dtype=float), jac=lambda x: jacobian(x),
                        method=method, loss=loss, f_scale=f_scale, max_nfev=max_nfev,
                        ftol=ftol, xtol=xtol, gtol=gtol, x_scale="jac")
    elapsed = time.perf_counter() - t0
    njev = int(out.njev) if out.njev is not None else 0
    return make_result(
        out.x, float(out.cost), nit=njev, nfev=int(out.nfev), success=bool(out.success),
        status=int(out.status), message=str(out.message), history=history, elapsed=elapsed,
        njev=njev, residual=out.fun, jac=out.jac,
    )


def _cholesky_step(A: Array, damp: Array, g: Array) -> Array:
    """``h`` with ``(A + diag(damp)) h = -g`` by dense Cholesky."""
    c = scipy.linalg.cho_factor(A + np.diag(damp), check_finite=False)
    return -scipy.linalg.cho_solve(c, g, check_finite=False)


def _plain_normal_equations(residual: Residual, jacobian: Jacobian):
    """``evaluate(x) -> r`` and ``linearize(x, r) -> (A, g, J)`` from plain callables."""

    def linearize(x: Array, r: Array):
        J = jacobian(x)
        return J.T @ J, J.T @ r, J

    return residual, linearize


def _cached_normal_equations(normal_equations: NormalEquations):
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


def _lm_normal_equations(
    evaluate: Residual, linearize: Callable, x: Array, *, max_nfev: int, ftol: float,
    xtol: float, gtol: float, monitor: Callable[[Array], float],
    start: tuple[Array, Array, Array] | None = None,
    damping: float | tuple[float, float] = 1e-3,
    linear_solver: LinearSolver = _cholesky_step,
) -> OptimizeResult:
    """Levenberg-Marquardt on the normal equations (see `levenberg_marquardt`).

    ``evaluate(x) -> r`` at every trial point, ``linearize(x, r) -> (J^T J, J^T r, J or
    None)`` at accepted points (right after `evaluate` at the same point).
    """
    t0 = time.perf_counter()
    if start is not None:
        r, A, g = start
        J = None
    else:
        r = evaluate(x)
        A, g, J = linearize(x, r)
    F = 0.5 * float(r @ r)
    nfev, njev, nit = 1, 1, 0
    history = [monitor(r)]
    # dimensionless: the damping is mu * diag(J^T J) (Marquardt scaling)
    mu, fallback = (damping, None) if np.isscalar(damping) else damping
    trusted = False  # the last accepted step agreed with the quadratic model
    nu = 2.0
    status, message = 0, "maximum number of function evaluations reached"
    while nfev < max_nfev:
        if F == 0.0:
            status, message = 1, "zero residual"
            break
        if np.max(np.abs(g), initial=0.0) <= gtol * max(np.sqrt(2 * F), 1e-300):
            status, message = 1, "gradient below gtol"
            break
        d = np.diag(A).copy()
        d = np.maximum(d, 1e-12 * max(d.max(), 1e-300))  # Marquardt scaling, kept positive
        try:
            h = linear_solver(A, mu * d, g)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        if np.linalg.norm(h) <= xtol * (np.linalg.norm(x) + xtol):
            status, message = 2, "step below xtol"
            break
        predicted = 0.5 * float(h @ (mu * d * h - g))
        if trusted and 0.0 <= predicted <= ftol * F:
            # the quadratic model, just confirmed by an accepted step, promises less than
            # ftol: converged without spending an evaluation to confirm it
            status, message = 3, "predicted reduction of the cost below ftol"
            break
        x_new = x + h
        r_new = evaluate(x_new)
        nfev += 1
        F_new = 0.5 * float(r_new @ r_new)
        rho = (F - F_new) / predicted if predicted > 0 else -1.0
        if predicted <= ftol * F and abs(F - F_new) <= ftol * F:
            # both reductions at round-off level (MINPACK's ftol test): converged; a
            # further step would only trade round-off for evaluations
            if F_new < F:
                x, r, F = x_new, r_new, F_new
                A, g, J = linearize(x, r)
                njev += 1
                nit += 1
                history.append(monitor(r))
            status, message = 3, "relative reduction of the cost below ftol"
            break
        if rho > 0 and np.isfinite(F_new):
            reduction = F - F_new
            x, r, F = x_new, r_new, F_new
            A, g, J = linearize(x, r)
            njev += 1
            nit += 1
            history.append(monitor(r))
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            fallback = None
            trusted = rho > 0.75
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
    extra = {} if J is None else {"jac": J}
    return make_result(
        x, F, nit=nit, nfev=nfev, success=status > 0, status=status, message=message,
        history=history, elapsed=time.perf_counter() - t0, njev=njev, residual=r,
        normal_matrix=A, gradient=g, damping=mu, **extra,
    )
