"""Least squares first, then a metaheuristic in a shrunk box (papers/000 sec. 4.2).

Paper 000's hybrid intelligent algorithm: (1) the modified least squares (Householder
Gauss-Newton) gives a sub-optimal solution quickly; (2) the GA's gene ranges are centred
on that solution and each parameter's range is shrunk to 1/3 of its tolerance range; the
GA then refines it. Here any metaheuristic of `kinecal.optimize` can be the second stage
(``hybrid-ga``, ``hybrid-sa-iafsa``, ``hybrid-pso``, ...), the shrink factor is an option,
and the least-squares solution is also seeded into the initial population. The paper's own GA
is ``ga-hu2005`` (``hybrid-ga-hu2005``, what ``kinecal reproduce hu2005`` runs); ``ga`` is
Deb's SBX GA.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.optimize import METHODS
from kinecal.optimize._common import make_result
from kinecal.optimize.lsq import householder_gauss_newton, levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["HYBRID_PREFIX", "hybrid_methods", "hybrid_minimize"]

Array = NDArray[np.float64]
HYBRID_PREFIX = "hybrid-"


def hybrid_methods() -> tuple[str, ...]:
    """``hybrid-<m>`` for every metaheuristic ``m``."""
    return tuple(HYBRID_PREFIX + m for m in METHODS)


def hybrid_minimize(
    population_cost: Callable[[Array], Array],
    residual: Callable[[Array], Array],
    jacobian: Callable[[Array], Array],
    x0: Array,
    half_width: Array,
    method: str = "ga",
    *,
    least_squares: str = "householder",
    ls_maxiter: int = 4,
    shrink: float = 1.0 / 3.0,
    seed_ls: bool = True,
    rng: int | np.random.Generator | None = None,
    maxiter: int | None = None,
    target: float | None = None,
    callback: Callable[[OptimizeResult], Any] | None = None,
    options: dict | None = None,
    monitor: Callable[[Array], float] | None = None,
) -> OptimizeResult:
    """Two-stage calibration: least squares, then `method` around its solution.

    Parameters
    ----------
    population_cost : callable
        ``(P, n) -> (P,)`` cost of the metaheuristic (paper 000: mean distance error).
    residual, jacobian : callable
        Residual ``(m,)`` and Jacobian ``(m, n)`` for the least-squares stage.
    x0 : ndarray, shape (n,)
        Nominal parameters (least-squares start).
    half_width : ndarray, shape (n,)
        Tolerance half-widths; the second stage's box is ``x_ls +- shrink * half_width``
        (papers/000 sec. 4.2 item 2: range shrunk to 1/3).
    method : str
        Metaheuristic of `kinecal.optimize.minimize`.
    least_squares : {"householder", "lm"}
        First stage: paper 000's Householder Gauss-Newton (``ls_maxiter`` iterations; the
        paper's LS gains nothing after 4) or Levenberg-Marquardt.
    seed_ls : bool
        Put the least-squares solution into the initial population.

    Returns
    -------
    OptimizeResult
        The metaheuristic's result with ``history`` = least-squares stage followed by the
        metaheuristic's, ``nit``/``nfev`` summed, plus ``ls_result``, ``ls_iterations`` and
        ``bounds`` (the second stage's box, ``(n, 2)``).
    """
    if method not in METHODS:
        raise InputError(
            f"unknown method {method!r} for the hybrid; expected one of {', '.join(METHODS)}",
            option="--method",
        )
    if not shrink > 0:
        raise InputError(f"shrink: expected > 0, got {shrink}", option="shrink")
    t0 = time.perf_counter()
    if least_squares == "householder":
        ls = householder_gauss_newton(residual, jacobian, x0, maxiter=ls_maxiter, monitor=monitor)
    elif least_squares == "lm":
        ls = levenberg_marquardt(residual, jacobian, x0, monitor=monitor)
    else:
        raise InputError(f"least_squares: expected householder or lm, got {least_squares!r}")
    from kinecal.optimize import minimize  # the metaheuristics: imported when one runs

    center = ls.x
    bounds = np.column_stack([center - shrink * half_width, center + shrink * half_width])
    res = minimize(
        population_cost,
        bounds,
        method,
        x0=center if seed_ls else None,
        rng=rng,
        maxiter=maxiter,
        target=target,
        callback=callback,
        options=options,
    )
    ls_cost = float(population_cost(center[None, :])[0])
    history = [ls_cost] + list(res.history)
    extra = {
        k: v
        for k, v in res.items()
        if k
        not in ("x", "fun", "nit", "nfev", "success", "status", "message", "history", "elapsed")
    }
    return make_result(
        res.x,
        res.fun,
        nit=res.nit,
        nfev=res.nfev + ls.nfev,
        success=res.success,
        status=res.status,
        message=f"least squares ({ls.nit} it.), then {method}: {res.message}",
        history=history,
        elapsed=time.perf_counter() - t0,
        ls_result=ls,
        ls_iterations=int(ls.nit),
        ls_history=list(ls.history),
        bounds=bounds,
        **extra,
    )
