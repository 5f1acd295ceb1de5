"""The robust start of the Levenberg-Marquardt path: outlier poses left out of the decisions.

One bad pose (a joint read a few degrees off, a reflector not seated) inflates the
residual of a least-squares fit; every decision that tests a reduction of the residual
against its size then goes wrong: the growth of the free set at the identified geometry
(`kinecal.calibration.serial.solve.grow_identifiable`, an F-test) keeps parameters held
that the good poses determine, and the fit of the good poses stays worse than without
the bad one. So, after the first fit on the free set chosen at nominal:

1. the poses are judged by the outlier rule of the ``outliers`` check (studentized
   distance errors, a pose measured at several markers pooled as one observation:
   `kinecal.calibration.diagnostics.observations`);
2. the flagged poses are left out and the fit repeated on the others; every pose is then
   judged again at that fit (a left-out pose by its prediction error, studentized by
   ``sqrt(1 + h)``), until the flagged set repeats (at most `MAX_ROUNDS` fits);
3. the rank and the free set are decided on the inliers; the final fit (a least-squares
   fit of every pose with ``loss="linear"``, or a robust fit with the outliers left out)
   starts from the inliers' solution.

Clean data flag nothing at step 1 and take exactly the path they took before.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics.fit import ROUND_OFF, pose_leverage
from kinecal.calibration.diagnostics.observations import pose_outliers
from kinecal.calibration.diagnostics.sizes import serial_size
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.data import Measurements
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["MAX_ROUNDS", "Inliers", "judge_poses", "merge_runs", "robust_fit",
           "robust_start"]

#: fits on the inliers at most (the flagged set usually repeats after the first)
MAX_ROUNDS = 3


@dataclass
class Inliers:
    """What `robust_start` found.

    Attributes
    ----------
    problem : CalibrationProblem
        The problem on the kept rows (the given problem when nothing was flagged).
    result : OptimizeResult
        The fit on the kept rows.
    outliers : list of int
        Rows left out (every row of a flagged pose), 0-based.
    keep : ndarray of int or None
        Rows kept (None: all).
    """

    problem: CalibrationProblem
    result: OptimizeResult
    outliers: list[int] = field(default_factory=list)
    keep: NDArray[np.intp] | None = None


def merge_runs(first: OptimizeResult, then: OptimizeResult) -> OptimizeResult:
    """`then` with the iteration counts, time and history of both runs."""
    then.nfev += first.nfev
    then.njev = getattr(then, "njev", 0) + getattr(first, "njev", 0)
    then.nit += first.nit
    then.history = list(first.history) + list(then.history[1:])
    if hasattr(first, "elapsed") and hasattr(then, "elapsed"):
        then.elapsed += first.elapsed
    return then


def judge_poses(problem: CalibrationProblem, x: NDArray[np.float64],
                poses: tuple[NDArray[np.intp], int] | None, normal: NDArray[np.float64],
                kept: NDArray[np.bool_] | None = None,
                residual: NDArray[np.float64] | None = None) -> list[int]:
    """Rows of the outlier poses at `x` (every row of `problem`).

    `normal` is the ``J^T W J`` of the fit at `x`; `kept` marks its rows (None: all).
    Errors of fitted rows are studentized by ``sqrt(1 - h)``, of left-out rows by
    ``sqrt(1 + h)`` (the variance of a prediction); `poses` pools the rows of one pose
    (`kinecal.calibration.diagnostics.observations.pose_groups`; None: a pose per row);
    `residual`: `problem`'s residual vector at `x` when known (saves a pass).
    """
    d = (problem.distances(x) if residual is None
         else problem.distances_from_residuals(residual))
    if not d.size or d.max() <= ROUND_OFF * serial_size(problem.model):
        return []
    h = pose_leverage(problem, x, normal)
    if kept is None:
        s = np.sqrt(np.maximum(1.0 - h, 1e-3))
    else:
        s = np.where(kept, np.sqrt(np.maximum(1.0 - h, 1e-3)), np.sqrt(1.0 + h))
    group, n = poses if poses is not None else (None, None)
    return pose_outliers(d / s, group, n)


def _subset(problem: CalibrationProblem, keep: NDArray[np.intp]) -> CalibrationProblem:
    data: Measurements = problem.data.subset(keep)
    rw = problem.rotation_weight if problem.R_meas is not None else None
    return CalibrationProblem(problem.model, data, problem.free, rw)


def robust_start(problem: CalibrationProblem, res: OptimizeResult,
                 poses: tuple[NDArray[np.intp], int] | None, ftol: float | None
                 ) -> Inliers:
    """Judge the poses at the first fit `res` of `problem` and refit on the inliers
    (module docstring, steps 1 and 2).

    Parameters
    ----------
    problem : CalibrationProblem
        Every row, the free set chosen at nominal.
    res : OptimizeResult
        Its first fit (with ``normal_matrix``).
    poses : (ndarray, int) or None
        Pose of each row and the number of poses (None: one row per pose).
    ftol : float or None
        Relative cost reduction at which the inliers' fits stop (None: converged).

    Returns
    -------
    Inliers
    """
    n = len(problem.data)
    flagged = judge_poses(problem, res.x, poses, res.normal_matrix, residual=res.residual)
    if not flagged:
        return Inliers(problem, res)
    sub, fit, done = problem, res, []
    for _ in range(MAX_ROUNDS):
        keep = np.setdiff1d(np.arange(n), flagged)
        if problem.rows * keep.size <= 2 * problem.n_free:  # too few left to judge by
            break
        sub = _subset(problem, keep)
        fit = merge_runs(fit, levenberg_marquardt.fit(
            sub.residuals, sub.jacobian, fit.x, monitor=sub.mean_distance_from_residuals,
            normal_equations=sub.normal_equations, ftol=ftol))
        done = flagged
        mask = np.zeros(n, dtype=bool)
        mask[keep] = True
        again = judge_poses(problem, fit.x, poses, fit.normal_matrix, mask)
        if not again:  # the poses flagged fit as well as the others at the inliers' fit
            return Inliers(problem, res)
        if again == flagged:
            break
        flagged = again
    if not done:
        return Inliers(problem, res)
    return Inliers(sub, fit, list(done), np.setdiff1d(np.arange(n), done))


def robust_fit(problem: CalibrationProblem, x: NDArray[np.float64],
               poses: tuple[NDArray[np.intp], int] | None, loss: str, f_scale: float | None,
               first: OptimizeResult) -> tuple[OptimizeResult, list[int]]:
    """The robust fit of every row from `x` (the inliers' solution, whose run `first` it
    continues), then, when poses are flagged, the same loss on the others (module
    docstring, step 3; down-weighted, a bad pose still pulls the fit).

    `f_scale` (length unit) defaults to 3 times the median distance error at `x`.
    Returns the last fit and the flagged rows.
    """
    d = problem.distances(x)
    scale = f_scale if f_scale is not None else 3.0 * max(float(np.median(d)), 1e-12)
    res = merge_runs(first, levenberg_marquardt.fit(
        problem.residuals, problem.jacobian, x, loss=loss, f_scale=scale,
        monitor=problem.mean_distance_from_residuals))
    d = problem.distances(res.x)
    if not d.size or d.max() <= ROUND_OFF * serial_size(problem.model):
        return res, []
    group, n = poses if poses is not None else (None, None)
    flagged = pose_outliers(d, group, n)
    keep = np.setdiff1d(np.arange(len(d)), flagged)
    if not flagged or problem.rows * keep.size <= 2 * problem.n_free:
        return res, flagged
    sub = _subset(problem, keep)
    res = merge_runs(res, levenberg_marquardt.fit(
        sub.residuals, sub.jacobian, res.x, loss=loss, f_scale=scale,
        monitor=sub.mean_distance_from_residuals))
    return res, flagged
