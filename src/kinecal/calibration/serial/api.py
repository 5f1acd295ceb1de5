"""`calibrate`: identify a serial arm's geometry from measured tool positions.

Methods
-------
``lm`` (default)
    Levenberg-Marquardt with the analytic Jacobian on the identifiable parameters.
``householder``
    Paper 000's modified least squares (Householder Gauss-Newton, sec. 4.1).
any metaheuristic of `kinecal.optimize` (``ga``, ``pso``, ``afsa``, ``sa-iafsa``, ``gwo``, ...)
    Searches the model's tolerance box around nominal, cost = mean distance error (paper 000).
``hybrid-<metaheuristic>``
    Paper 000's hybrid: least squares, then the metaheuristic in a box shrunk to 1/3.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from kinecal import diagnostics
from kinecal._blas import small_products
from kinecal.calibration.diagnostics.change import check_change
from kinecal.calibration.diagnostics.envelope import check_calibrated_range
from kinecal.calibration.diagnostics.fit import check_serial_fit
from kinecal.calibration.diagnostics.noise import check_stated_noise, check_stated_sigma
from kinecal.calibration.diagnostics.serial import SerialDataInfo, check_serial_data
from kinecal.calibration.method_options import check_method_options
from kinecal.calibration.serial.box import check_at_bounds, run_metaheuristic
from kinecal.calibration.serial.inputs import as_measurements, as_model, is_system
from kinecal.calibration.serial.polish import check_local_polish
from kinecal.calibration.serial.prior import prior_spec, prior_state
from kinecal.calibration.serial.prior_auto import apply_prior
from kinecal.calibration.serial.prior_fit import prior_entry
from kinecal.calibration.serial.problem import CalibrationProblem, resolve_free
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.calibration.serial.solution import solution_report, solution_uncertainty
from kinecal.calibration.serial.solve import solve_lm
from kinecal.calibration.serial.summaries import (
    conditions_of,
    result_extra,
    validation_errors,
)
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import model_for_markers, remap_markers
from kinecal.kinematics.serial.model import SerialModel
from kinecal.metrology.stats import axis_stats
from kinecal.optimize import METHODS
from kinecal.optimize.hybrid import hybrid_methods
from kinecal.optimize.lsq import LOSSES, householder_gauss_newton

__all__ = ["CALIBRATION_METHODS", "calibrate", "with_model_markers"]

CALIBRATION_METHODS: tuple[str, ...] = ("lm", "householder", *METHODS, *hybrid_methods())

#: default rank threshold of calibrate's free="identifiable": a direction whose pivot is
#: below 1e-4 of the largest (a condition number beyond ~1e4 on unit-norm columns) is
#: identifiable in exact arithmetic but not from real data; freeing it only slows the
#: solver down (UR5 laser-tracker data: 741 vs 9 evaluations for the same validation error)
CALIBRATION_RANK_TOL = 1e-4


def with_model_markers(data: Measurements, model: SerialModel) -> Measurements:
    """`data` with its marker indices into `model`'s markers (matched by name)."""
    if data.marker is None or data.marker_names == model.marker_names:
        return data
    marker = remap_markers(data.marker, data.marker_names, model.marker_names)
    return dataclasses.replace(data, marker=marker, marker_names=model.marker_names)


