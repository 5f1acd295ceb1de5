"""Geometry calibration of the parallel-link CMM (papers/004 machine, DESIGN section 5).

The 42 parameters (`kinecal.kinematics.stewart.platform.PARAMETER_NAMES`): base joints ``b_i``
(18), platform joints ``p_i`` (18) and leg offsets ``o_i`` (6). The probe offset ``ls``
is held at its nominal value: it only enters through ``p_i - s`` (papers/004 eq. 4), so a
change of ``ls`` is the same as moving all ``p_i`` along z.

Data: measured probe poses (e.g. from a laser tracker or a calibrated artefact) and the
machine's leg readings at those poses (`kinecal.calibration.stewart.data`). The
identification residual is the inverse kinematics, with an analytic, block-structured
Jacobian (`kinecal.calibration.stewart.identification`); `calibrate_stewart` solves it by
Levenberg-Marquardt and returns a `StewartCalibrationResult`
(`kinecal.calibration.stewart.result`). This module is the entry point and re-exports
those names.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal._blas import small_products
from kinecal.calibration.diagnostics.stewart import (
    DATA_RANK_TOL,
    check_stewart_data,
    check_stewart_fit,
)
from kinecal.calibration.stewart.data import (
    ARCSEC,
    StewartData,
    perturb_geometry,
    simulate_stewart,
)
from kinecal.calibration.stewart.identification import (
    identifiability,
    identification_jacobian,
    residuals,
)
from kinecal.calibration.stewart.result import (
    StewartCalibrationResult,
    abs_stats,
    pose_prediction_errors,
)
from kinecal.calibration.uncertainty import subspace_uncertainty
from kinecal.kinematics.stewart.platform import StewartPlatform

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


@small_products
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
    checked = check_stewart_data(nominal, data, validate=validate, unit=length_unit)
    t0 = time.perf_counter()
    info = identifiability(nominal, data.poses, rtol=DATA_RANK_TOL)  # as the checks judge

    def fun(v: Array) -> Array:
        return residuals(nominal.with_parameters(v), data).ravel()

    def jac(v: Array) -> Array:
        return identification_jacobian(nominal.with_parameters(v), data.poses)

    v0 = nominal.parameters
    from scipy.optimize import least_squares

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
        "before": abs_stats(residuals(nominal, data)),
        "after": abs_stats(sol.fun),
    }
    val = None
    if validate is not None:
        val = {
            "n": len(validate),
            "before": abs_stats(residuals(nominal, validate)),
            "after": abs_stats(residuals(geom, validate)),
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
