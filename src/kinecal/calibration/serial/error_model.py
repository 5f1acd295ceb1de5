"""Calibration with non-geometric error models chosen by cross-validation.

``calibrate_error_model(model, data, error_model)`` wraps `kinecal.calibrate`:

``geometric``
    `calibrate` itself (a model without joint errors is unchanged, bit for bit).
``compliance``, ``harmonic``, ``scale``, ``full``, or a ``+``-joined list of families
    The geometry plus the joint-error terms of those families
    (`kinecal.kinematics.serial.joint_errors`; ``full`` = all three, harmonics of order
    `harmonics`).
``model``
    The terms the model (file) declares (`kinecal.io.joint_errors_file`), as they are;
    with an explicit list of free names exactly those are free, coefficients included
    (`kinecal.calibration.serial.error_model_fit.fit_named`).
``auto``
    Every combination of the families, harmonics of order 1 to `harmonics` (default 4),
    scored by K-fold cross-validation on the calibration poses only (deterministic folds,
    `kinecal.calibration.serial.cross_validation`): half the score is the random folds'
    (poses among the calibration poses), half that of folds blocked by each joint's range
    and by time (poses beyond them); the one-standard-error rule picks the smallest model
    whose score is within one standard error of the best. The validation poses are never
    seen by the choice.

Every fitted model holds its terms at the edges of its calibration poses' joint readings
(`kinecal.kinematics.serial.joint_errors_envelope`): beyond them a harmonic series over a
partial turn or a scale term would run away.

In every case the identifiable coefficients are chosen after the geometry: first the
geometric calibration and its identifiable parameters (as `calibrate` does), then the
coefficients that keep a component above the rank threshold once the geometric columns
are projected out (`kinecal.calibration.serial.joint_identifiability`). A coefficient
confounded with the geometry (e.g. a harmonic that the joint offset and link lengths
reproduce) is held at its nominal value and reported with the combination that mimics it.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinecal._blas import small_products
from kinecal.calibration.diagnostics import CODES
from kinecal.calibration.serial.api import (
    CALIBRATION_RANK_TOL,
    calibrate,
    with_model_markers,
)
from kinecal.calibration.serial.cross_validation import (
    CVScore,
    FoldedRows,
    data_poses,
    n_poses,
    one_standard_error,
    partitions,
    within_and_beyond,
)
from kinecal.calibration.serial.error_model_fit import (
    choice_entry,
    envelope_of,
    fit_chosen,
    fit_named,
    merged_report,
    rotation_weight_of,
    terms_entry,
)
from kinecal.calibration.serial.error_model_result import ErrorModelResult, error_model_text
from kinecal.calibration.serial.error_model_spec import (
    AUTO_HARMONICS,
    DEFAULT_FOLDS,
    DEFAULT_HARMONICS,
    ERROR_MODELS,
    LSQ_METHODS,
    MAX_HARMONICS,
    candidates,
    parse_error_model,
)
from kinecal.calibration.serial.inputs import as_measurements, as_model
from kinecal.calibration.serial.joint_identifiability import CoefficientAnalysis
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.data import Measurements
from kinecal.diagnostics import expect, warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import FAMILIES, JointErrors, joint_errors_for
from kinecal.kinematics.serial.markers import model_for_markers
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["AUTO_HARMONICS", "DEFAULT_FOLDS", "DEFAULT_HARMONICS", "ERROR_MODELS", "LSQ_METHODS",
           "MAX_HARMONICS", "ErrorModelResult", "calibrate_error_model", "candidates",
           "error_model_text", "parse_error_model"]

def _label(families: Sequence[str], h: int) -> str:
    parts = [f"harmonic{h}" if f == "harmonic" else f for f in families]
    return "+".join(parts) or "geometric"


def _with_terms(model: SerialModel, spec: JointErrors | None) -> SerialModel:
    """`model` with the joint-error terms `spec` (values kept where the names exist)."""
    plain = dataclasses.replace(model, joint_errors=None)
    if spec is None:
        return plain
    names = dataclasses.replace(plain, joint_errors=dataclasses.replace(spec, values={}))
    known = set(names.parameter_names)
    values = {k: v for k, v in spec.values.items() if k in known}
    return dataclasses.replace(plain, joint_errors=dataclasses.replace(spec, values=values))


@small_products
def calibrate_error_model(
    model: SerialModel,
    data: Measurements,
    error_model: str = "auto",
    *,
    method: str = "lm",
    free: str | Sequence[str] = "identifiable",
    validate: Measurements | None = None,
    harmonics: int | None = None,
    folds: int | None = None,
    rank_tol: float = CALIBRATION_RANK_TOL,
    rotation_weight: float | None = None,
    **kwargs: Any,
) -> CalibrationResult:
    """Calibrate geometry and joint-error terms; ``auto`` chooses the terms by K-fold CV.

    Parameters
    ----------
    model : SerialModel, str or Path
        Nominal model (any joint-error terms it has are replaced by the chosen ones; their
        values are the starting point); a bundled name or a path is loaded.
    data : Measurements, str or Path
        Calibration poses (the only poses the choice sees); a CSV path or ``NAME:PART`` is
        read.
    error_model : str
        One of `ERROR_MODELS` or families joined by ``+`` (module docstring).
    method : {"lm", "householder"}
        Least-squares solver (``geometric`` accepts every method of `calibrate`).
    free : {"identifiable", "all"} or sequence of str
        Free geometric parameters, as in `calibrate`. With ``error_model="model"``, an
        explicit list is the whole free set: coefficients not named are held at the model's
        values.
    validate : Measurements, optional
        Held-out poses for the before/after statistics (never used for the choice).
    harmonics : int, optional
        Harmonic order of the fixed choices (default 2); the largest order ``auto`` tries
        (default 4).
    folds : int, optional
        Number of cross-validation folds (``auto``), 2 to the number of poses; default 10,
        or one fold per pose (leave-one-out) with fewer than 10 poses.
    rank_tol : float
        Relative pivot threshold of the identifiability analyses.
    rotation_weight : float, optional
        As in `calibrate`.
    **kwargs
        Passed to `calibrate` (``loss``, ``f_scale``, ``maxiter``, ``rng``, ...).

    Returns
    -------
    CalibrationResult
        The calibration of the chosen model; ``extra["error_model"]`` holds the choice and
        (``auto``) the cross-validation table, ``extra["joint_errors"]`` the terms and what
        each unidentifiable coefficient is confounded with.
    """
    model = as_model(model)
    data, validate = as_measurements(data, model), as_measurements(validate, model, "validate")
    if getattr(data, "station", None) is not None:  # stations: a stacked, geometric problem
        raise InputError("applies to tracker rows of one set-up; rows from several stations "
                         "are calibrated geometrically", option="--error-model")
    # one tool point per marker the data names, as `calibrate` gives a model without them
    model = model_for_markers(model, data.marker_names)
    data = with_model_markers(data, model)
    validate = None if validate is None else with_model_markers(validate, model)
    families = parse_error_model(error_model)
    if error_model == "model" and model.joint_errors is None:
        families = ()  # the model has no joint-error terms: a geometric calibration
    if families == ():
        return calibrate(model, data, method, free=free, validate=validate, rank_tol=rank_tol,
                         rotation_weight=rotation_weight, **kwargs)
    if error_model == "model" and not isinstance(free, str):  # --free NAMES, honoured
        return fit_named(model, data, method, free, validate=validate, rank_tol=rank_tol,
                         rotation_weight=rotation_weight, **kwargs)
    _check_arguments(error_model, method, harmonics)
    if kwargs.get("prior") is not None or kwargs.get("prior_from") is not None:
        raise InputError("not with joint-error terms yet (docs/priors.md)", option="--prior")
    t0 = time.perf_counter()
    auto = error_model == "auto"
    order = harmonics or (AUTO_HARMONICS if auto else DEFAULT_HARMONICS)
    plain = _with_terms(model, None)
    if error_model == "model":
        union_spec = model.joint_errors
    else:
        union_spec = joint_errors_for(plain, FAMILIES if auto else families, order,
                                      base=model.joint_errors)
    # every fit holds its terms at the edges of its own poses' readings
    union = _with_terms(model, union_spec.within(envelope_of(plain, data)))
    # 1. the geometry, as `calibrate` identifies it (coefficients held at their values);
    # its findings on the fit (outliers, lack of fit: what the joint errors may explain)
    # belong to the final model's fit, which reports its own
    with expect(*CODES) as geo_seen:
        geo = calibrate(plain, data, method, free=free, validate=validate, rank_tol=rank_tol,
                        rotation_weight=rotation_weight, **kwargs)
    params = np.r_[geo.params, union.nominal[plain.n_params:]]
    coef_names = [n for n in union.parameter_names[plain.n_params:]
                  if n not in model.fixed_names]
    rw = rotation_weight_of(geo, data, rotation_weight)
    table: list[dict] = []
    final_spec, k = union_spec, None
    if not auto:
        analysis = CoefficientAnalysis(union, data, geo.free, coef_names, params, rw)
    else:
        k = min(DEFAULT_FOLDS, n_poses(data)) if folds is None else int(folds)
        analysis, table, chosen, chosen_order = _auto_choice(
            union, data, geo, coef_names, params, rw, k, order, rank_tol)
        if not chosen:  # the geometric calibration is the result: its findings too
            for d in geo_seen:
                warn(d.code, d.message)
            geo.warnings = list(dict.fromkeys([*geo.warnings, *geo_seen]))
            geo.seconds = time.perf_counter() - t0
            geo.extra["error_model"] = choice_entry(error_model, "geometric", k, table, geo)
            return ErrorModelResult.of(geo, geo, data)
        final_spec = joint_errors_for(plain, chosen, chosen_order, base=model.joint_errors)
    # 3. the chosen model: geometry and identifiable coefficients together, its terms held
    # at the edges of the calibration poses' joint readings
    final_model = _with_terms(model, final_spec.within(envelope_of(plain, data)))
    res, ident = fit_chosen(final_model, data, method, geo, geo_seen, analysis,
                            [n for n in final_model.parameter_names[plain.n_params:]
                             if n not in model.fixed_names],
                            validate=validate, rank_tol=rank_tol, free_choice=free,
                            rotation_weight=rotation_weight, **kwargs)
    res.identifiability = merged_report(geo.identifiability, ident, res.identifiability)
    res.seconds = time.perf_counter() - t0
    label = (_label(final_spec.families, final_spec.harmonics) if error_model != "model"
             else "model")
    res.extra["error_model"] = choice_entry(error_model, label, k, table, geo)
    res.extra["joint_errors"] = terms_entry(res, ident)
    return ErrorModelResult.of(res, geo, data)


def _check_arguments(error_model: str, method: str, harmonics: int | None) -> None:
    if method not in LSQ_METHODS:
        raise InputError(f"--error-model {error_model} needs a least-squares method "
                         f"({', '.join(LSQ_METHODS)}), got {method!r}", option="--method")
    if harmonics is not None and not 1 <= harmonics <= MAX_HARMONICS:
        raise InputError(f"expected a harmonic order 1..{MAX_HARMONICS}, got {harmonics}",
                         option="--harmonics")


def _auto_choice(union: SerialModel, data: Measurements, geo: CalibrationResult,
                 coef_names: list[str], params: np.ndarray, rw: float, k: int, order: int,
                 rank_tol: float):
    """2. ``auto``: one pass at the geometric calibration gives every fold's normal
    equations and the identifiability of every coefficient; each candidate is scored by
    K-fold cross-validation (`k` folds), the one-standard-error rule chooses.

    Returns ``(analysis, table, chosen families, chosen harmonic order)``.
    """
    cols = list(geo.free) + coef_names
    parts = partitions(data.q, k, data.time, poses=data_poses(data))
    folded = FoldedRows(union, data, params, union.index(cols), k, rw, parts)
    analysis = CoefficientAnalysis(union, data, geo.free, coef_names, params, rw,
                                   gram=folded.total, positions=folded.positions)
    cands = candidates(order)
    member = _membership(union, coef_names)
    sets = [list(geo.free) + analysis.identifiable(
        [n for n in coef_names if member(n, fam, h)], rank_tol) for _, fam, h in cands]
    sizes = [len(s_) for s_ in sets]
    pos = {n: i for i, n in enumerate(cols)}
    cand_cols = [[pos[n] for n in s_] for s_ in sets]
    within = folded.scores(cand_cols)
    blocked = {p.name: folded.scores(cand_cols, i) for i, p in enumerate(parts) if i}
    scores = within_and_beyond(within, list(blocked.values()))
    # a candidate with more parameters than a fold's training rows is not fitted by
    # the fold: it cannot be chosen (the geometric model always can)
    train_rows = folded.rows.rows * (len(data) - max(int(np.bincount(p.folds).max())
                                                      for p in parts))
    fits = [i == 0 or sizes[i] <= train_rows for i in range(len(cands))]
    scores = [sc if ok else CVScore(float("inf"), float("inf"), sc.fold_means)
              for sc, ok in zip(scores, fits, strict=True)]
    best, pick = one_standard_error(scores, sizes)

    def number(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None

    table = [{"model": label, "parameters": sizes[i],
              "coefficients": sizes[i] - len(geo.free),
              "score": number(scores[i].mean), "cv_se": number(scores[i].se),
              "cv_mean": number(within[i].mean) if fits[i] else None,
              "cv_blocked": ({nm: number(bs[i].mean) for nm, bs in blocked.items()}
                             if fits[i] else {}),
              "best": i == best, "chosen": i == pick}
             for i, (label, _, _) in enumerate(cands)]
    return analysis, table, cands[pick][1], cands[pick][2]


def _membership(model: SerialModel, names: Sequence[str]):
    """``member(name, families, h)``: does coefficient `name` belong to a candidate with
    `families` and harmonic order `h`?"""
    terms = model._joint_terms
    n_geo = model._n_geometric
    family = {n: terms.families[k - n_geo] for n, k in zip(names, model.index(list(names)),
                                                           strict=True)}

    def member(name: str, families: Sequence[str], h: int) -> bool:
        if family[name] != "harmonic":
            return family[name] in families
        order = int(name.rsplit(".", 1)[1][3:])  # dq{j}.sin{h} / dq{j}.cos{h}
        return "harmonic" in families and order <= h

    return member


