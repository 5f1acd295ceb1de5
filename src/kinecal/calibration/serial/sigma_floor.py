"""The unmodelled error ``tau`` that the per-axis standard deviations of a tracker file are
weighted with (`kinecal.calibration.serial.row_weights`): one fit without them, its
residual rows, ``tau`` per row kind."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from kinecal.calibration.serial.row_weights import estimate_floor
from kinecal.calibration.serial.solve import solve_lm
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["with_sigma_floor"]


def with_sigma_floor(model: SerialModel, data: Measurements, free: str | Sequence[str], *,
                     rank_tol: float, rotation_weight: float | None = None) -> Measurements:
    """`data` with ``sigma_floor`` estimated from a Levenberg-Marquardt fit of `free`
    without the standard deviations (`data` itself when it has none, or a floor)."""
    if data.sigma is None or data.sigma_floor is not None:
        return data
    plain = dataclasses.replace(data, sigma=None)
    sol = solve_lm(model, plain, free, rank_tol=rank_tol, rotation_weight=rotation_weight)
    x = sol.result.x
    rot = sol.problem.rotation_errors(x) if data.rotations is not None else None
    tau = estimate_floor(sol.problem.errors(x), rot, data.sigma, len(sol.names))
    return dataclasses.replace(data, sigma_floor=tau)
