"""Population optimizers behind one :func:`minimize` (see ``docs/optimizers.md``).

>>> import numpy as np
>>> from kinecal.optimize import minimize
>>> res = minimize(lambda X: np.sum((X - 0.3) ** 2, axis=1), [(-1, 1)] * 3, "pso", rng=0)
>>> bool(res.fun < 1e-8)
True

Methods (:data:`METHODS`): ``ga`` (Deb's SBX GA) and ``ga-hu2005`` (papers/000), ``pso``
(Clerc and Kennedy's constriction PSO) and ``pso-liu2008`` (papers/004), ``afsa`` and
``sa-iafsa`` (papers/002), ``gwo`` (Mirjalili 2014), ``igwo`` (Nadimi-Shahraki et al. 2021),
``dlh-gwo-de`` (papers/001), ``de`` (JADE, Zhang and Sanderson 2009) and ``de-storn1997``
(Storn and Price 1997). ``ga``, ``pso`` and ``de`` are the variants that search best at an
equal budget; the ``-<paper>`` variants keep the papers' algorithms and settings
(``benchmarks/bench_swarm.py``). More can be added with :func:`register`.

Least squares: ``kinecal.optimize.lsq`` (``householder_gauss_newton`` of papers/000 sec. 4.1,
``levenberg_marquardt``) on ``kinecal.optimize.lm`` (the LM core, ``solve_normal_equations``).

`minimize` and the registry live in `kinecal.optimize.search`, imported on first use: a
module of this package alone (``factor``, ``lm``) loads no metaheuristic.
"""

from __future__ import annotations

from kinecal._lazy import lazy_exports

#: Built-in method names, in the registry's order (`kinecal.optimize.search` checks it)
METHODS: tuple[str, ...] = ("ga", "pso", "afsa", "sa-iafsa", "gwo", "igwo", "dlh-gwo-de", "de",
                            "ga-hu2005", "pso-liu2008", "de-storn1997")

_LAZY = {name: "kinecal.optimize.search" for name in (
    "minimize", "register", "methods", "get_method", "_REGISTRY")}
_LAZY.update({name: "kinecal.optimize._common" for name in (
    "Optimizer", "check_bounds", "make_result", "make_rng")})

__all__ = ["METHODS", "Optimizer", "check_bounds", "get_method", "make_result", "make_rng",
           "methods", "minimize", "register"]

__getattr__, _dir = lazy_exports(__name__, _LAZY)


def __dir__() -> list[str]:
    return sorted(__all__)
