"""Shared machinery of the population optimizers: bounds, scaling, rng, driver, result.

Every algorithm of :mod:`kinecal.optimize` is a small :class:`Optimizer` subclass working in
the unit hypercube ``[0, 1]^n``. It proposes points with :meth:`Optimizer.ask` and receives
their costs with :meth:`Optimizer.tell`. :func:`drive` maps the points to the user's bounds,
evaluates the whole batch in one call of the objective and handles the budgets
(``maxiter``, ``maxfev``), the ``target`` cost, the ``history``, the ``callback``, the timing
and the :class:`scipy.optimize.OptimizeResult`. Least-squares solvers (``optimize/lsq.py``)
reuse :func:`make_result` and :func:`make_rng` so that every solver returns the same type.
The box and argument helpers live in :mod:`kinecal.optimize._box` and are re-exported here.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, Iterable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from kinecal.errors import InputError
from kinecal.optimize._box import (
    RngLike,
    as_int,
    as_positive,
    as_probability,
    check_bounds,
    clip_unit,
    distinct_others,
    from_unit,
    make_rng,
    seed_points,
    to_unit,
)

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = [
    "STATUS_MESSAGES",
    "FitResult",
    "Optimizer",
    "RngLike",
    "as_int",
    "as_positive",
    "as_probability",
    "check_bounds",
    "clip_unit",
    "distinct_others",
    "drive",
    "fit_result",
    "from_unit",
    "make_result",
    "make_rng",
    "seed_points",
    "to_unit",
]

#: ``status`` codes of :func:`drive` and their messages.
STATUS_MESSAGES = {
    0: "maximum number of iterations reached",
    1: "maximum number of function evaluations reached",
    2: "target cost reached",
    3: "stopped by the callback",
}


class Optimizer:
    """Base class of an ask/tell population optimizer in the unit hypercube.

    A subclass defines ``name``, ``defaults`` (option name -> default, the paper's names and
    values), ``default_maxiter`` and the generator :meth:`_steps`, which yields batches of unit-cube
    points ``(P, n)`` and receives their costs ``(P,)``; it increments ``self.nit`` when an
    iteration is complete and keeps ``self.population`` / ``self.energies`` current.

    Parameters
    ----------
    n : int
        Number of variables.
    rng : None, int or numpy.random.Generator
        Source of randomness (``np.random.default_rng(rng)``); the only one used.
    x0 : numpy.ndarray, shape (k, n), optional
        Seed points in the unit cube, placed in the initial population (at most its size).
    maxiter : int, optional
        Iteration budget, also the horizon of schedules (PSO inertia, GWO ``a``).
    options : mapping, optional
        Algorithm options by name; unknown names raise :class:`InputError` (a ``ValueError``).
    """

    name: ClassVar[str] = ""
    defaults: ClassVar[dict[str, Any]] = {}
    default_maxiter: ClassVar[int] = 100

    def __init__(
        self,
        n: int,
        *,
        rng: RngLike = None,
        x0: np.ndarray | None = None,
        maxiter: int | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        self.n = as_int("n", n, 1)
        self.rng = make_rng(rng)
        self.x0 = None if x0 is None else np.atleast_2d(np.asarray(x0, dtype=float))
        self.maxiter = self.default_maxiter if maxiter is None else as_int("maxiter", maxiter, 0)
        opts = dict(options or {})
        unknown = sorted(set(opts) - set(self.defaults))
        if unknown:
            valid = ", ".join(sorted(self.defaults)) or "none"
            raise InputError(
                f"unknown option(s) {', '.join(map(repr, unknown))} for method "
                f"{self.name!r}; valid options: {valid}",
                option="options",
            )
        self.options = {**self.defaults, **opts}
        self._configure(self.options)
        self.nit = 0
        self.best_x = np.full(self.n, np.nan)
        self.best_f = np.inf
        self.population = np.empty((0, self.n))
        self.energies = np.empty(0)
        self._gen = self._steps()
        self._pending = next(self._gen)

    # -- to be provided by subclasses --------------------------------------------------------
    def _configure(self, options: dict[str, Any]) -> None:
        """Validate the options and store them as attributes."""

    def _steps(self) -> Generator[np.ndarray, np.ndarray, None]:
        """Yield point batches ``(P, n)``, receive costs ``(P,)`` (implemented by subclasses)."""
        raise NotImplementedError
        yield np.empty((0, self.n))  # pragma: no cover

    # -- ask / tell ----------------------------------------------------------------------------
    def ask(self) -> np.ndarray:
        """Return the next batch of points to evaluate, shape ``(P, n)``, in the unit cube."""
        return self._pending

    def tell(self, X: np.ndarray, f: np.ndarray) -> None:
        """Report the costs ``f`` (shape ``(P,)``) of the batch ``X`` returned by :meth:`ask`."""
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_f = float(f[i])
            self.best_x = X[i].copy()
        self._pending = self._gen.send(f)

    def initial_population(self, size: int) -> np.ndarray:
        """Uniform random ``(size, n)`` points with the seed points ``x0`` in the first rows."""
        U = self.rng.random((size, self.n))
        if self.x0 is not None:
            k = min(size, self.x0.shape[0])
            U[:k] = self.x0[:k]
        return U


class FitResult(dict):
    """A solver's outcome with the fields and behaviour of `scipy.optimize.OptimizeResult`
    (a dict whose keys read and write as attributes), built without importing
    scipy.optimize: that import costs 0.13-0.17 s, a quarter of a ``kinecal calibrate``
    command. kinecal's own paths (the LM path of `calibrate`) carry this; the public
    solvers return scipy's class (`make_result`).
    """

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError as exc:
            raise AttributeError(name) from exc

    __setattr__ = dict.__setitem__  # type: ignore[assignment]
    __delattr__ = dict.__delitem__  # type: ignore[assignment]

    def __dir__(self) -> list[str]:
        return list(self.keys())


def fit_result(
    x: np.ndarray,
    fun: float,
    *,
    nit: int,
    nfev: int,
    success: bool,
    status: int,
    message: str,
    history: Iterable[float] = (),
    elapsed: float = 0.0,
    **extra: Any,
) -> FitResult:
    """The `FitResult` of a solver (parameters as `make_result`)."""
    return FitResult(
        x=np.asarray(x, dtype=float),
        fun=float(fun),
        nit=int(nit),
        nfev=int(nfev),
        success=bool(success),
        status=int(status),
        message=str(message),
        history=[float(h) for h in history],
        elapsed=float(elapsed),
        **extra,
    )


def make_result(
    x: np.ndarray,
    fun: float,
    *,
    nit: int,
    nfev: int,
    success: bool,
    status: int,
    message: str,
    history: Iterable[float] = (),
    elapsed: float = 0.0,
    **extra: Any,
) -> OptimizeResult:
    """Build the :class:`scipy.optimize.OptimizeResult` every kinecal solver returns.

    Parameters
    ----------
    x : numpy.ndarray, shape (n,)
        Best point, in the problem's units.
    fun : float
        Its cost.
    nit, nfev : int
        Iterations and objective evaluations (points evaluated).
    success, status, message
        Outcome (``status`` codes in :data:`STATUS_MESSAGES` for the metaheuristics).
    history : iterable of float
        Best cost after each iteration, ``history[0]`` the initial best.
    elapsed : float
        Wall time in seconds.
    **extra
        Further fields (``population``, ``population_energies``, ``jac``, ...).
    """
    from scipy.optimize import OptimizeResult  # 0.1-0.2 s: only once a solver returns

    return OptimizeResult(fit_result(x, fun, nit=nit, nfev=nfev, success=success,
                                     status=status, message=message, history=history,
                                     elapsed=elapsed, **extra))


def _evaluate(fun: Callable[[np.ndarray], Any], X: np.ndarray) -> np.ndarray:
    f = np.asarray(fun(X), dtype=float)
    if f.shape != (X.shape[0],):
        if f.size != X.shape[0]:
            raise InputError(
                f"the objective must return one cost per row, shape ({X.shape[0]},), "
                f"got shape {f.shape}",
                option="fun",
            )
        f = f.reshape(X.shape[0])
    if np.isnan(np.add.reduce(f)):  # one cheap test; NaN (or inf - inf) -> look closer
        f = np.where(np.isnan(f), np.inf, f)
    return f


def drive(
    opt: Optimizer,
    fun: Callable[[np.ndarray], Any],
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    maxfev: int | None = None,
    target: float | None = None,
    callback: Callable[[OptimizeResult], Any] | None = None,
    start: float | None = None,
) -> OptimizeResult:
    """Run ``opt`` on the vectorized objective ``fun`` over the box ``[lo, hi]``.

    Parameters
    ----------
    opt : Optimizer
        A fresh optimizer; its ``maxiter`` is the iteration budget.
    fun : callable
        ``fun(X) -> f`` with ``X`` of shape ``(P, n)`` in the box's units, ``f`` of shape ``(P,)``;
        NaN costs count as ``+inf``.
    lo, hi : numpy.ndarray, shape (n,)
        The box.
    maxfev : int, optional
        Stop once this many points were evaluated (checked after each batch, so the last batch
        may pass it).
    target : float, optional
        Stop as soon as the best cost is ``<= target`` (checked after every batch).
    callback : callable, optional
        Called after each iteration with an ``OptimizeResult`` (``x, fun, nit, nfev``); returning
        True or raising ``StopIteration`` stops the run.
    start : float, optional
        ``time.perf_counter()`` at the start of the run (default: now).

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x, fun, nit, nfev, success, status, message, population`` (``(P, n)``, box units),
        ``population_energies`` (``(P,)``), ``history`` (best cost after each iteration,
        ``len(history) == nit + 1``) and ``elapsed`` (s). ``success`` is True when ``target`` was
        reached, or, without ``target``, when a finite cost was found.
    """
    t0 = time.perf_counter() if start is None else start
    span = hi - lo
    history: list[float] = []
    nfev = 0
    status = 0
    done_iters = 0
    partial = False  # batches told since the last completed iteration
    maxiter = opt.maxiter
    while True:
        U = opt.ask()
        f = _evaluate(fun, lo + U * span)
        nfev += f.shape[0]
        opt.tell(U, f)
        best = opt.best_f
        if not history:
            history.append(best)
            done_iters = opt.nit
        elif opt.nit > done_iters:
            done_iters = opt.nit
            partial = False
            history.append(best)
            if callback is not None:
                from scipy.optimize import OptimizeResult

                info = OptimizeResult(x=lo + opt.best_x * span, fun=best, nit=done_iters, nfev=nfev)
                try:
                    stop = callback(info)
                except StopIteration:
                    stop = True
                if stop is True:
                    status = 3
                    break
        else:
            partial = True
        if target is not None and best <= target:
            status = 2
            break
        if maxfev is not None and nfev >= maxfev:
            status = 1
            break
        if done_iters >= maxiter and not partial:
            status = 0
            break
    if partial:
        history.append(best)  # stopped inside an iteration: it counts as one
    nit = len(history) - 1
    if target is not None:
        success = bool(opt.best_f <= target)
    else:
        success = bool(np.isfinite(opt.best_f))
    return make_result(
        lo + opt.best_x * span,
        opt.best_f,
        nit=nit,
        nfev=nfev,
        success=success,
        status=status,
        message=STATUS_MESSAGES[status],
        history=history,
        elapsed=time.perf_counter() - t0,
        population=lo + opt.population * span,
        population_energies=opt.energies.copy(),
    )
