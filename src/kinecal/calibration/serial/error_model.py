"""Calibration with non-geometric error models chosen by cross-validation.

``calibrate_error_model(model, data, error_model)`` wraps `kinecal.calibrate`:

``geometric``
    `calibrate` itself (a model without joint errors is unchanged, bit for bit).
``compliance``, ``harmonic``, ``scale``, ``full``, or a ``+``-joined list of families
    The geometry plus the joint-error terms of those families
    (`kinecal.kinematics.serial.joint_errors`; ``full`` = all three, harmonics of order
    `harmonics`).
``model``
    The terms the model (file) declares (`kinecal.io.joint_errors_file`), as they are.
``auto``
    Every combination of the families, harmonics of order 1 to `harmonics`, scored by
    K-fold cross-validation on the calibration poses only (deterministic folds,
    `kinecal.calibration.serial.cross_validation`); the one-standard-error rule picks the
    smallest model whose score is within one standard error of the best. The validation
    poses are never seen by the choice.

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

from kinecal.calibration.diagnostics import CODES
from kinecal.calibration.identifiability import IdentifiabilityReport
from kinecal.calibration.serial.api import CALIBRATION_RANK_TOL, calibrate
from kinecal.calibration.serial.cross_validation import (
    CVScore,
    FoldedRows,
    n_poses,
    one_standard_error,
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
from kinecal.calibration.serial.joint_identifiability import CoefficientAnalysis, correlated_with
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.data import Measurements
from kinecal.diagnostics import expect, warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import FAMILIES, JointErrors, joint_errors_for
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["AUTO_HARMONICS", "DEFAULT_FOLDS", "DEFAULT_HARMONICS", "ERROR_MODELS", "LSQ_METHODS",
           "MAX_HARMONICS", "ErrorModelResult", "calibrate_error_model", "candidates",
           "error_model_text", "parse_error_model"]

#: diagnostics on a fit's residual (`kinecal.calibration.diagnostics`): those of the
#: geometric stage are not reported when a joint-error model is chosen
FIT_CODES = frozenset(("outliers", "lack-of-fit", "residual-offset", "parameter-tolerance",
                       "unidentifiable-free", "residual-above-noise"))


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
        Free geometric parameters, as in `calibrate`.
    validate : Measurements, optional
        Held-out poses for the before/after statistics (never used for the choice).
    harmonics : int, optional
        Harmonic order of the fixed choices (default 2); the largest order ``auto`` tries
        (default 3).
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
    families = parse_error_model(error_model)
    if error_model == "model" and model.joint_errors is None:
        families = ()  # the model has no joint-error terms: a geometric calibration
    if families == ():
        return calibrate(model, data, method, free=free, validate=validate, rank_tol=rank_tol,
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
    union = _with_terms(model, union_spec)
    # 1. the geometry, as `calibrate` identifies it (coefficients held at their values);
    # its findings on the fit (outliers, lack of fit: what the joint errors may explain)
    # belong to the final model's fit, which reports its own
    with expect(*CODES) as geo_seen:
        geo = calibrate(plain, data, method, free=free, validate=validate, rank_tol=rank_tol,
                        rotation_weight=rotation_weight, **kwargs)
    params = np.r_[geo.params, union.nominal[plain.n_params:]]
    coef_names = [n for n in union.parameter_names[plain.n_params:]
                  if n not in model.fixed_names]
    rw = _rotation_weight(geo, data, rotation_weight)
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
            geo.extra["error_model"] = _choice(error_model, "geometric", k, table, geo)
            return ErrorModelResult.of(geo, geo, data)
        final_spec = joint_errors_for(plain, chosen, chosen_order, base=model.joint_errors)
    # 3. the chosen model: geometry and identifiable coefficients together
    final_model = _with_terms(model, final_spec)
    res, ident = _fit_chosen(final_model, data, method, geo, geo_seen, analysis,
                             [n for n in final_model.parameter_names[plain.n_params:]
                              if n not in model.fixed_names],
                             validate=validate, rank_tol=rank_tol,
                             rotation_weight=rotation_weight, **kwargs)
    res.identifiability = _merged_report(geo.identifiability, ident, res.identifiability)
    res.seconds = time.perf_counter() - t0
    label = (_label(final_spec.families, final_spec.harmonics) if error_model != "model"
             else "model")
    res.extra["error_model"] = _choice(error_model, label, k, table, geo)
    res.extra["joint_errors"] = _terms_entry(res, ident)
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
    folded = FoldedRows(union, data, params, union.index(cols), k, rw)
    analysis = CoefficientAnalysis(union, data, geo.free, coef_names, params, rw,
                                   gram=folded.total, positions=folded.positions)
    cands = candidates(order)
    member = _membership(union, coef_names)
    sets = [list(geo.free) + analysis.identifiable(
        [n for n in coef_names if member(n, fam, h)], rank_tol) for _, fam, h in cands]
    sizes = [len(s_) for s_ in sets]
    pos = {n: i for i, n in enumerate(cols)}
    scores = folded.scores([[pos[n] for n in s_] for s_ in sets])
    # a candidate with more parameters than a fold's training rows is not fitted by
    # the fold: it cannot be chosen (the geometric model always can)
    train_rows = folded.rows.rows * (len(data) - int(np.bincount(folded.folds).max()))
    scores = [sc if i == 0 or sizes[i] <= train_rows else
              CVScore(float("inf"), float("inf"), sc.fold_means)
              for i, sc in enumerate(scores)]
    best, pick = one_standard_error(scores, sizes)
    table = [{"model": label, "parameters": sizes[i],
              "coefficients": sizes[i] - len(geo.free),
              "cv_mean": sc.mean if np.isfinite(sc.mean) else None,
              "cv_se": sc.se if np.isfinite(sc.se) else None,
              "best": i == best, "chosen": i == pick}
             for i, ((label, _, _), sc) in enumerate(zip(cands, scores, strict=True))]
    return analysis, table, cands[pick][1], cands[pick][2]


def _fit_chosen(final_model: SerialModel, data: Measurements, method: str,
                geo: CalibrationResult, geo_seen, analysis: CoefficientAnalysis,
                names: list[str], *, rank_tol: float, **kwargs):
    """Geometry and the identifiable coefficients `names` of the chosen model together.

    Identifiability is local: a coefficient at the edge of the threshold at the geometric
    calibration may fall below it at the solution. Its fit would be honest (only it and its
    partners lose their standard error), but kinecal chose this free set, and it never
    frees what the poses do not identify: it is held and the fit redone (the discarded
    fit's warning about it is not the user's concern). Returns ``(result, coefficient
    identifiability report)``.
    """
    ident = analysis.report(names, rank_tol)
    coefficients = set(names)
    while True:
        with expect("unidentifiable-free") as seen:
            res = calibrate(final_model, data, method, free=list(geo.free) + ident.identifiable,
                            rank_tol=rank_tol, **kwargs)
        late = [n for n in res.identifiability.unidentifiable if n in coefficients]
        if not late:
            # what remains is the user's, and so are the geometric stage's findings on the
            # data (not those on its fit, which the joint errors may have removed)
            data_findings = [d for d in geo_seen if d.code not in FIT_CODES]
            for d in [*seen, *data_findings]:
                warn(d.code, d.message)
            res.warnings = list(dict.fromkeys([*res.warnings, *seen, *data_findings]))
            return res, ident
        ident = dataclasses.replace(
            ident, rank=ident.rank - len(late),
            identifiable=[n for n in ident.identifiable if n not in late],
            unidentifiable=[n for n in names if n in late or n in ident.unidentifiable],
            confounded_with={**ident.confounded_with,
                             **{n: res.identifiability.confounded_with.get(n, {})
                                for n in late}})


def _terms_entry(res: CalibrationResult, ident: IdentifiabilityReport) -> dict:
    """The ``joint_errors`` entry of the result JSON: the terms (model-file section, read
    back by ``kinecal fk --params``), which are identifiable and what the others equal."""
    from kinecal.io.joint_errors_file import joint_errors_to_file

    nom = res.nominal_model
    return {
        "model": joint_errors_to_file(nom, 180.0 / np.pi if nom.angle_unit == "deg" else 1.0),
        "identifiable": ident.identifiable,
        "unidentifiable": ident.unidentifiable,
        "confounded_with": ident.confounded_with,
        "correlated_with": correlated_with(res, ident.identifiable),
    }


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


def _rotation_weight(geo: CalibrationResult, data: Measurements,
                     rotation_weight: float | None) -> float:
    if data.rotations is None:
        return 0.0
    if rotation_weight is not None:
        return float(rotation_weight)
    from kinecal.calibration.serial.problem import characteristic_length

    return characteristic_length(geo.nominal_model, data)


def _choice(error_model: str, label: str, folds: int | None, table: list[dict],
            geo: CalibrationResult) -> dict:
    """The ``error_model`` entry of the result JSON."""
    out: dict[str, Any] = {"requested": error_model, "selected": label}
    if table:
        out.update({"folds": folds, "rule": "one standard error", "candidates": table})
    g = {"calibration_mean": float(np.mean(geo.errors_after)), "seconds": float(geo.seconds)}
    if geo.val_after is not None:
        g["validation_mean"] = float(np.mean(geo.val_after))
    out["geometric"] = g
    return out


def _merged_report(geo: IdentifiabilityReport, coef: IdentifiabilityReport,
                   final: IdentifiabilityReport) -> IdentifiabilityReport:
    """One report over geometry and coefficients: geometric candidates and coefficients
    as analysed in turn, condition number and observability of the final free set."""
    return IdentifiabilityReport(
        names=list(geo.names) + list(coef.names),
        rank=len(final.identifiable),
        identifiable=list(final.identifiable),
        unidentifiable=list(geo.unidentifiable) + list(coef.unidentifiable),
        confounded_with={**geo.confounded_with, **coef.confounded_with},
        condition_number=final.condition_number,
        singular_values=final.singular_values,
        observability=final.observability,
    )
