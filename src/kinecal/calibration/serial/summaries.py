"""Before/after statistics of a serial calibration and its result's extras.

Kept apart from `kinecal.calibration.serial.api` (the entry point) so that it stays a short
read: the distance, per-axis and orientation error statistics on calibration and validation
poses, and the method- and data-dependent entries of ``CalibrationResult.extra``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel
from kinecal.metrology.stats import axis_stats, error_stats
from kinecal.spatial import rotation_angle

__all__ = ["result_extra", "validation_errors"]


def _rotation_stats(model: SerialModel, data: Measurements, params: np.ndarray) -> dict:
    """Before/after statistics of the geodesic orientation errors (degrees)."""
    R_meas = np.swapaxes(np.asarray(data.rotations), 1, 2)
    out = {}
    for when, p in (("before", None), ("after", params)):
        err = np.degrees(rotation_angle(model.fk(data.q, p, data.marker)[:, :3, :3] @ R_meas))
        out[when] = error_stats(err)
    return out

def validation_errors(model: SerialModel, validate: Measurements | None, params: np.ndarray,
                axes: dict) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Validation distance errors before/after (None without validation poses); their
    per-axis statistics go into `axes`."""
    if validate is None:
        return None, None
    vq, vm = validate.q, validate.marker
    ev0 = model.positions(vq, None, vm) - validate.xyz
    ev1 = model.positions(vq, params, vm) - validate.xyz
    axes["validation"] = {"before": axis_stats(ev0), "after": axis_stats(ev1)}
    return np.linalg.norm(ev0, axis=1), np.linalg.norm(ev1, axis=1)

def result_extra(res, names, model, data, validate, params, axes, noise, info, loss) -> dict:
    """The result's ``extra``: what only some methods and data produce."""
    extra: dict[str, Any] = {}
    rotation = {}
    if data.rotations is not None:
        rotation["calibration"] = _rotation_stats(model, data, params)
    if validate is not None and validate.rotations is not None:
        rotation["validation"] = _rotation_stats(model, validate, params)
    if "singular" in res:  # Householder: directions where J^T J was singular
        extra["singular_parameters"] = [names[i] for i in res.singular]
    if rotation:  # measured orientations: rotation errors in degrees
        extra["rotation_deg"] = rotation
    extra["axis_errors"] = axes  # per-axis position errors (x, y, z), model - measured
    if noise is not None:  # the stated noise: chi-square test, known-noise standard errors
        extra["noise"] = noise
    if data.sigma is not None and data.sigma_floor is not None:  # rows weighted per axis
        extra["row_weights"] = {"floor_position": float(data.sigma_floor[0]),
                                "floor_rotation_rad": float(data.sigma_floor[1]),
                                "weight": "c / (s^2 + floor^2), mean position weight 1"}
    if info.unique_rows is not None:  # exact copies of rows: counted once in the covariance
        extra["independent_poses"] = len(info.unique_rows)
    if loss != "linear":
        extra["loss"] = loss
    if "search_box" in res:  # metaheuristics: the box searched (calibration.serial.box)
        extra["search_box"] = {"box": res.search_box["box"]} | {
            side: dict(zip(names, res.search_box[side], strict=True))
            for side in ("lower", "upper")}
    if "ls_history" in res:  # hybrid: the least-squares stage before the metaheuristic
        extra["least_squares_history"] = [float(h) for h in res.ls_history]
        extra["least_squares_iterations"] = int(res.ls_iterations)
    return extra


def conditions_of(data: Measurements, validate: Measurements | None) -> dict:
    """The ``conditions`` of a result: the temperature and time columns of the calibration
    poses, and of the validation poses (keys prefixed ``validation_``)."""
    out = {}
    for prefix, d in (("", data), ("validation_", validate)):
        for name in ("temperature", "time"):
            v = None if d is None else getattr(d, name, None)
            if v is not None:
                out[prefix + name] = np.asarray(v, dtype=float)
    return out
