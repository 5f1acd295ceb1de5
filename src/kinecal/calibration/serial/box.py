"""The search box of a metaheuristic calibration, and the check that its answer is inside.

A metaheuristic (``calibrate --method pso|de|ga|...``) searches a box of parameter values.
Two boxes (the method option ``box``; ``--box`` on the command line):

``data`` (the default)
    Derived from the measurements: a Levenberg-Marquardt fit on the same free parameters
    from nominal, then a box centred there, `SE_WIDTH` standard errors of each parameter
    to either side, at least `FLOOR` of the model file's tolerance and at most that
    tolerance. The box holds the data's minimum whatever the arm's errors, and is narrow
    where the data determine a parameter well.
``tolerances``
    The model file's tolerance box around the nominal values (``tolerances: {length,
    angle}``): the setting of the papers (Hu, Xiao and Li 2005, sec. 4.2; Zhao and Yang),
    which `kinecal reproduce` keeps. An arm whose errors exceed the tolerances has its
    minimum outside this box: on the real UR5 data LM moves alpha3 by 0.66 deg against a
    0.5 deg tolerance, and DE, PSO and GA then end on the box's face at 0.28-0.36 mm where
    LM reaches 0.101 mm.

After the search, `check_at_bounds` warns ``at-bounds`` when the answer sits on a face of
the box it searched (docs/diagnostics.md): the minimum may lie beyond it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.problem import CalibrationProblem, column_scale
from kinecal.calibration.uncertainty import subspace_uncertainty
from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.optimize.hybrid import HYBRID_PREFIX, hybrid_minimize
from kinecal.optimize.lsq import levenberg_marquardt

__all__ = ["AT_BOUNDS", "BOXES", "FLOOR", "SE_WIDTH", "box_choice", "check_at_bounds",
           "run_metaheuristic", "search_box"]

Array = NDArray[np.float64]

#: the boxes a metaheuristic calibration can search (module docstring)
BOXES = ("data", "tolerances")
#: half-width of the data box in standard errors of the LM fit: the minimum of the mean
#: distance error (the metaheuristics' cost) lies within a few standard errors of the
#: least-squares one
SE_WIDTH = 10.0
#: smallest half-width of the data box, as a fraction of the tolerance (noise-free data
#: have standard errors at round-off)
FLOOR = 1e-3
#: an answer within this fraction of the box's width from a face sits on it
AT_BOUNDS = 1e-3


def box_choice(options: dict[str, Any], method: str) -> str:
    """The ``box`` option of a plain metaheuristic's `options` (removed from them),
    checked; default ``data``. A hybrid searches its own box (``hybrid``)."""
    if method.startswith("hybrid-"):
        if "box" in options:
            raise InputError("box applies to the plain metaheuristics: a hybrid searches a "
                             "box shrunk around its least-squares solution (option shrink)",
                             option="--box")
        return "hybrid"
    box = options.pop("box", "data")
    if box not in BOXES:
        raise InputError(f"box: expected one of {', '.join(BOXES)}, got {box!r}",
                         option="--box")
    return box


def search_box(problem: CalibrationProblem, box: str) -> tuple[Array, dict[str, Any]]:
    """The search box ``(n_free, 2)`` and what it is (module docstring).

    Returns
    -------
    bounds : ndarray, shape (n_free, 2)
    info : dict
        ``{"box": "data" | "tolerances", "center": (n_free,), "half_width": (n_free,)}``;
        for ``data`` also ``"lm_nfev"`` (evaluations of the fit the box is centred on).
    """
    tol = np.asarray(problem.half_width, dtype=float)
    if box == "tolerances":
        bounds = problem.bounds()
        return bounds, {"box": box, "center": problem.x0.copy(), "half_width": tol.copy()}
    res = levenberg_marquardt.fit(problem.residuals, problem.jacobian, problem.x0,
                              normal_equations=problem.normal_equations)
    x = np.asarray(res.x, dtype=float)
    n_rows = problem.rows * len(problem.data)
    scale = column_scale(problem.model, problem.data, problem.free,
                         positions=problem.errors(x) + problem.xyz)
    unc = subspace_uncertainty(res.normal_matrix, 2.0 * float(res.fun), n_rows,
                               problem.n_free, scale)
    se = np.sqrt(np.clip(np.diag(unc.covariance), 0.0, None))
    se = np.where(np.isfinite(se), se, np.inf)
    half = np.clip(SE_WIDTH * se, FLOOR * tol, tol)
    bounds = np.column_stack([x - half, x + half])
    return bounds, {"box": box, "center": x, "half_width": half, "lm_nfev": int(res.nfev)}


def run_metaheuristic(problem: CalibrationProblem, method: str, options: dict[str, Any], *,
                      rng, maxiter: int | None, target: float | None, callback,
                      monitor) -> Any:
    """Run the metaheuristic (or ``hybrid-*``) `method` on `problem` in its box.

    `options` are the method's (the ``box`` and a hybrid's ``shrink``, ``least_squares``,
    ``ls_maxiter``, ``seed_ls`` taken out of them). Returns the solver's
    ``OptimizeResult`` with ``search_box = {"box", "lower", "upper"}`` (lists per free
    parameter) and, for the data box, the LM fit's evaluations counted in ``nfev``.
    """
    box = box_choice(options, method)
    if method.startswith(HYBRID_PREFIX):
        hopts = {k: options.pop(k) for k in ("shrink", "least_squares", "ls_maxiter", "seed_ls")
                 if k in options}
        res = hybrid_minimize(problem.population_cost, problem.residuals, problem.jacobian,
                              problem.x0, problem.half_width, method[len(HYBRID_PREFIX):],
                              rng=rng, maxiter=maxiter, target=target, callback=callback,
                              options=options or None, monitor=monitor, **hopts)
        bounds = res.bounds
    else:
        from kinecal.optimize import minimize  # the metaheuristics, only when one runs

        bounds, info = search_box(problem, box)
        res = minimize(problem.population_cost, bounds, method, rng=rng, maxiter=maxiter,
                       target=target, callback=callback, options=options or None)
        res.nfev += info.get("lm_nfev", 0)
    res.search_box = {"box": box, "lower": bounds[:, 0].tolist(),
                      "upper": bounds[:, 1].tolist()}
    return res


def check_at_bounds(problem: CalibrationProblem, x: Array, search: dict[str, Any],
                    method: str) -> list[str]:
    """``at-bounds``: the free parameters of the answer `x` that sit on a face of the box
    searched (`run_metaheuristic`'s ``search_box``: ``box``, ``lower``, ``upper``), within
    `AT_BOUNDS` of its width. Returns their names (warned once, all of them)."""
    x = np.asarray(x, dtype=float)
    lo, hi = np.asarray(search["lower"], float), np.asarray(search["upper"], float)
    box = search["box"]
    near = AT_BOUNDS * (hi - lo)
    low, high = x <= lo + near, x >= hi - near
    names = [n for n, on in zip(problem.free, low | high, strict=True) if on]
    if not names:
        return []
    shown = ", ".join(f"{n} ({'lower' if lw else 'upper'} face)" for n, lw, hg in
                      zip(problem.free, low, high, strict=True) if lw or hg)
    if box == "tolerances":
        what = ("the model file's tolerance box around nominal; the arm's errors may exceed "
                "its tolerances: search the box derived from the data (--box data, the "
                "default), or use --method lm")
    elif method.startswith("hybrid-"):
        what = ("the hybrid's box shrunk around its least-squares solution; widen it (option "
                "shrink) or use --method lm")
    else:
        what = None
    if what is None:  # the data box holds the least-squares minimum at its centre
        warn("at-bounds",
             f"method {method} ended on the face of its search box for {len(names)} of "
             f"{len(problem.free)} free parameters: {shown}; the box is centred on the "
             f"Levenberg-Marquardt fit, {SE_WIDTH:g} standard errors to either side, so the "
             "search stalled on its face: give it more iterations, or use --method lm")
        return names
    warn("at-bounds",
         f"method {method} ended on the face of its search box for {len(names)} of "
         f"{len(problem.free)} free parameters: {shown}; the minimum may lie outside {what}")
    return names
