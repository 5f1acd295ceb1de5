"""The free set of a stacked problem, decided as `calibrate_blocks` decides it: the rank at
the nominal geometry (each block's unknowns fitted to its data), the fit with the noise of
each block estimated, outlier observations left out of the decisions, the parameters that
became identifiable at the solution freed when the fit improves significantly, and the
identifiability of the free set at the solution.

`calibrate_blocks` and ``kinecal identifiability --data A.csv --data B.csv``
(`kinecal.calibration.blocks.plan.analyse_kinds`) both run `solve_blocks`: what the
analysis of a mix says is identifiable is what its calibration frees.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.analysis import StackAnalysis, analyse_stack, report_for
from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.floors import set_sigma_floors
from kinecal.calibration.blocks.solve import StackFit, fit_stack
from kinecal.calibration.blocks.stack import StackedProblem, fit_nuisance
from kinecal.calibration.blocks.weights import initial_sigma
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["StackSolution", "solve_blocks", "start_blocks"]

Array = NDArray[np.float64]


def start_blocks(model: SerialModel, blocks: Sequence[ResidualBlock], params: np.ndarray
                 ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each block's unknowns fitted to its data with the arm at `params`, and its
    residuals there."""
    nuis, res = [], []
    for b in blocks:
        v, r = fit_nuisance(b, model, params, b.start(model, params), b.stated_sigma())
        nuis.append(v)
        res.append(r)
    return nuis, res


@dataclass
class StackSolution:
    """What `solve_blocks` found.

    Attributes
    ----------
    fit : StackFit
        The fit (its problem holds the free set and the noise per block).
    analysis : StackAnalysis
        Identifiability at the solution; its ``report`` is that of the free set (held
        candidates unidentifiable).
    start : StackAnalysis
        Identifiability of the candidates at the nominal geometry.
    before : list of ndarray
        Each block's error per observation at nominal (its unknowns fitted).
    final : StackedProblem
        The problem with every candidate free at the solution (what `analysis` analysed;
        the identifiability per chain of a robot system analyses it again).
    """

    fit: StackFit
    analysis: StackAnalysis
    start: StackAnalysis
    before: list[Array]
    final: StackedProblem | None = None


def solve_blocks(model: SerialModel, blocks: Sequence[ResidualBlock], candidates: list[str],
                 choose: bool, *, rank_tol: float, loss: str = "linear",
                 f_scale: float | None = None,
                 check: Callable[[list, list, StackAnalysis, list[str]], None] | None = None,
                 ) -> StackSolution:
    """Decide the free set and fit (module docstring).

    Parameters
    ----------
    model : SerialModel
        With the markers the blocks use.
    blocks : sequence of ResidualBlock
    candidates : list of str
        The parameters analysed.
    choose : bool
        Free their identifiable subset (and grow it at the solution); else all of them.
    rank_tol : float
        Relative rank threshold.
    loss, f_scale
        As in `kinecal.calibration.blocks.calibrate_blocks`.
    check : callable, optional
        ``check(nuisance, before, start_analysis, names)`` before the fit (the data checks).
    """
    p0 = model.nominal
    nuis0, r0 = start_blocks(model, blocks, p0)
    before = [b.observation_errors(r) for b, r in zip(blocks, r0, strict=True)]
    sig0, known = initial_sigma(blocks)
    start = StackedProblem(model, blocks, candidates, sig0)
    ana0 = analyse_stack(start, start.pack(p0, nuis0), rank_tol, check=True)
    names = list(ana0.report.identifiable if choose else candidates)
    if check is not None:
        check(nuis0, before, ana0, names)
    fit = fit_stack(model, blocks, names, candidates, p0, nuis0, sig0, known, tol=rank_tol,
                    grow=choose, loss=loss, f_scale=f_scale)
    if set_sigma_floors(fit.problem, fit.result.x):  # tracker rows weighted by their s
        x = fit.result.x
        fit = fit_stack(model, blocks, list(fit.problem.free), candidates,
                        fit.problem.params(x), fit.problem.nuisance(x), sig0, known,
                        tol=rank_tol, grow=False, loss=loss, f_scale=f_scale)
    prob, x = fit.problem, np.asarray(fit.result.x, dtype=float)
    params, nuis = prob.params(x), prob.nuisance(x)
    final = StackedProblem(model, blocks, candidates, prob.sigma, params)
    final.exclude(prob.excluded)
    ana = analyse_stack(final, final.pack(params, nuis), rank_tol)
    ana.report = report_for(ana, prob.free, rank_tol)
    return StackSolution(fit, ana, ana0, before, final)
