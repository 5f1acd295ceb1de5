"""`calibrate_blocks`: identify a serial arm from measurement sets of any kinds at once.

Steps: blocks from the data (`make`), each block's unknowns started from the data at the
nominal geometry (`fit_nuisance`: the "before" state), data checks per kind, the
identifiability of the arm on the stack with the mix's blind motions removed
(`analysis`), the fit with the noise of each block stated or estimated (`solve`),
uncertainty on the identifiable subspace with every unknown marginalised, plausibility
checks per kind, before/after statistics per set and on validation sets of any kind.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from kinecal import diagnostics
from kinecal._blas import small_products
from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.checks import (
    check_block_data,
    check_blocks,
    check_fits,
    check_stack_rows,
    check_stack_unknowns,
    check_validation_overlap,
)
from kinecal.calibration.blocks.decide import solve_blocks, start_blocks
from kinecal.calibration.blocks.make import DataSet, make_blocks, marker_names
from kinecal.calibration.blocks.motions import unseen_words
from kinecal.calibration.blocks.prior import stack_prior
from kinecal.calibration.blocks.result import KindsCalibrationResult, kind_entry
from kinecal.calibration.blocks.system_ident import system_identifiability
from kinecal.calibration.blocks.tips import by_tip
from kinecal.calibration.blocks.uncertainty import stack_uncertainty
from kinecal.calibration.diagnostics.change import check_change
from kinecal.calibration.diagnostics.fit import (
    check_parameter_tolerance,
    check_unidentifiable_free,
)
from kinecal.calibration.serial.prior import prior_spec, prior_state
from kinecal.calibration.serial.prior_fit import prior_entry
from kinecal.calibration.serial.problem import candidate_names
from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import model_for_markers
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.tree.system import SystemModel, is_system
from kinecal.optimize.lsq import LOSSES

__all__ = ["BLOCK_METHODS", "RANK_TOL", "calibrate_blocks", "calibrate_system",
           "validation_errors"]

#: solvers of the stacked problem
BLOCK_METHODS = ("lm",)
#: rank threshold of free="identifiable": the serial calibration's (CALIBRATION_RANK_TOL)
RANK_TOL = 1e-4


@small_products
def calibrate_blocks(
    model: SerialModel,
    data: Sequence[DataSet],
    *,
    sigma: Sequence[float | None] | None = None,
    validate: Sequence[DataSet] | None = None,
    validate_sigma: Sequence[float | None] | None = None,
    method: str = "lm",
    free: str | Sequence[str] = "identifiable",
    loss: str = "linear",
    f_scale: float | None = None,
    rank_tol: float = RANK_TOL,
    rotation_weight: float | None = None,
    prior: object = None,
    prior_from: object = None,
) -> KindsCalibrationResult:
    """Identify `model`'s geometry from measurement sets of any kinds (one problem).

    Parameters
    ----------
    model : SerialModel
        Nominal model.
    data : sequence of Measurements, GaugeMeasurements or ResidualBlock
        The measurement sets: tracker points / poses, ballbar and pair distances, fixed
        points, planes (`kinecal.io.kinds.read_kind`), or blocks of other kinds.
    sigma : sequence of float or None, optional
        Stated 1-sigma noise per set (length unit; what it is the noise of depends on the
        kind: docs/measurement-kinds.md); None for a set: its file's ``sigma`` column, else
        estimated from the fit (and said so).
    validate : sequence, optional
        Held-out sets of any kinds: their own unknowns are fitted with the arm held, at
        nominal (before) and at the calibrated geometry (after).
    validate_sigma : sequence of float or None, optional
        Their noise (for the fit of their unknowns when rows differ in noise).
    method : {"lm"}
        Levenberg-Marquardt on the stacked normal equations.
    free : {"identifiable", "all"} or sequence of str
        As in `kinecal.calibrate`; "identifiable" is decided on the stack.
    loss, f_scale
        Robust loss of a final refit (``huber``, ``soft_l1``, ``cauchy``, ``arctan``) and its
        scale in units of the noise; outlier observations are flagged either way.
    rank_tol : float
        Relative rank threshold of the identifiability analysis.
    rotation_weight : float, optional
        Tracker poses: length units per rad of the rotation rows.
    prior, prior_from
        A prior on the arm's free parameters, as in `kinecal.calibrate` (its rows join the
        stack: `kinecal.calibration.blocks.prior`).

    Returns
    -------
    KindsCalibrationResult
    """
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate(model, list(data), sigma, validate, validate_sigma, method, free,
                         loss, f_scale, rank_tol, rotation_weight, (prior, prior_from))
    res.warnings = list(found)
    return res


def calibrate_system(model: SystemModel, data, method: str = "lm", *, validate=None,
                     sigma=None, **kw) -> KindsCalibrationResult:
    """Identify a robot system (`kinecal.kinematics.tree.SystemModel`) from measurement
    sets of any kinds whose rows name their tips: `calibrate_blocks` with one set or a
    list (`sigma`: one value for every set, or one per set); what `kinecal.calibrate`
    does with a system. The result has, beside the overall figures, the errors per tip
    (``extra["by_tip"]``, the JSON's ``calibration.by_tip``) and what each chain's data
    identify alone (``extra["system"]``, `system_ident`)."""
    from kinecal.calibration.serial.merge import data_sets

    sets, sig = data_sets(data, sigma, "data")
    vsets = None if validate is None else data_sets(validate, None, "validation")[0]
    return calibrate_blocks(model, sets, sigma=sig, validate=vsets, method=method, **kw)


def _check_arguments(method: str, loss: str, data: list, f_scale, rank_tol) -> None:
    if method not in BLOCK_METHODS:
        raise InputError(f"unknown method {method!r} for several measurement kinds; expected "
                         f"one of {', '.join(BLOCK_METHODS)}", option="--method")
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if not data:
        raise InputError("no measurement sets")
    if f_scale is not None and not (np.isfinite(f_scale) and f_scale > 0):
        raise InputError(f"f_scale: expected a positive number, got {f_scale}")
    if not (0 < rank_tol < 1):
        raise InputError(f"rank_tol: expected 0 < rank_tol < 1, got {rank_tol}")


def validation_errors(model: SerialModel, blocks: Sequence[ResidualBlock],
                      params: np.ndarray) -> list[np.ndarray]:
    """Error per observation of each validation block at `params`, its unknowns fitted."""
    _, res = start_blocks(model, blocks, params)
    return [b.observation_errors(r) for b, r in zip(blocks, res, strict=True)]


def _length_errors(blocks, errors) -> np.ndarray:
    """Errors of the blocks in the length unit (all blocks if none is), concatenated."""
    use = [e for b, e in zip(blocks, errors, strict=True) if b.unit == "length"] or errors
    return np.concatenate(use) if use else np.zeros(0)


def _check_validation(model: SerialModel, blocks: Sequence[ResidualBlock],
                      names: Sequence[str]) -> list[np.ndarray]:
    """The validation sets' own checks at nominal (a file of another robot, joints in
    another unit); returns their errors there (the "before" of the validation)."""
    nuis, res = start_blocks(model, blocks, model.nominal)
    errors = [b.observation_errors(r) for b, r in zip(blocks, res, strict=True)]
    check_block_data(model, blocks, nuis, errors, names, "validation ")
    return errors


def _calibrate(model, data, sigma, validate, validate_sigma, method, free, loss, f_scale,
               rank_tol, rotation_weight, priors=(None, None)) -> KindsCalibrationResult:
    _check_arguments(method, loss, data, f_scale, rank_tol)
    t0 = time.perf_counter()
    model = model_for_markers(model, marker_names(list(data) + list(validate or [])))
    spec = None if is_system(model) else prior_spec(model, *priors, method, loss)
    check_stack_rows(data)
    check_stack_rows(list(validate or []), "validation ")
    blocks = make_blocks(model, data, sigma, rotation_weight)
    val_blocks = make_blocks(model, validate or [], validate_sigma, rotation_weight)
    cand = candidate_names(model, free)
    check_stack_unknowns(blocks, len(cand))
    vb: list[np.ndarray] = []

    def check(nuis0, before, ana0, names) -> None:  # before the fit
        check_blocks(model, blocks, nuis0, before, ana0, names)
        check_validation_overlap(blocks, val_blocks)
        vb.extend(_check_validation(model, val_blocks, ana0.report.names))

    sol = solve_blocks(model, blocks, cand, free == "identifiable", rank_tol=rank_tol,
                       loss=loss, f_scale=f_scale, check=check)
    fit, ana, before = sol.fit, sol.analysis, sol.before
    prior_used = pfit = None
    if spec is not None:  # the MAP fit (docs/priors.md); the analysis stays the data's
        prior_used, pfit = stack_prior(fit, spec, rank_tol)
        if pfit is not None:
            fit.result = pfit.result
    prob, x = fit.problem, np.asarray(fit.result.x, dtype=float)
    params, nuis = prob.params(x), prob.nuisance(x)
    if pfit is not None:  # the posterior: the prior decides the blind motions too
        unc, nuis_std = pfit.uncertainty, pfit.nuisance_std
    else:
        unc, nuis_std = stack_uncertainty(prob, x, ana,
                                          fit.outliers if loss != "linear" else [])
        unc.estimable &= ~np.isin(prob.free, ana.report.unidentifiable)
    check_unidentifiable_free([n for n, e in zip(prob.free, unc.estimable, strict=True)
                               if not e], free)
    check_parameter_tolerance(model, params, np.where(unc.estimable, unc.std, np.inf),
                              prob.free, ana.report.confounded_with)
    if not is_system(model):  # the same-arm rule of the commands that read results
        check_change(model, params, _full_std(model, prob, unc), prob.free,
                     kinds=[b.kind for b in blocks], prior=prior_state(spec, pfit),
                     prior_decided=[] if pfit is None else pfit.split["decided_by_prior"])
    r1 = prob.block_residuals(x)
    after = [b.observation_errors(r) for b, r in zip(blocks, r1, strict=True)]
    check_fits(model, prob, x, r1, fit, loss)
    entries = []
    for i, b in enumerate(blocks):
        how = "stated" if fit.known[i] else (
            "estimated" if np.isfinite(fit.factors[i]) else "not estimable")
        entries.append(kind_entry(b, prob.sigma[i], how, before[i], after[i],
                                  b.nuisance_report(nuis[i], nuis_std[i])))
    val_entries, val_before, val_after = [], None, None
    if val_blocks:
        va = validation_errors(model, val_blocks, params)
        val_entries = [kind_entry(b, b.stated_sigma(), "stated" if b.stated_sigma() is not None
                                  else "not used", e0, e1)
                       for b, e0, e1 in zip(val_blocks, vb, va, strict=True)]
        val_before, val_after = _length_errors(val_blocks, vb), _length_errors(val_blocks, va)
    more = {}
    if is_system(model):  # a robot system: errors per tip, what each chain identifies
        more["by_tip"] = {"calibration": by_tip(model.tips, blocks, before, after)}
        if val_blocks:
            more["by_tip"]["validation"] = by_tip(model.tips, val_blocks, vb, va)
        more["system"] = system_identifiability(sol.final, sol.final.pack(params, nuis),
                                                rank_tol, ana)
    if not is_system(model):
        more["prior"] = prior_entry(model, spec, prior_used, pfit)
    return _result(model, prob, fit, ana, unc, params, before, after, entries, val_entries,
                   val_before, val_after, blocks, val_blocks, t0, loss, more)


def _full_std(model, prob, unc) -> np.ndarray:
    """Standard errors of every parameter ``(n_params,)``: 0 held, ``inf`` not estimable."""
    std = np.zeros(model.n_params)
    std[prob.index] = np.where(unc.estimable, unc.std, np.inf)
    return std


def _result(model, prob, fit, ana, unc, params, before, after, entries, val_entries,
            val_before, val_after, blocks, val_blocks, t0, loss, more):
    res = fit.result
    names = prob.free
    report = ana.report
    std = np.zeros(model.n_params)
    std[prob.index] = unc.std
    offsets = np.cumsum([0, *[b.n_obs for b in blocks]])
    outliers = [int(offsets[i] + j) for i, j in fit.outliers]
    labels = [blocks[i].observation_labels()[j] for i, j in fit.outliers]
    qs = [b.configurations() for b in blocks]
    q_all = np.concatenate([q for q, _ in qs])
    m_all = (np.concatenate([np.zeros(len(q), np.intp) if m is None else m for q, m in qs])
             if model.marker_names else None)
    extra = {"kinds": entries, "not_seen": list(ana.unseen),
             "not_seen_words": unseen_words(ana.unseen), "noise_rounds": int(fit.rounds),
             "data": [b.source for b in blocks]}
    if ana.shown_by_fixtures:
        extra["fixtures_show"] = list(ana.shown_by_fixtures)
    if val_entries:
        extra["validation_kinds"] = val_entries
        extra["validation_data"] = [b.source for b in val_blocks]
    extra.update(more)
    if labels:
        extra["outlier_observations"] = labels
    if loss != "linear":
        extra["loss"] = loss
    return KindsCalibrationResult(
        model=model.with_params(params, name=f"{model.name}-calibrated"),
        nominal_model=model, method="lm", free=list(names), params=params, std=std,
        covariance=unc.covariance, identifiability=report,
        errors_before=_length_errors(blocks, before), errors_after=_length_errors(blocks, after),
        val_before=val_before, val_after=val_after, seed=None, iterations=int(res.nit),
        evaluations=int(res.nfev), seconds=time.perf_counter() - t0,
        history=list(res.history), outliers=outliers, message=str(res.message),
        success=bool(res.success), sigma=unc.sigma, extra=extra, q_calibration=q_all,
        q_validation=None, marker_calibration=m_all, uncertainty=unc, lost=[])
