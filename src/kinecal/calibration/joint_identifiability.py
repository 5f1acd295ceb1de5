"""Identifiability of joint-error coefficients beyond the geometry.

The geometry comes first: its identifiable parameters are those of the geometric
calibration. A joint-error coefficient is identifiable when its (scaled) Jacobian column
keeps a component above the rank threshold once the geometric columns are projected out;
among the coefficients, column-pivoted QR of the projected columns decides (the exact tie
rule of `kinecal.calibration.identifiability.pivoted_qr_diagonal`). So a coefficient
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
    IdentifiabilityReport,
    conditioning,
    observability_indices,
    pivoted_qr_diagonal,
)
from kinecal.calibration.problem import column_scale
from kinecal.calibration.rows import PoseRows
from kinecal.data import Measurements
from kinecal.kinematics.serial import SerialModel

__all__ = ["CoefficientAnalysis", "correlated_with"]

Array = NDArray[np.float64]
#: |correlation| from which a free coefficient is reported as correlated with a parameter
CORRELATION_REPORT = 0.9


class CoefficientAnalysis:
    """The R factor of the geometric free columns and candidate coefficients, once.

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
    """

    def __init__(self, model: SerialModel, data: Measurements, geometric: Sequence[str],
                 coefficients: Sequence[str], params: Array, rotation_weight: float = 0.0
                 ) -> None:
        self.geometric = list(geometric)
        self.coefficients = list(coefficients)
        self.names = self.geometric + self.coefficients
        rows = PoseRows(model, data, rotation_weight, weighted=False)
        R, _, P = rows.factor(np.asarray(params, dtype=float), model.index(self.names))
        k = len(self.names)
        self.scale = column_scale(model, data, self.names, params, positions=P)
        self.Rs = R[:k, :k] * self.scale
        self.n_rows = rows.rows * rows.n_poses
        self._pos = {n: i for i, n in enumerate(self.names)}

    def report(self, names: Sequence[str], tol: float) -> IdentifiabilityReport:
        """Which of the coefficients `names` are identifiable beyond the geometry."""
        names = list(names)
        kg = len(self.geometric)
        cols = list(range(kg)) + [self._pos[n] for n in names]
        Rs = self.Rs[:, cols]
        f = self.scale[cols]
        ref = float(np.linalg.norm(Rs, axis=0).max(initial=0.0))
        if kg:
            Q, _ = np.linalg.qr(Rs[:, :kg])
            rest = Rs[:, kg:] - Q @ (Q.T @ Rs[:, kg:])
        else:
            rest = Rs.copy()
        diag, piv = pivoted_qr_diagonal(rest) if names else (np.zeros(0), np.zeros(0, int))
        rank = int((diag > tol * ref).sum()) if ref > 0 else 0
        kept = np.sort(piv[:rank])
        dropped = np.sort(piv[rank:])
        confounded: dict[str, dict[str, float]] = {}
        basis = list(range(kg)) + [kg + i for i in kept]
        labels = self.geometric + names
        if dropped.size:
            A = Rs[:, basis]
            coef = np.linalg.lstsq(A, Rs[:, kg + dropped], rcond=None)[0] if basis else \
                np.zeros((0, dropped.size))
            coef = coef * f[basis][:, None] / f[kg + dropped][None, :]
            for j, d in enumerate(dropped):
                c = coef[:, j]
                big = np.abs(c) > 1e-6 * max(np.abs(c).max(initial=0.0), 1e-300)
                confounded[names[d]] = {labels[basis[i]]: float(c[i])
                                        for i in np.flatnonzero(big)}
        cond, s = conditioning(Rs[:, basis]) if basis else (float("inf"), np.zeros(0))
        return IdentifiabilityReport(
            names=names, rank=int(rank), identifiable=[names[i] for i in kept],
            unidentifiable=[names[i] for i in dropped], confounded_with=confounded,
            condition_number=cond, singular_values=s,
            observability=observability_indices(s, self.n_rows),
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
