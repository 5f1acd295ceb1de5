"""Has a metaheuristic found the minimum? A local least-squares polish from its answer
(code ``optimizer-stalled``, docs/diagnostics.md).

``kinecal calibrate --method pso`` on the README's UR5 data stopped at a mean error of
2.806 mm and reported a 90 % improvement, where Levenberg-Marquardt reaches 0.0185 mm: the
swarm had stalled far from the minimum, and nothing said so. After every metaheuristic
(and hybrid) the result is polished by a few Levenberg-Marquardt iterations from the
metaheuristic's own answer; when the polished mean distance error is less than
1 / `STALL_FACTOR` of the metaheuristic's, the answer was not a minimum and the warning
gives both figures. The result itself stays the metaheuristic's (it is what was asked
for); ``--method lm`` gives the polished one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.diagnostics import warn
from kinecal.optimize.lsq import levenberg_marquardt

__all__ = ["POLISH_EVALUATIONS", "STALL_FACTOR", "check_local_polish"]

Array = NDArray[np.float64]

#: the metaheuristic's mean error above this many times the polished one: stalled (a
#: minimum of the mean distance is near one of the squared distance: within a few tens
#: of percent on noisy data, never a factor of two)
STALL_FACTOR = 2.0
#: residual evaluations of the polish (LM converges in well under 20 on calibrations)
POLISH_EVALUATIONS = 50


def check_local_polish(problem, x: Array, method: str, target: float | None = None
                       ) -> float | None:
    """``optimizer-stalled``: the mean distance error at `x` is more than `STALL_FACTOR`
    times what Levenberg-Marquardt reaches from `x`.

    Parameters
    ----------
    problem : CalibrationProblem
        The calibration problem the metaheuristic solved.
    x : ndarray, shape (n_free,)
        Its answer.
    method : str
        The method's name, for the message.
    target : float, optional
        The metaheuristic's target mean error: an answer within it stopped as asked and is
        not judged.

    Returns
    -------
    float or None
        The polished mean distance error (None when not judged).
    """
    mean = float(problem.distances(x).mean())
    if target is not None and mean <= target:
        return None
    try:
        res = levenberg_marquardt.fit(problem.residuals, problem.jacobian, np.asarray(x, float),
                                  max_nfev=POLISH_EVALUATIONS)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):  # no verdict, no noise
        return None
    polished = float(problem.distances(res.x).mean())
    if np.isfinite(polished) and mean > STALL_FACTOR * polished:
        unit = problem.model.length_unit
        other = "" if method.startswith("hybrid-") else " (or a hybrid-* method)"
        warn("optimizer-stalled",
             f"method {method} stopped at a mean error of {mean:.4g} {unit}, but a "
             f"Levenberg-Marquardt polish from its answer reaches {polished:.4g} {unit} "
             f"({mean / max(polished, np.finfo(float).tiny):.3g} times less): the "
             "metaheuristic stalled before the minimum and its improvement is not the "
             f"calibration's; use --method lm{other}, or give the metaheuristic more "
             "iterations")
    return polished
