"""The unmodelled error ``tau`` of tracker sets with per-axis standard deviations in a
stacked problem (`kinecal.calibration.serial.row_weights`): the first fit leaves their rows
unweighted; ``tau`` comes from each set's residual there, and the fit is repeated with the
rows weighted ``1 / (s^2 + tau^2)``."""

from __future__ import annotations

import dataclasses

import numpy as np

from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.serial.row_weights import estimate_floor, sigma_row_scale

__all__ = ["set_sigma_floors"]


def set_sigma_floors(problem: StackedProblem, x: np.ndarray) -> bool:
    """Estimate ``tau`` of every tracker block with standard deviations and no floor yet
    at the solution `x` and weight its rows with it; True when any block changed."""
    residuals = problem.block_residuals(x)
    changed = False
    for b, r in zip(problem.blocks, residuals, strict=True):
        data = getattr(b, "data", None)
        if b.kind != "tracker" or data is None or data.sigma is None or \
                data.sigma_floor is not None:
            continue
        e = np.asarray(r, dtype=float).reshape(-1, b.rows)
        rot = e[:, 3:] / b.rotation_weight if b.rows == 6 else None
        k = problem.k * b.n_rows / max(problem.m, 1) + b.n_nuisance
        tau = estimate_floor(e[:, :3], rot, data.sigma, round(k))
        b.data = dataclasses.replace(data, sigma_floor=tau)
        b._scale = sigma_row_scale(b.data, b.rotation_weight or 1.0)
        changed = True
    return changed
