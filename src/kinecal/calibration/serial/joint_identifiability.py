"""Identifiability of joint-error coefficients beyond the geometry.

The geometry comes first: its identifiable parameters are those of the geometric
calibration. A joint-error coefficient is identifiable when its (scaled) Jacobian column
keeps a component above the rank threshold once the geometric columns are projected out;
among the coefficients, column-pivoted QR of the projected columns decides (the exact tie
rule of `kinecal.calibration.identifiability.pivoted_qr_diagonal`: of two coefficients with
the same effect the later one is kept, a harmonic rather than a gravity force, which keeps
the choice independent of round-off). So a coefficient
never displaces a geometric parameter, and one that the geometry reproduces (a first
harmonic that a joint offset and link lengths mimic on these poses, the gravity force of
a joint whose axis is parallel to gravity) is reported with the combination of free
parameters that has the same effect.

Columns are scaled like the geometric identifiability analysis: lengths 1, angles ``1/L``,
coefficients by their effect (`JointErrorTerms.effect_scale`); the threshold is relative to
the largest scaled column.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.identifiability import (
    RANK_TOL,
    IdentifiabilityReport,
    conditioning,
    observability_indices,
    pivoted_qr_diagonal,
)
from kinecal.calibration.serial.problem import column_scale
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.factor import gram_root

__all__ = ["CoefficientAnalysis", "correlated_with", "identifiability_with_terms"]

Array = NDArray[np.float64]
#: |correlation| from which a free coefficient is reported as correlated with a parameter
CORRELATION_REPORT = 0.9


class CoefficientAnalysis:
    """The scaled R factor of the geometric free columns and candidate coefficients, once;
    then `report` for any subset of the coefficients.

    Parameters
    ----------
    model : SerialModel
        Model holding the coefficients.
    data : Measurements
        Calibration poses.
    geometric : sequence of str
        Free geometric parameters (the geometric calibration's).
    coefficients : sequence of str
        Every candidate coefficient.
    params : ndarray, shape (n_params,)
        Where to linearise (the geometric calibration, coefficients at nominal).
    rotation_weight : float
        Length units per rad of rotation rows (measured orientations only).
    gram, positions : ndarray, optional
        The Gram matrix ``(k + 1, k + 1)`` of ``[J | r]`` for ``geometric + coefficients``
        and the tool positions ``(N, 3)`` at `params`, when a pass already made them
        (`kinecal.calibration.serial.cross_validation.FoldedRows`); its square root stands in for
        the R factor (exact enough at thresholds from 1e-6). Otherwise one TSQR pass.
    """

    def __init__(self, model: SerialModel, data: Measurements, geometric: Sequence[str],
                 coefficients: Sequence[str], params: Array, rotation_weight: float = 0.0,
                 gram: Array | None = None, positions: Array | None = None) -> None:
        self.geometric = list(geometric)
        self.coefficients = list(coefficients)
        self.names = self.geometric + self.coefficients
        k = len(self.names)
        rows = PoseRows(model, data, rotation_weight, weighted=False)
        self.n_rows = rows.rows * rows.n_poses
        if gram is None:
            R, _, positions = rows.factor(np.asarray(params, dtype=float),
                                          model.index(self.names))
        self.scale = column_scale(model, data, self.names, params, positions=positions)
        if gram is None:
            self.Rs = R[:k, :k] * self.scale
        else:
            self.Rs = gram_root(gram[:k, :k] * np.outer(self.scale, self.scale))
        kg = len(self.geometric)
        if gram is None:
            self.norms = np.linalg.norm(self.Rs, axis=0)
        else:  # exact from the diagonal: the root's columns carry sqrt(eps) round-off, and
            # a column without effect (an exact zero) must stay one ("no effect")
            self.norms = np.sqrt(np.clip(np.diag(gram[:k, :k]), 0.0, None)) * self.scale
        self.geo_norm = float(self.norms[:kg].max(initial=0.0))
        if kg:  # the coefficients' columns beyond the geometric span, once
            Q, _ = np.linalg.qr(self.Rs[:, :kg])
            self.rest = self.Rs[:, kg:] - Q @ (Q.T @ self.Rs[:, kg:])
        else:
            self.rest = self.Rs.copy()
        self._pos = {n: i for i, n in enumerate(self.coefficients)}

    def identifiable(self, names: Sequence[str], tol: float) -> list[str]:
        """The identifiable coefficients among `names` (in the order of `names`)."""
        return self.report(names, tol, confounding=False).identifiable

    def report(self, names: Sequence[str], tol: float, confounding: bool = True
               ) -> IdentifiabilityReport:
        """Which of the coefficients `names` are identifiable beyond the geometry, and
        (`confounding`) what each of the others equals."""
        names = list(names)
        kg = len(self.geometric)
        sub = np.array([self._pos[n] for n in names], dtype=np.intp)
        ref = max(self.geo_norm, float(self.norms[kg + sub].max(initial=0.0)))
        rank, piv = 0, np.arange(sub.size)
        if sub.size and ref > 0:
            # the exact tie rule (equal effects, e.g. a joint's first harmonic and the
            # gravity force of a mass on its link: the later column, the harmonic, is kept)
            # on the square factor of the projected columns (same norms and products)
            R0 = np.linalg.qr(self.rest[:, sub], mode="r")
            diag, piv = pivoted_qr_diagonal(R0, stop=tol * ref)
            rank = int((diag > tol * ref).sum())
        kept = np.sort(piv[:rank])
        dropped = np.sort(piv[rank:])
        cols = list(range(kg)) + [kg + int(sub[i]) for i in kept]
        labels = self.geometric + [names[i] for i in kept]
        confounded: dict[str, dict[str, float]] = {}
        if confounding and dropped.size:
            f = self.scale
            A = self.Rs[:, cols]
            D = self.Rs[:, kg + sub[dropped]]
            coef = (np.linalg.lstsq(A, D, rcond=None)[0] if cols
                    else np.zeros((0, dropped.size)))
            coef = coef * f[cols][:, None] / f[kg + sub[dropped]][None, :]
            for j, d in enumerate(dropped):
                if self.norms[kg + sub[d]] <= 1e-8 * ref:  # no effect at all on these poses
                    confounded[names[d]] = {}
                    continue
                c = coef[:, j]
                big = np.abs(c) > 1e-6 * max(np.abs(c).max(initial=0.0), 1e-300)
                confounded[names[d]] = {labels[i]: float(c[i]) for i in np.flatnonzero(big)}
        cond, s = (conditioning(self.Rs[:, cols]) if confounding and cols
                   else (float("nan"), np.zeros(0)))
        return IdentifiabilityReport(
            names=names, rank=int(rank), identifiable=[names[i] for i in kept],
            unidentifiable=[names[i] for i in dropped], confounded_with=confounded,
            condition_number=cond, singular_values=s,
            observability=observability_indices(s, self.n_rows) if s.size else {},
        )


def correlated_with(result, names: Sequence[str], threshold: float = CORRELATION_REPORT
                    ) -> dict[str, dict[str, float]]:
    """Free coefficients strongly correlated with other free parameters.

    From the result's covariance: for each of `names` (free coefficients), the free
    parameters whose correlation with it is at least `threshold` in magnitude. Such a
    coefficient is identifiable, but part of its effect is shared: its standard error is
    inflated and its value trades off against theirs.
    """
    free = list(result.free)
    C = np.asarray(result.covariance, dtype=float)
    d = np.sqrt(np.clip(np.diag(C), 0.0, None))
    if C.size == 0 or not np.isfinite(C).all():
        return {}
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = C / np.outer(d, d)
    out: dict[str, dict[str, float]] = {}
    for n in names:
        if n not in free:
            continue
        i = free.index(n)
        row = {free[j]: float(corr[i, j]) for j in range(len(free))
               if j != i and np.isfinite(corr[i, j]) and abs(corr[i, j]) >= threshold}
        if row:
            out[n] = dict(sorted(row.items(), key=lambda kv: -abs(kv[1])))
    return out


def identifiability_with_terms(model: SerialModel, data: Measurements,
                               free: str | Sequence[str] = "all",
                               error_model: str | None = None, harmonics: int | None = None,
                               tol: float = RANK_TOL) -> tuple[SerialModel, IdentifiabilityReport]:
    """The identifiability of a model's geometry and joint-error coefficients on `data`.

    The geometry first (`kinecal.calibration.serial.problem.resolve_free` on the model without
    its joint errors, `free` choosing the candidates), then the coefficients beyond the
    identifiable geometry (`CoefficientAnalysis`), at the nominal values. The terms are the
    model's own (`error_model` None) or those of `error_model` (families, as
    ``--error-model``; `harmonics` their order, default 2).

    Returns
    -------
    model : SerialModel
        The model with the terms analysed.
    report : IdentifiabilityReport
        Over the geometric candidates and every coefficient: rank, identifiable and
        unidentifiable parameters (with what each is confounded with); condition number,
        singular values and observability of the whole identifiable set.
    """
    import dataclasses

    from kinecal.calibration.serial.error_model_spec import DEFAULT_HARMONICS, parse_error_model
    from kinecal.calibration.serial.problem import resolve_free
    from kinecal.errors import InputError
    from kinecal.kinematics.serial.joint_errors import joint_errors_for

    plain = dataclasses.replace(model, joint_errors=None)
    if error_model is not None or harmonics is not None:
        families = parse_error_model(error_model or "harmonic")
        if families is None:
            raise InputError("expected joint-error families (compliance, harmonic, scale, "
                             f"full), got {error_model!r}", option="--error-model")
        if harmonics is not None and harmonics < 1:
            raise InputError(f"expected a harmonic order >= 1, got {harmonics}",
                             option="--harmonics")
        spec = joint_errors_for(plain, families, harmonics or DEFAULT_HARMONICS,
                                base=model.joint_errors)
        model = dataclasses.replace(plain, joint_errors=spec)
    if model.joint_errors is None:
        return plain, resolve_free(plain, data, free, tol=tol)[1]
    n_geo = plain.n_params
    if not isinstance(free, str):  # explicit names: the geometric ones are the candidates
        free = [n for n in free if n in plain.parameter_names]
    _, geo = resolve_free(plain, data, free, tol=tol)
    coefs = [n for n in model.parameter_names[n_geo:] if n not in model.fixed_names]
    analysis = CoefficientAnalysis(model, data, geo.identifiable, coefs, model.nominal)
    rep = analysis.report(coefs, tol)
    return model, IdentifiabilityReport(
        names=list(geo.names) + coefs, rank=geo.rank + rep.rank,
        identifiable=list(geo.identifiable) + rep.identifiable,
        unidentifiable=list(geo.unidentifiable) + rep.unidentifiable,
        confounded_with={**geo.confounded_with, **rep.confounded_with},
        condition_number=rep.condition_number, singular_values=rep.singular_values,
        observability=rep.observability)
