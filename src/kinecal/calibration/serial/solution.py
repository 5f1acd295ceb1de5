"""What a serial-arm calibration knows at its solution: the covariance of the free
parameters on their identifiable subspace (`solution_uncertainty`, the stack's own
`kinecal.calibration.uncertainty.arm_uncertainty` on the serial problem's normal matrix)
and the identifiability report of an explicit free set redone there
(`solution_report`). Used by `kinecal.calibration.serial.api`."""

from __future__ import annotations

import dataclasses

import numpy as np

from kinecal.calibration.identifiability import analyse_factor
from kinecal.calibration.serial.problem import CalibrationProblem, column_scale
from kinecal.calibration.uncertainty import Uncertainty, arm_uncertainty
from kinecal.optimize.factor import gram_root

__all__ = ["solution_report", "solution_uncertainty"]


def solution_uncertainty(problem: CalibrationProblem, x: np.ndarray, outliers: list[int],
                 unique_rows: np.ndarray | None, normal: np.ndarray | None, rss: float,
                 rank: int, positions: np.ndarray | None = None) -> Uncertainty:
    """Covariance of the free parameters at `x` on their identifiable subspace.

    The rows entering it: every pose but the robust loss' outliers, and of exact copies of a
    row only the first (a copied row adds no information; counting it would shrink the
    standard errors by the square root of the number of copies). `normal` and `rss`:
    ``J^T W J`` and the weighted RSS at `x` when the solver already has them for all poses
    (LM); otherwise one chunked pass over the kept poses. `positions`: the model's tool
    points at `x` when known.
    """
    k = problem.n_free
    n = len(problem.data)
    keep = None
    if outliers or unique_rows is not None:
        keep = np.arange(n) if unique_rows is None else np.asarray(unique_rows)
        keep = np.setdiff1d(keep, outliers)
    if normal is None or keep is not None:
        G = problem.gram(x, keep=keep)
        normal, rss = G[:k, :k], G[k, k]
    n_rows = problem.rows * (n if keep is None else len(keep))
    P = problem.errors(x) + problem.xyz if positions is None else positions
    scale = column_scale(problem.model, problem.data, problem.free, positions=P)
    return arm_uncertainty(normal, rss, n_rows, k, rank, scale)  # the stack's covariance


def solution_report(problem: CalibrationProblem, x: np.ndarray, report, normal, tol: float):
    """The identifiability report of an explicit free set, redone at the solution `x`.

    Identifiability is local (large angle errors can separate parameters that are
    confounded at nominal); the uncertainty and the words "not identifiable" must describe
    the fit actually made.
    """
    k = problem.n_free
    if normal is None:
        normal = problem.gram(x)[:k, :k]
    P = problem.errors(x) + problem.xyz
    sub = analyse_factor(gram_root(normal), problem.free, problem.rows * len(problem.data),
                         tol=tol, scale=column_scale(problem.model, problem.data, problem.free,
                                                     positions=P))
    return dataclasses.replace(
        report, rank=sub.rank, identifiable=sub.identifiable, unidentifiable=sub.unidentifiable,
        confounded_with=sub.confounded_with, condition_number=sub.condition_number,
        singular_values=sub.singular_values, observability=sub.observability)