@small_products
def calibrate(
    model: SerialModel,
    data: Measurements | Sequence[Any],
    method: str = "lm",
    *,
    free: str | Sequence[str] = "identifiable",
    validate: Measurements | Sequence[Any] | None = None,
    rng: int | np.random.Generator | None = None,
    loss: str = "linear",
    f_scale: float | None = None,
    maxiter: int | None = None,
    target: float | None = None,
    options: dict[str, Any] | None = None,
    progress: Callable[[int, float], Any] | None = None,
    rank_tol: float = CALIBRATION_RANK_TOL,
    rotation_weight: float | None = None,
    sigma: float | Sequence[float | None] | None = None,
    validate_register: str | None = None,
    prior: Any = None,
    prior_from: Any = None,
) -> CalibrationResult:
    """Identify the geometric parameters of `model` from `data`.

    Parameters
    ----------
    model : SerialModel, str or Path
        Nominal model (a bundled name or a model file / URDF path is loaded).
    data : Measurements, str, Path or sequence
        Calibration poses (joint angles, measured tool positions); or several data sets of
        any measurement kinds (`kinecal.io.kinds.read_kind`: tracker points / poses,
        ballbar and pair distances, fixed points, planes), calibrated as one problem
        (`kinecal.calibration.blocks.calibrate_blocks`; tracker-only sets are merged and
        take this function's path). A CSV path or a bundled ``NAME:PART`` (also in a
        sequence) is read for `model`, its kind from its columns.
    method : str
        One of `CALIBRATION_METHODS` (see module docstring).
    free : {"identifiable", "all"} or sequence of str
        Free parameters: the identifiable subset of the model's calibratable parameters
        (default), all of them, or explicit names.
    validate : Measurements, str, Path or sequence, optional
        Held-out poses (or data sets of any kinds) for before/after validation statistics
        (paths are read as `data`).
    rng : int or Generator, optional
        Randomness of the metaheuristics (an int is recorded as the result's seed).
    loss : str
        ``linear`` or a robust loss (``huber``, ``soft_l1``, ``cauchy``, ``arctan``) for
        ``lm``; with a robust loss, outlier poses are flagged.
    f_scale : float, optional
        Robust loss scale (length unit); default 3x the median distance error after a
        first plain fit.
    maxiter : int, optional
        Iteration budget of ``householder`` and the metaheuristics (default: paper settings).
    target : float, optional
        Metaheuristics stop when the mean distance error is ``<= target`` (paper 000's eps).
    options : dict, optional
        Method options (metaheuristic options; for hybrids also ``shrink``,
        ``least_squares`` and ``ls_maxiter``).
    progress : callable, optional
        ``progress(iteration, best_mean_error)`` after each iteration of iterative methods.
    rank_tol : float
        Relative pivot threshold of the identifiability analysis behind
        ``free="identifiable"`` (see `CALIBRATION_RANK_TOL`).
    rotation_weight : float, optional
        With measured orientations (``data.rotations``): length units per radian of rotation
        error (default: the workspace's characteristic length; see `CalibrationProblem`).
    sigma : float or sequence of float or None, optional
        The instrument's stated 1-sigma noise per coordinate (length unit, a row of weight
        1): the residual is tested against it (``residual-above-noise``) and the standard
        errors with the noise known are added as ``extra["noise"]``
        (`kinecal.calibration.diagnostics.noise`). With several data sets: one per set
        (None: estimated), the sets weighted by it.
    validate_register : {"all", "N%"}, optional
        Validation data from another tracker set-up: base and tool refitted on all (or N %,
        drawn with `rng`) of its rows first (`kinecal.calibration.serial.validation_frame`).
    prior, prior_from : optional
        A prior on the free parameters (a MAP fit; `kinecal.calibration.serial.prior`,
        docs/priors.md): ``"auto"``, groups ``"lengths=0.5,angles=0.05"`` (or a dict;
        model file units) or a CSV ``name,sigma[,mean]``; `prior_from` a previous result
        (path or object) whose values replace the nominal ones. Default: no prior.

    Returns
    -------
    CalibrationResult
        With ``warnings``: the plausibility diagnostics of this calibration
        (`kinecal.calibration.diagnostics`), also issued as `kinecal.diagnostics.KinecalWarning`
        unless an outer collector (the command line) takes them.

    Raises
    ------
    InputError
        Bad arguments, or data that cannot give an answer (too few distinct poses).
    TypeError
        `model` or `data` of another type than those above.
    """
    model = as_model(model)
    data, validate = as_measurements(data, model), as_measurements(validate, model, "validate")
    if is_system(model):  # several chains: the stacked problem, whatever the data
        from kinecal.calibration.blocks.api import calibrate_system

        for option, value in (("--validate-register", validate_register),
                              ("--prior", prior), ("--prior-from", prior_from)):
            if value is not None:
                raise InputError("applies to a serial arm, not to a system", option=option)
        return calibrate_system(model, data, method, validate=validate, free=free, loss=loss,
                                f_scale=f_scale, rank_tol=rank_tol, sigma=sigma,
                                rotation_weight=rotation_weight)
    if validate_register is not None:  # checked before any work
        from kinecal.calibration.serial.validation_frame import parse_register

        parse_register(validate_register)
        if validate is None:
            raise InputError("applies with validation data only", option="--validate-register")
    # re-registered validation data are judged after the fit only (their raw errors are
    # the tracker's move, not the model's)
    res = _dispatch(model, data, method, free=free, rng=rng, loss=loss,
                    validate=validate if validate_register is None else None,
                    f_scale=f_scale, maxiter=maxiter, target=target, options=options,
                    progress=progress, rank_tol=rank_tol, rotation_weight=rotation_weight,
                    sigma=sigma, prior=prior, prior_from=prior_from)
    if validate is not None:  # re-registered, or checked for another frame
        from kinecal.calibration.serial.validation_frame import judge_validation

        judge_validation(res, validate, validate_register, rng)
    if isinstance(validate, Measurements):  # validation poses beyond the calibrated range
        with diagnostics.collect(python_warnings=True) as found:
            check_calibrated_range(validate.q, res.envelope, res.nominal_model,
                                   "validation poses")
        res.warnings = list(dict.fromkeys([*res.warnings, *found]))
    return res


