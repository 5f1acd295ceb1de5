"""`CalibrationProblem`: free parameters, residuals, analytic Jacobian, population cost.

The unknowns ``x`` are the free parameters' values (model length unit, rad). The residual
of pose ``i`` is ``sqrt(w_i) * (p_model(q_i; x) - p_measured_i)`` (3 rows per pose); the
metaheuristics minimise paper 000's criterion ``s = mean_i ||p_model - p_measured||``
(papers/000 sec. 2, the mean Euclidean distance error), evaluated for a whole population
in one call.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.identifiability import (
    RANK_TOL,
    IdentifiabilityReport,
    analyse_factor,
)
from kinecal.calibration.serial.row_weights import row_sqrt_weights
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import axis_angle_from_matrix, left_jacobian_inverse

__all__ = [
    "CalibrationProblem",
    "analyse_poses",
    "candidate_names",
    "characteristic_length",
    "column_scale",
    "identification_rows",
    "resolve_free",
    "row_norms",
]

Array = NDArray[np.float64]


def characteristic_length(model: SerialModel, data: Measurements, params=None,
                          positions: Array | None = None) -> float:
    """RMS distance of the tool points from their centroid (model length unit).

    An angle of ``1 / L`` rad sweeps an arc of one length unit at this distance: the
    scale that makes angle and length parameters comparable. `positions` ``(N, 3)``: the
    tool points at `params` when already known (saves a forward-kinematics pass).

    Tool points that do not move at `params` (a tool on the axis of a one-joint chain: the
    spread is round-off, 1e-16 m, and would make every angle weigh 1e16 times a length)
    give their RMS distance from the base origin instead, or 1 when that is zero too.
    """
    P = model.positions(data.q, params, data.marker) if positions is None else positions
    D = P - P.mean(axis=0)
    n = max(len(D), 1)
    L = float(np.sqrt(np.einsum("ij,ij->", D, D) / n))
    size = float(np.sqrt(np.einsum("ij,ij->", P, P) / n))
    if L > 1e-8 * size:
        return L
    return size if size > 0 else 1.0


def row_norms(e: Array) -> Array:
    """Euclidean norms of the last axis, ``(..., 3) -> (...)``, without temporaries."""
    return np.sqrt(np.einsum("...i,...i->...", e, e))


def column_scale(
    model: SerialModel, data: Measurements, names: Sequence[str], params=None,
    positions: Array | None = None,
) -> Array:
    """Column factors ``(k,)``: 1 for lengths, ``1 / L`` for angles (`characteristic_length`),
    ``1 / (L rms(dq/dc))`` for joint-error coefficients (`JointErrorTerms.effect_scale`)."""
    L = characteristic_length(model, data, params, positions)
    idx = model.index(list(names))
    scale = np.where(model.is_angle()[idx], 1.0 / L, 1.0)
    terms, n_geo = model._joint_terms, model._n_geometric
    if terms is not None and (idx >= n_geo).any():  # joint-error coefficients: by effect
        scale[idx >= n_geo] = terms.effect_scale(data.q, L)[idx[idx >= n_geo] - n_geo]
    return scale


def identification_rows(
    model: SerialModel, data: Measurements, names: Sequence[str], params=None,
    rotation_weight: float | None = None,
) -> Array:
    """Identification Jacobian rows ``(3N or 6N, k)`` of `names` for the measured quantities.

    Position rows always; with measured orientations (``data.rotations``) also the three
    rotation rows per pose, times `rotation_weight` (length per rad; default the
    `characteristic_length`), so that they compare with the position rows.
    """
    idx = model.index(list(names))
    if data.rotations is None:
        J = model.identification_jacobian(data.q, params, marker=data.marker)
        return J[:, :, idx].reshape(-1, idx.size)
    J = model.identification_jacobian(data.q, params, "pose", data.marker)[:, :, idx]
    w = characteristic_length(model, data, params) if rotation_weight is None else rotation_weight
    J[:, 3:] *= w
    return J.reshape(-1, idx.size)


def resolve_free(
    model: SerialModel, data: Measurements, free: str | Sequence[str], params: Array | None = None,
    tol: float = RANK_TOL,
) -> tuple[list[str], IdentifiabilityReport]:
    """Free parameter names for ``free`` = ``"all"``, ``"identifiable"`` or explicit names.

    ``all`` means every calibratable parameter of the model (not the ones fixed by its
    design); ``identifiable`` keeps the subset that pivoted QR finds identifiable from
    `data`'s poses. The identifiability report of the candidate set is returned as well.
    """
    names = candidate_names(model, free)
    report = analyse_poses(model, data, names, params, tol=tol)
    if free == "identifiable":
        names = report.identifiable
    return names, report


def candidate_names(model: SerialModel, free: str | Sequence[str]) -> list[str]:
    """The parameters `resolve_free` analyses: every calibratable one for ``"all"`` and
    ``"identifiable"``, else the names given (a list, or one comma-separated string)."""
    if isinstance(free, str):
        if free in ("all", "identifiable"):
            names = list(model.calibratable)
        else:
            names = [n.strip() for n in free.split(",") if n.strip()]
            if not names:
                raise InputError(
                    f"free: expected all, identifiable or parameter names, got {free!r}",
                    option="--free",
                )
    else:
        names = list(free)
    try:
        model.index(names)
    except InputError as exc:
        raise InputError(exc.message, option="--free") from None
    if len(set(names)) != len(names):
        raise InputError("free: a parameter is listed twice", option="--free")
    return names


def analyse_poses(
    model: SerialModel, data: Measurements, names: Sequence[str], params: Array | None = None,
    tol: float = RANK_TOL, rotation_weight: float | None = None,
) -> IdentifiabilityReport:
    """Identifiability of `names` from `data`'s poses at `params` (default nominal).

    The identification rows (`identification_rows`, unweighted) are folded chunk by chunk
    into their R factor (TSQR): memory stays linear in the number of poses with a small
    constant, and the report is that of `analyse` on the full matrix.
    """
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    P = None
    if rotation_weight is None and data.rotations is not None:
        P = model.positions(data.q, p, data.marker)
        rotation_weight = characteristic_length(model, data, p, P)
    rows = PoseRows(model, data, rotation_weight or 0.0, weighted=False)
    k = len(names)
    R, _, P = rows.factor(p, model.index(list(names)))
    scale = column_scale(model, data, names, p, positions=P)
    return analyse_factor(R[:k, :k], names, rows.rows * rows.n_poses, tol=tol, scale=scale)


class CalibrationProblem:
    """Least-squares view of a serial-arm calibration.

    Parameters
    ----------
    model : SerialModel
        Nominal model (start point and values of the fixed parameters).
    data : Measurements
        Joint readings and measured tool positions.
    free : sequence of str
        Names of the free parameters.
    rotation_weight : float, optional
        With measured orientations: length units per radian of rotation error in the
        residual (default: the workspace's `characteristic_length`; the ratio of position
        to orientation noise is the statistically right choice when known).

    Notes
    -----
    With measured orientations each pose has six residuals: the position error and
    ``rotation_weight * log(R_model R_measured^T)`` (a rotation vector in the measurement
    frame); its Jacobian uses the inverse left Jacobian of SO(3), exact to first order at
    any residual size.
    """

    def __init__(self, model: SerialModel, data: Measurements, free: Sequence[str],
                 rotation_weight: float | None = None) -> None:
        self.model = model
        self.data = data
        self.free = list(free)
        self.index = model.index(self.free)
        self.base_params = model.nominal
        self.x0 = self.base_params[self.index].copy()
        self.R_meas = None if data.rotations is None else np.asarray(data.rotations, float)
        self.rows = 3 if self.R_meas is None else 6
        n_res = self.rows * len(data)
        if n_res < len(self.free):
            raise InputError(
                f"{len(data)} poses give {n_res} equations for {len(self.free)} free parameters: "
                f"expected at least {int(np.ceil(len(self.free) / self.rows))} poses"
            )
        self.rotation_weight = 0.0
        if self.R_meas is not None:
            self.rotation_weight = (characteristic_length(model, data) if rotation_weight is None
                                    else float(rotation_weight))
            if not self.rotation_weight > 0:
                raise InputError(f"rotation weight: expected > 0, got {rotation_weight}",
                                 option="--rotation-weight")
        sw = row_sqrt_weights(data, self.rows, self.rotation_weight)
        #: square roots of the row weights (N, rows): `kinecal.calibration.serial.row_weights`
        self.sqrt_w = np.ones((len(data), self.rows)) if sw is None else sw
        self.weighted = sw is not None
        #: chunked rows (weighted like `residuals`) for the memory-linear passes
        self.pose_rows = PoseRows(model, data, self.rotation_weight, weighted=True)
        self._cache: tuple | None = None
        self.q = np.asarray(data.q, dtype=float)
        self.xyz = np.asarray(data.xyz, dtype=float)
        self.marker = data.marker  # per-pose marker (several tool points) or None
        angle = model.is_angle()[self.index]
        tol = model.tolerances or {}
        self.half_width = np.where(angle, tol.get("angle", 0.02), tol.get("length", 1.0))

    @property
    def n_free(self) -> int:
        """Number of free parameters."""
        return len(self.free)

    def full(self, x: Array) -> Array:
        """Full parameter vector(s) ``(n_params,)`` or ``(P, n_params)`` from free values."""
        x = np.asarray(x, dtype=float)
        p = np.broadcast_to(self.base_params, x.shape[:-1] + (self.model.n_params,)).copy()
        p[..., self.index] = x
        return p

    def _sweep(self, x: Array):
        """FK sweep at `x`, cached: LM asks for the Jacobian where it evaluated residuals."""
        x = np.asarray(x, dtype=float)
        if self._cache is not None and np.array_equal(self._cache[0], x):
            return self._cache[1]
        sweep = self.model.sweep(self.q, self.full(x), self.marker)
        self._cache = (x.copy(), sweep)
        return sweep

    def errors(self, x: Array) -> Array:
        """Position error vectors ``model - measured`` ``(N, 3)`` (or ``(P, N, 3)``)."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 1 and self._cache is not None and np.array_equal(self._cache[0], x):
            return self._cache[1].positions - self.xyz
        return self.model.positions(self.q, self.full(x), self.marker) - self.xyz

    def distances(self, x: Array) -> Array:
        """Euclidean distance errors ``(N,)`` (or ``(P, N)``) in the length unit."""
        return row_norms(self.errors(x))

    def rotation_errors(self, x: Array) -> Array:
        """Rotation error vectors ``log(R_model R_measured^T)`` ``(N, 3)`` (rad); needs
        measured orientations."""
        if self.R_meas is None:
            raise InputError("these measurements have no orientations")
        R = self._sweep(np.asarray(x, dtype=float)).rotations
        return axis_angle_from_matrix(R @ np.swapaxes(self.R_meas, 1, 2))

    def residuals(self, x: Array) -> Array:
        """Weighted residual vector ``(3N,)``, or ``(6N,)`` with measured orientations."""
        e = self.errors(x)
        if self.R_meas is not None:
            e = np.concatenate([e, self.rotation_weight * self.rotation_errors(x)], axis=1)
        return (e * self.sqrt_w).ravel() if self.weighted else e.ravel()

    def jacobian(self, x: Array) -> Array:
        """Analytic Jacobian of `residuals`, shape ``(3N or 6N, n_free)``."""
        sweep = self._sweep(x)
        if self.R_meas is None:
            Jt = sweep.jacobian_t(columns=self.index)  # (k, 3, N)
        else:
            Jt = sweep.jacobian_t("pose", columns=self.index)  # (k, 6, N)
            Jl = left_jacobian_inverse(self.rotation_errors(x))  # (N, 3, 3)
            Jt[:, 3:] = self.rotation_weight * np.einsum("nij,kjn->kin", Jl, Jt[:, 3:])
        if self.weighted:
            Jt *= self.sqrt_w.T
        return Jt.transpose(2, 1, 0).reshape(-1, self.n_free)

    def normal_equations(self, x: Array) -> tuple[Array, Array, Array]:
        """``(residuals, J^T J, J^T r)`` at `x`, accumulated over cache-sized chunks of poses.

        The same numbers as from `residuals` and `jacobian` (to round-off), without forming
        the ``(3N, n_free)`` Jacobian or keeping the FK frames of all poses.
        """
        return self.pose_rows.normal_equations(self.full(x), self.index)

    def gram(self, x: Array, names: Sequence[str] | None = None,
             keep: Array | None = None) -> Array:
        """Gram matrix ``(k + 1, k + 1)`` of ``[J | r]`` at `x`, chunked (see `PoseRows`).

        `names` (default the free parameters) selects the Jacobian columns (any parameter of
        the model); `keep` (pose indices) restricts the rows.
        """
        cols = self.index if names is None else self.model.index(list(names))
        return self.pose_rows.gram(self.full(x), cols, keep)[0]

    def errors_from_residuals(self, r: Array) -> Array:
        """Position error vectors ``(N, 3)`` recomputed from a vector of `residuals`."""
        e = np.asarray(r).reshape(-1, self.rows)[:, :3]
        return e / self.sqrt_w[:, :3] if self.weighted else e

    def distances_from_residuals(self, r: Array) -> Array:
        """Euclidean distance errors ``(N,)`` recomputed from a vector of `residuals`."""
        e = np.asarray(r).reshape(-1, self.rows)[:, :3]
        if self.weighted:
            e = e / self.sqrt_w[:, :3]
        return row_norms(e)

    def positions_from_residuals(self, r: Array) -> Array:
        """Model tool positions ``(N, 3)`` recomputed from a vector of `residuals`."""
        e = np.asarray(r).reshape(-1, self.rows)[:, :3]
        if self.weighted:
            e = e / self.sqrt_w[:, :3]
        return e + self.xyz

    def mean_distance_from_residuals(self, r: Array) -> float:
        """Paper 000's ``s`` recomputed from a residual vector of `residuals`."""
        return float(self.distances_from_residuals(r).mean())

    def population_cost(self, X: Array) -> Array:
        """Mean distance error ``s`` (papers/000 sec. 2) of each row of ``X`` ``(P, n_free)``."""
        return self.distances(np.atleast_2d(X)).mean(axis=-1)

    def bounds(self, center: Array | None = None, shrink: float = 1.0) -> Array:
        """Search box ``(n_free, 2)``: nominal (or `center`) +- tolerance * `shrink`."""
        c = self.x0 if center is None else np.asarray(center, dtype=float)
        h = self.half_width * shrink
        return np.column_stack([c - h, c + h])
