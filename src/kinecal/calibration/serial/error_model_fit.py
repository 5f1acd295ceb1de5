"""The fits of `kinecal.calibration.serial.error_model`: the chosen terms with the geometry,
a model's own terms with an explicit free list, and the entries of the result JSON.

`fit_chosen` frees the geometry's identifiable parameters and the identifiable
coefficients of the chosen terms; the warnings the user sees are those of that last fit
(and the geometric stage's findings on the data that it does not repeat), worded for the
free set the user asked for. `fit_named` honours ``--free NAMES`` on a model that declares
joint-error terms: exactly the named parameters are free, coefficients included.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinecal.calibration.diagnostics import CODES
from kinecal.calibration.diagnostics.envelope import check_calibrated_range
from kinecal.calibration.diagnostics.fit import check_unidentifiable_free
from kinecal.calibration.identifiability import IdentifiabilityReport
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.joint_identifiability import CoefficientAnalysis, correlated_with
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.data import Measurements
from kinecal.diagnostics import Diagnostic, expect, warn
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC

__all__ = ["FIT_CODES", "choice_entry", "envelope_of", "fit_chosen", "fit_named",
           "merged_report", "rotation_weight_of", "terms_entry"]

#: diagnostics on a fit's residual (`kinecal.calibration.diagnostics`): those of the
#: geometric stage are not reported when a joint-error model is chosen
FIT_CODES = frozenset(("outliers", "lack-of-fit", "residual-offset", "parameter-tolerance",
                       "unidentifiable-free", "residual-above-noise"))


def envelope_of(model: SerialModel, data: Measurements) -> JointEnvelope:
    """The joint readings of the calibration poses (`JointEnvelope`)."""
    return JointEnvelope.of(data.q, [k != PRISMATIC for k in model.joint_kinds])


def _issue(res: CalibrationResult, seen: list[Diagnostic], extra: Sequence[Diagnostic],
           free_choice: object) -> None:
    """Issue the warnings of the fit kept (`seen`, its ``unidentifiable-free`` worded for the
    user's `free_choice`) and `extra` findings whose codes it does not raise itself."""
    own = {d.code for d in seen}
    out: list[Diagnostic] = []
    for d in seen:
        if d.code == "unidentifiable-free":
            with expect("unidentifiable-free") as worded:
                check_unidentifiable_free(res.unidentifiable_free(), free_choice)
            out += worded or [d]
        else:
            out.append(d)
    out += [d for d in extra if d.code not in own]
    for d in dict.fromkeys(out):
        warn(d.code, d.message)
    res.warnings = list(dict.fromkeys(out))


def fit_chosen(final_model: SerialModel, data: Measurements, method: str,
               geo: CalibrationResult, geo_seen, analysis: CoefficientAnalysis,
               names: list[str], *, rank_tol: float, free_choice: object = "identifiable",
               **kwargs):
    """Geometry and the identifiable coefficients `names` of the chosen model together.

    Identifiability is local: a coefficient at the edge of the threshold at the geometric
    calibration may fall below it at the solution. Its fit would be honest (only it and its
    partners lose their standard error), but kinecal chose this free set, and it never
    frees what the poses do not identify: it is held and the fit redone. The warnings of a
    discarded fit are not the user's concern: only the last fit's are issued (with the
    geometric stage's findings on the data that it does not repeat, not those on its fit,
    which the joint errors may have removed). Returns ``(result, coefficient
    identifiability report)``.
    """
    ident = analysis.report(names, rank_tol)
    coefficients = set(names)
    while True:
        with expect(*CODES) as seen:
            res = calibrate(final_model, data, method, free=list(geo.free) + ident.identifiable,
                            rank_tol=rank_tol, **kwargs)
        late = [n for n in res.identifiability.unidentifiable if n in coefficients]
        if not late:
            _issue(res, seen, [d for d in geo_seen if d.code not in FIT_CODES], free_choice)
            return res, ident
        ident = dataclasses.replace(
            ident, rank=ident.rank - len(late),
            identifiable=[n for n in ident.identifiable if n not in late],
            unidentifiable=[n for n in names if n in late or n in ident.unidentifiable],
            confounded_with={**ident.confounded_with,
                             **{n: res.identifiability.confounded_with.get(n, {})
                                for n in late}})


def fit_named(model: SerialModel, data: Measurements, method: str, free: Sequence[str],
              **kwargs) -> CalibrationResult:
    """A model with joint-error terms calibrated with exactly the parameters `free` free
    (``--free NAMES``), its other coefficients held at the model's values.

    Freed coefficients are fitted on these poses: the terms are then held at the edges of
    their joint readings. Held ones keep the model's envelope, and poses beyond it warn
    ``outside-calibrated-range`` (re-registering a calibrated model on poses elsewhere).
    The result's ``joint_errors`` entry lets ``fk --params`` rebuild the terms.
    """
    n_geo = model._n_geometric
    coefficients = set(model.parameter_names[n_geo:])
    spec = model.joint_errors
    if coefficients & set(free):
        model = dataclasses.replace(model, joint_errors=spec.within(envelope_of(model, data)))
    else:
        check_calibrated_range(data.q, spec.envelope, model,
                               "calibration poses (the model's joint-error terms)")
    res = calibrate(model, data, method, free=list(free), **kwargs)
    freed = [n for n in free if n in coefficients]
    report = res.identifiability
    res.extra["joint_errors"] = terms_entry(res, dataclasses.replace(
        report, identifiable=[n for n in report.identifiable if n in coefficients],
        unidentifiable=[n for n in freed if n in report.unidentifiable]))
    return res


def terms_entry(res: CalibrationResult, ident: IdentifiabilityReport) -> dict:
    """The ``joint_errors`` entry of the result JSON: the terms (model-file section, read
    back by ``kinecal fk --params``), which are identifiable and what the others equal."""
    from kinecal.io.joint_errors_file import joint_errors_to_file

    nom = res.nominal_model
    return {
        "model": joint_errors_to_file(nom, 180.0 / np.pi if nom.angle_unit == "deg" else 1.0),
        "identifiable": ident.identifiable,
        "unidentifiable": ident.unidentifiable,
        "confounded_with": {n: ident.confounded_with.get(n, {}) for n in ident.unidentifiable},
        "correlated_with": correlated_with(res, ident.identifiable),
    }


def rotation_weight_of(geo: CalibrationResult, data: Measurements,
                     rotation_weight: float | None) -> float:
    if data.rotations is None:
        return 0.0
    if rotation_weight is not None:
        return float(rotation_weight)
    from kinecal.calibration.serial.problem import characteristic_length

    return characteristic_length(geo.nominal_model, data)


def choice_entry(error_model: str, label: str, folds: int | None, table: list[dict],
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


def merged_report(geo: IdentifiabilityReport, coef: IdentifiabilityReport,
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