def _dispatch(model, data, method, *, validate, sigma, **kw) -> CalibrationResult:
    """The calibration behind `calibrate`: tracker rows of one set-up on the fast path,
    anything else stacked (`kinecal.calibration.serial.merge.tracker_input`,
    `kinecal.calibration.serial.several`)."""
    from kinecal.calibration.serial.merge import tracker_input

    data = tracker_input(model, data, kw["free"], kw["rank_tol"], kw["rotation_weight"])
    if not isinstance(data, Measurements) or not (validate is None or isinstance(
            validate, Measurements)):
        from kinecal.calibration.serial.several import several

        return several(_dispatch, model, data, method, validate=validate, sigma=sigma, **kw)
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate(model, data, method, validate=validate, sigma=sigma, **kw)
    res.warnings = list(found)
    return res


def _check_arguments(method: str, loss: str, f_scale, maxiter, target, options, model,
                     sigma, data: Measurements) -> None:
    """Every argument checked before any work: a typo must not cost a calibration."""
    if method not in CALIBRATION_METHODS:
        raise InputError(f"unknown method {method!r}; expected one of "
                         f"{', '.join(CALIBRATION_METHODS)}", option="--method")
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    check_method_options(method, loss=loss, f_scale=f_scale, maxiter=maxiter, target=target,
                         options=options)
    check_stated_sigma(model, sigma)
    if len(data) < 1:
        raise InputError("no calibration poses")


def _setup(model, data, method, free, validate, rank_tol, rotation_weight, loss, f_scale):
    """The problem, its free names, the identifiability reports and the data checks.

    Returns ``(problem, lm_solution or None, names, report, info, first_report)``; for
    ``lm`` the analysis, robust start, fit and growth run in few passes
    (`kinecal.calibration.serial.solve`), with a robust `loss` the robust fit too.
    """
    found: list[SerialDataInfo] = []

    def check(names: list[str], report) -> None:  # the data checks, before the fit
        found.append(check_serial_data(model, data, names, report, validate=validate,
                                       rank_tol=rank_tol))
        found.append(report)

    res = None
    if method == "lm":
        sol = solve_lm(model, data, free, rank_tol=rank_tol, rotation_weight=rotation_weight,
                       check=check, loss=loss, f_scale=f_scale)
        problem, res, names, report = sol.problem, sol, sol.names, sol.report
    else:
        names, report = resolve_free(model, data, free, tol=rank_tol)
        check(names, report)
        problem = CalibrationProblem(model, data, names, rotation_weight)
    info, first_report = found
    return problem, res, names, report, info, first_report


def _run_method(problem: CalibrationProblem, res, method, *, rng, maxiter, target, options,
                progress):
    """Run `method` on `problem` (``lm``: `res` is `solve_lm`'s solution, already fitted
    with the loss). Returns ``(OptimizeResult, outlier rows of a robust loss)``."""
    monitor = problem.mean_distance_from_residuals
    outliers: list[int] = []
    options = dict(options or {})

    def callback(intermediate):
        if progress is not None:
            progress(int(intermediate.nit), float(intermediate.fun))
        return False

    if method == "lm":
        return res.result, list(res.outliers)
    if method == "householder":
        return householder_gauss_newton(problem.residuals, problem.jacobian, problem.x0,
                                        maxiter=maxiter or 100, monitor=monitor,
                                        callback=callback), outliers
    return run_metaheuristic(problem, method, options, rng=rng, maxiter=maxiter,
                             target=target, callback=callback, monitor=monitor), outliers


