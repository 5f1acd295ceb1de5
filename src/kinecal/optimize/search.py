"""`minimize`: the registry of population optimizers and the one entry point that runs them
(`kinecal.optimize`'s exports; see ``docs/optimizers.md``).

The method classes are imported here, not by the package: ``kinecal.optimize.factor`` or
``kinecal.optimize.lm`` alone (the identifiability analysis, the LM of ``kinecal fk``'s
and ``kinecal handeye-images``' neighbours) loads none of them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize import METHODS as _METHODS
from kinecal.optimize._common import (
    Optimizer,
    as_int,
    check_bounds,
    drive,
    make_result,
    make_rng,
    seed_points,
)
from kinecal.optimize.afsa import AFSA, SAIAFSA
from kinecal.optimize.de import AdaptiveDE, ClassicDE
from kinecal.optimize.ga import SBXGA, ArithmeticGA
from kinecal.optimize.gwo import GWO, IGWO
from kinecal.optimize.gwo_de import DLHGWODE
from kinecal.optimize.pso import ConstrictionPSO, LinearInertiaPSO

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = [
    "METHODS",
    "_REGISTRY",
    "Optimizer",
    "check_bounds",
    "get_method",
    "make_result",
    "make_rng",
    "methods",
    "minimize",
    "register",
]

_REGISTRY: dict[str, type[Optimizer]] = {}


def register(name: str, cls: type[Optimizer]) -> None:
    """Make the ask/tell class ``cls`` available to :func:`minimize` as ``method=name``.

    Parameters
    ----------
    name : str
        Method name (lower case); an existing name is replaced.
    cls : type
        A subclass of :class:`kinecal.optimize._common.Optimizer`.
    """
    if not (isinstance(cls, type) and issubclass(cls, Optimizer)):
        raise TypeError(f"expected an Optimizer subclass, got {cls!r}")
    _REGISTRY[str(name).lower()] = cls


def methods() -> tuple[str, ...]:
    """Names of all registered methods (the built-in :data:`METHODS` first)."""
    return tuple(_REGISTRY)


def get_method(name: str) -> type[Optimizer]:
    """Return the optimizer class registered as ``name``.

    Raises
    ------
    kinecal.InputError
        (a ``ValueError``) naming the valid methods if ``name`` is unknown.
    """
    key = name.lower() if isinstance(name, str) else name
    if key not in _REGISTRY:
        raise InputError(
            f"unknown method {name!r}; valid methods: {', '.join(_REGISTRY)}", option="method"
        )
    return _REGISTRY[key]


for _cls in (
    SBXGA,
    ConstrictionPSO,
    AFSA,
    SAIAFSA,
    GWO,
    IGWO,
    DLHGWODE,
    AdaptiveDE,
    ArithmeticGA,
    LinearInertiaPSO,
    ClassicDE,
):
    register(_cls.name, _cls)

#: Built-in method names (also `kinecal.optimize.METHODS`, written out there).
METHODS: tuple[str, ...] = tuple(_REGISTRY)
if METHODS != _METHODS:
    raise ImportError(f"kinecal.optimize.METHODS {_METHODS} differs from the registry {METHODS}")


def minimize(
    fun: Callable[[np.ndarray], Any],
    bounds: Any,
    method: str = "pso",
    *,
    x0: Any = None,
    rng: int | np.random.Generator | None = None,
    maxiter: int | None = None,
    maxfev: int | None = None,
    target: float | None = None,
    vectorized: bool = True,
    callback: Callable[[OptimizeResult], Any] | None = None,
    options: Mapping[str, Any] | None = None,
) -> OptimizeResult:
    """Minimize ``fun`` over a box with a population metaheuristic.

    Parameters
    ----------
    fun : callable
        ``fun(X) -> f``, ``X`` of shape ``(P, n)`` (points in the bounds' units), ``f`` of shape
        ``(P,)``; with ``vectorized=False``, ``fun(x) -> float`` for one point ``x`` ``(n,)``.
        NaN costs count as ``+inf``.
    bounds : array_like, shape (n, 2)
        ``(low, high)`` per variable. The search runs in the unit hypercube mapped onto it.
    method : str
        One of :data:`METHODS` (or a name added with :func:`register`).
    x0 : array_like, shape (n,) or (k, n), optional
        Points seeded into the initial population (clipped into the bounds), e.g. an analytic or
        least-squares solution.
    rng : None, int or numpy.random.Generator
        Randomness (``np.random.default_rng(rng)``): the same seed gives bit-identical results.
    maxiter : int, optional
        Iteration budget (default: the method's paper setting); also the horizon of the
        schedules (PSO inertia, GWO ``a``).
    maxfev : int, optional
        Budget of evaluated points (checked after each batch).
    target : float, optional
        Stop as soon as the best cost is ``<= target``.
    vectorized : bool
        Whether ``fun`` takes a population (default) or one point.
    callback : callable, optional
        ``callback(intermediate_result)`` after each iteration, with ``x, fun, nit, nfev``;
        returning True (or raising ``StopIteration``) stops the run.
    options : mapping, optional
        Algorithm options by the paper's names (see each class and ``docs/optimizers.md``).

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x`` ``(n,)``, ``fun``, ``nit``, ``nfev``, ``success``, ``status`` (0 maxiter, 1 maxfev,
        2 target, 3 callback), ``message``, ``population`` ``(P, n)``, ``population_energies``
        ``(P,)``, ``history`` (best cost after each iteration, ``history[0]`` the initial best)
        and ``elapsed`` (s).

    Raises
    ------
    kinecal.InputError
        (a ``ValueError``) for an unknown method or option, malformed bounds, bad ``x0`` or
        budgets, or an objective returning the wrong shape.
    """
    start = time.perf_counter()
    cls = get_method(method)
    lo, hi = check_bounds(bounds)
    seeds = seed_points(x0, lo, hi)
    if maxfev is not None:
        maxfev = as_int("maxfev", maxfev, 1)
    if target is not None:
        try:
            target = float(target)
        except (TypeError, ValueError) as exc:
            raise InputError(f"expected a number, got {target!r}", option="target") from exc
    if callback is not None and not callable(callback):
        raise InputError("expected a callable", option="callback")
    if not callable(fun):
        raise InputError("expected a callable objective", option="fun")
    opt = cls(lo.size, rng=rng, x0=seeds, maxiter=maxiter, options=options)
    if vectorized:
        objective = fun
    else:

        def objective(X: np.ndarray) -> np.ndarray:
            return np.array([fun(x) for x in X], dtype=float)

    return drive(
        opt, objective, lo, hi, maxfev=maxfev, target=target, callback=callback, start=start
    )
