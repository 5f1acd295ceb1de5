"""Geometry calibration of the parallel-link CMM (papers/004 machine, DESIGN section 5).

The 42 parameters (`kinecal.kinematics.stewart.PARAMETER_NAMES`): base joints ``b_i``
(18), platform joints ``p_i`` (18) and leg offsets ``o_i`` (6). The probe offset ``ls``
is held at its nominal value: it only enters through ``p_i - s`` (papers/004 eq. 4), so a
change of ``ls`` is the same as moving all ``p_i`` along z.

Data: measured probe poses (e.g. from a laser tracker or a calibrated artefact) and the
machine's leg readings at those poses. The identification residual is the inverse
kinematics (papers/004 eq. 4-5)::

    r_ji = |R_j (p_i - s) + t_j - b_i| - o_i - L_ji

with the analytic Jacobian ``dr/db_i = -n_ji``, ``dr/dp_i = R_j^T n_ji``,
``dr/do_i = -1`` (``n_ji`` the unit leg vector). Each leg's 7 parameters only touch that
leg's residuals, so the 42-column Jacobian is block-structured.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from kinecal import diagnostics
from kinecal.calibration.diagnostics.stewart import DATA_RANK_TOL
from kinecal.calibration.uncertainty import subspace_uncertainty
from kinecal.diagnostics import Diagnostic
from kinecal.errors import InputError
from kinecal.kinematics.stewart import N_PARAMETERS, PARAMETER_NAMES, StewartPlatform
from kinecal.kinematics.stewart_fk import expmap
from kinecal.spatial import matrix_from_rpy, pose_errors, rpy_from_matrix, transform_from

__all__ = [
    "ARCSEC",
    "StewartCalibrationResult",
    "StewartData",
    "calibrate_stewart",
    "identifiability",
    "identification_jacobian",
    "perturb_geometry",
    "pose_prediction_errors",
    "residuals",
    "simulate_stewart",
]

Array = NDArray[np.float64]

#: one arc second in rad
ARCSEC = np.pi / (180.0 * 3600.0)


@dataclass
class StewartData:
    """Calibration data: measured probe poses and leg readings.

    Attributes
    ----------
    poses : ndarray, shape (N, 6)
        Measured probe poses (length unit, rad).
    legs : ndarray, shape (N, 6)
        Leg readings (length unit).
    true_poses : ndarray, shape (N, 6), optional
        Noise-free poses (simulation only).
    true_legs : ndarray, shape (N, 6), optional
        Noise-free readings (simulation only).
    """

    poses: Array
    legs: Array
    true_poses: Array | None = None
    true_legs: Array | None = None

    def __post_init__(self) -> None:
        self.poses = np.asarray(self.poses, dtype=float)
        self.legs = np.asarray(self.legs, dtype=float)
        if self.poses.ndim != 2 or self.poses.shape[1] != 6 or self.legs.shape != self.poses.shape:
            raise InputError(
                f"poses and legs must both be (N, 6), got {self.poses.shape}, {self.legs.shape}"
            )
        bad = ~(np.isfinite(self.poses).all(1) & np.isfinite(self.legs).all(1))
        if bad.any():
            raise InputError("poses and legs must be finite", row=int(np.argmax(bad)) + 1)

    def __len__(self) -> int:
        return int(self.poses.shape[0])


def perturb_geometry(
    geom: StewartPlatform, amplitude: float, rng: np.random.Generator | int | None = None
) -> StewartPlatform:
    """A "true" machine: every one of the 42 parameters off by ``U(-amplitude, amplitude)``."""
    gen = np.random.default_rng(rng)
    return geom.with_parameters(geom.parameters + gen.uniform(-amplitude, amplitude, N_PARAMETERS))


def _noisy_poses(poses: Array, pos_sigma: float, rot_sigma: float, gen) -> Array:
    R = matrix_from_rpy(poses[:, 3:])
    Rn = expmap(gen.normal(0.0, rot_sigma, (len(poses), 3))) @ R
    t = poses[:, :3] + gen.normal(0.0, pos_sigma, (len(poses), 3))
    return np.concatenate([t, rpy_from_matrix(Rn)], axis=1)


def simulate_stewart(
    true_geom: StewartPlatform,
    n_poses: int,
    *,
    rng: np.random.Generator | int | None = None,
    position_noise: float = 1e-6,
    rotation_noise: float = ARCSEC,
    leg_noise: float = 1e-6,
    box: ArrayLike | None = None,
) -> StewartData:
    """Simulated calibration data of a machine with geometry `true_geom`.

    Parameters
    ----------
    true_geom : StewartPlatform
        The real machine.
    n_poses : int
        Number of poses (random in the workspace, `StewartPlatform.random_poses`).
    rng : Generator or int, optional
        Random generator or seed.
    position_noise : float
        Std of the measured tip position, per axis (length unit; default 1 um).
    rotation_noise : float
        Std of the measured orientation, per axis of a small rotation (rad; 1 arcsec).
    leg_noise : float
        Std of the leg readings (length unit; default 1 um).
    box : array_like, shape (6, 2), optional
        Pose box (default `StewartPlatform.workspace_box`).

    Returns
    -------
    StewartData
        Measured (noisy) poses and readings, and the noise-free ones.
    """
    gen = np.random.default_rng(rng)
    poses = true_geom.random_poses(n_poses, gen, box)
    legs = true_geom.inverse(poses)
    meas = _noisy_poses(poses, position_noise, rotation_noise, gen)
    readings = legs + gen.normal(0.0, leg_noise, legs.shape)
    return StewartData(meas, readings, poses, legs)


def residuals(geom: StewartPlatform, data: StewartData) -> Array:
    """Predicted minus measured leg readings, shape (N, 6) (length unit)."""
    return geom.inverse(data.poses) - data.legs


def identification_jacobian(geom: StewartPlatform, poses: ArrayLike) -> Array:
    """Analytic derivative of the predicted readings by the 42 parameters.

    Parameters
    ----------
    geom : StewartPlatform
    poses : array_like, shape (N, 6)
        Probe poses (length unit, rad).

    Returns
    -------
    ndarray, shape (N * 6, 42)
        Row ``6 j + i`` is reading ``i`` at pose ``j``; columns in `PARAMETER_NAMES` order.
    """
    x = np.asarray(poses, dtype=float)
    R = matrix_from_rpy(x[:, 3:])
    lv = geom.leg_vectors_from(R, x[:, :3])
    n = lv / np.linalg.norm(lv, axis=-1, keepdims=True)  # (N, 6, 3)
    npl = np.einsum("nji,nkj->nki", R, n)  # R^T n_i, (N, 6, 3)
    N = x.shape[0]
    J = np.zeros((N, 6, N_PARAMETERS))
    legs = np.arange(6)
    for a in range(3):  # loop over x, y, z: each one a vectorized scatter over poses
        J[:, legs, 3 * legs + a] = -n[:, :, a]
        J[:, legs, 18 + 3 * legs + a] = npl[:, :, a]
    J[:, legs, 36 + legs] = -1.0
    return J.reshape(N * 6, N_PARAMETERS)


def identifiability(
    geom: StewartPlatform, poses: ArrayLike, rtol: float = 1e-10
) -> dict[str, object]:
    """Rank, condition number and singular values of the 42-parameter Jacobian.

    Columns are used as they are (all parameters are lengths in the same unit).

    Returns
    -------
    dict
        ``rank``, ``n_parameters``, ``condition_number``, ``singular_values`` (42,),
        ``unidentifiable``: the parameters dropped by QR with column pivoting beyond the rank.
    """
    from scipy.linalg import qr

    J = identification_jacobian(geom, poses)
    s = np.linalg.svd(J, compute_uv=False)
    rank = int(np.sum(s > rtol * s[0]))
    _, _, piv = qr(J, mode="economic", pivoting=True)
    cond = float(s[0] / s[rank - 1]) if rank else float("inf")
    return {
        "rank": rank,
        "n_parameters": N_PARAMETERS,
        "condition_number": cond,
        "singular_values": s,
        "unidentifiable": [PARAMETER_NAMES[k] for k in piv[rank:]],
    }


def _stats(err: Array) -> dict[str, float]:
    e = np.abs(np.asarray(err, dtype=float)).ravel()
    return {
        "mean": float(e.mean()),
        "rms": float(np.sqrt(np.mean(e**2))),
        "std": float(e.std()),
        "max": float(e.max()),
    }


def pose_prediction_errors(
    geom: StewartPlatform, legs: ArrayLike, true_poses: ArrayLike
) -> dict[str, dict[str, float]]:
    """Probe poses predicted from leg readings by `geom` (Newton FK) vs the true poses.

    Returns
    -------
    dict
        ``position`` statistics (length unit) and ``rotation`` statistics (arcsec).
    """
    x = np.asarray(true_poses, dtype=float)
    fk = geom.forward(legs, x0=x, on_failure="flag")
    Test = transform_from(matrix_from_rpy(fk.poses[:, 3:]), fk.poses[:, :3])
    Tref = transform_from(matrix_from_rpy(x[:, 3:]), x[:, :3])
    rot, pos = pose_errors(Test, Tref)
    return {"position": _stats(pos), "rotation_arcsec": _stats(rot / ARCSEC)}


@dataclass
class StewartCalibrationResult:
    """Identified geometry and error statistics (JSON via `to_dict`).

    Attributes
    ----------
    geometry : StewartPlatform
        Calibrated machine.
    nominal : StewartPlatform
        Starting (nominal) machine.
    std : ndarray, shape (42,)
        Standard errors of the parameters (length unit).
    rank, condition_number : int, float
        Identifiability of the 42 parameters on the calibration poses.
    calibration, validation : dict
        ``n`` and leg-reading error statistics ``before`` / ``after`` (length unit).
    iterations, evaluations : int
    seconds : float
    history : list of float
        RMS leg residual at the start and the end (length unit).
    warnings : list of Diagnostic
        Plausibility diagnostics (`kinecal.calibration.diagnostics.stewart`).
    length_unit : str
        The geometry's length unit (for the text and the JSON).
    outliers : list of int
        0-based calibration poses whose leg residuals are outliers (median/MAD rule).
    bounded : bool
        False when the poses identify fewer parameters than well-spread workspace poses
        (``std`` is then ``inf`` for the undetermined ones).
    errors_before, errors_after : ndarray, shape (N,), optional
        Norm of the six leg residuals of each calibration pose (length unit).

    Notes
    -----
    ``std`` is ``inf`` (``null`` in the JSON) for a parameter the poses cannot identify:
    the covariance is restricted to the combinations they determine
    (`kinecal.calibration.uncertainty`).
    """

    geometry: StewartPlatform
    nominal: StewartPlatform
    std: Array
    rank: int
    condition_number: float
    unidentifiable: list[str]
    calibration: dict
    validation: dict | None
    iterations: int
    evaluations: int
    seconds: float
    history: list[float] = field(default_factory=list)
    warnings: list[Diagnostic] = field(default_factory=list)
    length_unit: str = "m"
    outliers: list[int] = field(default_factory=list)
    bounded: bool = True
    errors_before: Array | None = None
    errors_after: Array | None = None

    def to_dict(self) -> dict:
        """The DESIGN calibration JSON layout, for the Stewart parameters."""
        params = {
            name: {"nominal": float(a), "identified": float(b),
                   "std": float(s) if np.isfinite(s) else None, "free": True}
            for name, a, b, s in zip(
                PARAMETER_NAMES,
                self.nominal.parameters,
                self.geometry.parameters,
                self.std,
                strict=True,
            )
        }
        ref = self.validation if self.validation is not None else self.calibration
        b, a = ref["before"]["rms"], ref["after"]["rms"]
        improve = 100.0 * (1.0 - a / b) if b > 0 else 0.0
        return {
            "model": self.nominal.name,
            "method": "lm",
            "length_unit": self.length_unit,
            "parameters": params,
            "unidentifiable": self.unidentifiable,
            "rank": self.rank,
            "condition_number": self.condition_number,
            "calibration": self.calibration,
            "validation": self.validation,
            "improvement_percent": improve,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "seconds": self.seconds,
            "history": self.history,
            "outliers": [int(i) for i in self.outliers],
            "bounded": bool(self.bounded),
            "warnings": [d.to_dict() for d in self.warnings],
        }

    def summary(self) -> str:
        """Text table of the before/after leg-reading errors (geometry length unit), the
        undetermined parameters and the warnings."""
        u = self.length_unit
        lines = [f"rank {self.rank}/{N_PARAMETERS}, condition {self.condition_number:.3g}"]
        loose = [n for n, s in zip(PARAMETER_NAMES, self.std, strict=True) if not np.isfinite(s)]
        if loose:
            lines.append("not identifiable (value arbitrary, no standard error): "
                         + ", ".join(loose))
        for label, part in (("calibration", self.calibration), ("validation", self.validation)):
            if part is None:
                continue
            b, a = part["before"]["rms"], part["after"]["rms"]
            lines.append(f"{label:12s} n={part['n']:4d}  leg rms before {b:.4g} {u}  "
                         f"after {a:.4g} {u}")
        if self.outliers:
            lines.append(f"outlier poses (0-based): {self.outliers}")
        if self.warnings:
            lines += [f"warnings ({len(self.warnings)}):"]
            lines += [f"  [{d.code}] {d.message}" for d in self.warnings]
        return "\n".join(lines)

    def report(self, path: str | Path) -> Path:
        """Write a self-contained HTML report (`kinecal.report.stewart`); returns its path."""
        from kinecal.report.stewart import stewart_report

        return stewart_report(self, path)


def calibrate_stewart(
    nominal: StewartPlatform,
    data: StewartData,
    *,
    validate: StewartData | None = None,
    max_nfev: int = 100,
    length_unit: str = "m",
) -> StewartCalibrationResult:
    """Identify the 42 parameters by Levenberg-Marquardt on the inverse-kinematics residual.

    Parameters
    ----------
    nominal : StewartPlatform
        Start geometry.
    data : StewartData
        Calibration poses and readings (more than 7 distinct poses for 42 unknowns; 21 or
        more recommended).
    validate : StewartData, optional
        Held-out poses for the before/after statistics.
    max_nfev : int
        Evaluation limit of the solver.
    length_unit : str
        The geometry's length unit (messages, summary and JSON).

    Returns
    -------
    StewartCalibrationResult
        With ``warnings``, also issued as `kinecal.diagnostics.KinecalWarning` unless an
        outer collector (the command line) takes them.

    Raises
    ------
    InputError
        Too few distinct poses (``too-few-poses``).
    """
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate_stewart(nominal, data, validate, max_nfev, length_unit)
    res.warnings = list(found)
    return res


def _calibrate_stewart(nominal: StewartPlatform, data: StewartData,
                       validate: StewartData | None, max_nfev: int,
                       length_unit: str) -> StewartCalibrationResult:
    from kinecal.calibration.diagnostics.stewart import (
        check_stewart_data,
        check_stewart_fit,
    )

    checked = check_stewart_data(nominal, data, validate=validate, unit=length_unit)
    t0 = time.perf_counter()
    info = identifiability(nominal, data.poses, rtol=DATA_RANK_TOL)  # as the checks judge

    def fun(v: Array) -> Array:
        return residuals(nominal.with_parameters(v), data).ravel()

    def jac(v: Array) -> Array:
        return identification_jacobian(nominal.with_parameters(v), data.poses)

    v0 = nominal.parameters
    sol = least_squares(fun, v0, jac=jac, method="lm", x_scale="jac", max_nfev=max_nfev)
    geom = nominal.with_parameters(sol.x)
    rank = int(info["rank"])
    rows = np.arange(sol.fun.size)
    if checked.unique_rows is not None:  # exact copies of a row count once
        rows = (6 * checked.unique_rows[:, None] + np.arange(6)).ravel()
    r, J = sol.fun[rows], sol.jac[rows]
    unc = subspace_uncertainty(J.T @ J, float(r @ r), r.size, rank)
    std = unc.std
    outliers = check_stewart_fit(sol.fun.reshape(-1, 6), rank, checked.reference_rank,
                                 length_unit, list(info["unidentifiable"]))
    calib = {
        "n": len(data),
        "before": _stats(residuals(nominal, data)),
        "after": _stats(sol.fun),
    }
    val = None
    if validate is not None:
        val = {
            "n": len(validate),
            "before": _stats(residuals(nominal, validate)),
            "after": _stats(residuals(geom, validate)),
        }
    return StewartCalibrationResult(
        geometry=geom,
        nominal=nominal,
        std=std,
        rank=int(info["rank"]),
        condition_number=float(info["condition_number"]),
        unidentifiable=list(info["unidentifiable"]),
        calibration=calib,
        validation=val,
        iterations=int(sol.njev),
        evaluations=int(sol.nfev),
        seconds=time.perf_counter() - t0,
        history=[float(np.sqrt(np.mean(fun(v0) ** 2))), float(np.sqrt(np.mean(sol.fun**2)))],
        length_unit=length_unit,
        outliers=outliers,
        bounded=rank >= checked.reference_rank,
        errors_before=np.linalg.norm(residuals(nominal, data), axis=1),
        errors_after=np.linalg.norm(sol.fun.reshape(-1, 6), axis=1),
    )