def _calibrate(model, data, method, *, free, validate, rng, loss, f_scale, maxiter, target,
               options, progress, rank_tol, rotation_weight, sigma, prior=None,
               prior_from=None) -> CalibrationResult:
    _check_arguments(method, loss, f_scale, maxiter, target, options, model, sigma, data)
    model = model_for_markers(model, data.marker_names)  # one tool point per marker seen
    spec = prior_spec(model, prior, prior_from, method, loss)
    data = with_model_markers(data, model)
    validate = None if validate is None else with_model_markers(validate, model)
    seed = int(rng) if isinstance(rng, int | np.integer) else None
    t0 = time.perf_counter()
    problem, res, names, report, info, first_report = _setup(
        model, data, method, free, validate, rank_tol, rotation_weight, loss, f_scale)
    res, outliers = _run_method(problem, res, method, rng=rng, maxiter=maxiter, target=target,
                                options=options, progress=progress)
    pfit = prior_used = None
    if spec is not None:  # the MAP fit (docs/priors.md)
        prior_used, pfit = apply_prior(problem, res, spec, sigma=sigma, rank=report.rank,
                                       rank_tol=rank_tol)
        res = res if pfit is None else pfit.result
    x = np.asarray(res.x, dtype=float)
    if method not in ("lm", "householder"):  # did the metaheuristic reach a minimum?
        check_at_bounds(problem, x, res.search_box, method)
        check_local_polish(problem, x, method, target)
    explicit = list(first_report.names) == list(names)
    normal = res.get("normal_matrix") if loss == "linear" else None
    fit_normal = normal if pfit is None else pfit.normal  # with the prior's information
    # errors at the solution: from LM's last residual when it has one (no FK pass)
    e_after = (problem.errors_from_residuals(res.residual) if normal is not None
               else problem.errors(x))
    if explicit:  # what the poses identify at the identified values, not at nominal
        report = solution_report(problem, x, report, normal, rank_tol)
    unc = pfit.uncertainty if pfit is not None else solution_uncertainty(  # the posterior, or
        problem, x, outliers, info.unique_rows, normal, 2.0 * float(res.fun),
        report.rank if explicit else len(names), e_after + problem.xyz)
    if pfit is None:  # the report has the last word (a prior decides the rest)
        unc.estimable &= ~np.isin(names, report.unidentifiable)
    params = problem.full(x)
    std = np.zeros(model.n_params)
    std[problem.index] = unc.std
    flagged = check_serial_fit(
        problem, x, unc.std, unc.estimable, free_choice=free,
        least_squares=method in ("lm", "householder"), robust=loss != "linear",
        groups=info.groups if info.n_distinct < len(data) else None,
        rank=int(unc.estimable.size - unc.null.shape[1]),
        confounded_with=first_report.confounded_with, normal=fit_normal,
        residual=res.residual if normal is not None else None, poses=info.poses)
    outliers = outliers or flagged
    check_change(model, params, std, names, prior=prior_state(spec, pfit),
                 prior_decided=[] if pfit is None else pfit.split["decided_by_prior"])
    e_before = problem.errors(problem.x0)
    axes = {"calibration": {"before": axis_stats(e_before), "after": axis_stats(e_after)}}
    val_before, val_after = validation_errors(model, validate, params, axes)
    noise = None if sigma is None else check_stated_noise(
        problem, x, unc, sigma, unique_rows=info.unique_rows, normal=fit_normal,
        excluded=outliers if loss != "linear" else (), method=method)
    return CalibrationResult(
        model=model.with_params(params, name=f"{model.name}-calibrated"),
        nominal_model=model,
        method=method,
        free=names,
        params=params,
        std=std,
        covariance=unc.covariance,
        identifiability=report,
        errors_before=np.linalg.norm(e_before, axis=1),
        errors_after=np.linalg.norm(e_after, axis=1),
        val_before=val_before,
        val_after=val_after,
        seed=seed,
        iterations=int(res.nit),
        evaluations=int(res.nfev),
        seconds=time.perf_counter() - t0,
        history=list(res.history),
        outliers=outliers,
        message=str(res.message),
        success=bool(res.success),
        sigma=unc.sigma,
        extra={**result_extra(res, names, model, data, validate, params, axes, noise, info,
                              loss), "prior": prior_entry(model, spec, prior_used, pfit)},
        q_calibration=np.asarray(data.q),
        q_validation=None if validate is None else np.asarray(validate.q),
        marker_calibration=data.marker,
        marker_validation=None if validate is None else validate.marker,
        uncertainty=unc,
        lost=list(info.lost),
        conditions=conditions_of(data, validate),
    )
