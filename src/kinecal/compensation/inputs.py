"""Inputs of a compensation, checked: the nominal and calibrated models, the program's
joints and Cartesian targets, and the calibrated base frame's distance from nominal."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.calibration.serial.inputs import as_calibrated, as_model, is_path
from kinecal.compensation.findings import outside_limits_message
from kinecal.compensation.same_arm import Registration, in_length_unit
from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import TOOL_NAMES
from kinecal.kinematics.serial.ik import characteristic_length
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import check_transform, transform_from_pq

__all__ = ["BASE_FAR_ANGLE", "BASE_FAR_LENGTH", "TOOL_FAR_LENGTH", "TOOL_FAR_TOLERANCES",
           "check_base", "check_tool", "program_joints", "program_models", "program_targets",
           "with_nominal_tool"]

Array = NDArray[np.float64]

#: calibrated base this far from nominal (fraction of the arm's length, rad): warn
BASE_FAR_LENGTH = 0.05
BASE_FAR_ANGLE = 0.1


def check_base(nominal: SerialModel, reg: Registration, warn: Any) -> None:
    """Warn (``base-frame-far``) when the registration `reg` of the calibrated arm onto
    the nominal one moves the base by more than `BASE_FAR_LENGTH` of the arm or
    `BASE_FAR_ANGLE` rad; `warn` is `kinecal.diagnostics.warn` or a silent stand-in."""
    L = characteristic_length(nominal)
    if reg.shift > BASE_FAR_LENGTH * L or reg.turn > BASE_FAR_ANGLE:
        warn(
            "base-frame-far",
            f"the calibrated base frame is {reg.shift:.4g} {nominal.length_unit} and "
            f"{np.degrees(reg.turn):.3g} deg from the nominal one: the measurements were "
            "probably taken in an instrument's frame, not the robot's; compensate with "
            "base='nominal' (--base nominal) unless the program's poses are in that frame")


TOOL_POINT = TOOL_NAMES[:3]

#: calibrated tool point this far from nominal (the larger of a fraction of the arm's
#: length and a number of length tolerances): it is probably a measurement target
TOOL_FAR_LENGTH = 0.01
TOOL_FAR_TOLERANCES = 10.0


def _tool_names(model: SerialModel) -> list[str]:
    return [n for n in model.parameter_names if n.startswith("tool.")]


def check_tool(nominal: SerialModel, calibrated: SerialModel, warn: Any) -> None:
    """Warn (``tool-point-far``) when the calibrated tool point lies further from the
    nominal one than `TOOL_FAR_LENGTH` of the arm and `TOOL_FAR_TOLERANCES` length
    tolerances: a calibration identifies where its *target* sits (a tracker reflector),
    which compensation would then move to the program's poses instead of the program's
    tool. Compared only when both models have the same parameters."""
    names = [n for n in _tool_names(nominal) if n in TOOL_POINT]
    if not names or list(calibrated.parameter_names) != list(nominal.parameter_names):
        return
    idx = nominal.index(names)
    d = float(np.linalg.norm(calibrated.nominal[idx] - nominal.nominal[idx]))
    tol = float((nominal.tolerances or {}).get("length", 0.0))
    limit = max(TOOL_FAR_LENGTH * characteristic_length(nominal), TOOL_FAR_TOLERANCES * tol)
    if d > limit:
        warn("tool-point-far",
             f"the calibrated tool point is {d:.4g} {nominal.length_unit} from the nominal "
             "one: if it is the calibration's measurement target (a tracker reflector) and "
             "not the program's tool, compensate with tool='nominal' (--tool nominal: the "
             "nominal tool on the calibrated arm)")


def with_nominal_tool(calibrated: SerialModel, nominal: SerialModel) -> SerialModel:
    """`calibrated` with the nominal model's tool (point and frame): the program's tool on
    the calibrated arm, when the calibration measured another target (or several: the
    markers of a calibration with several tracker targets are replaced by that tool)."""
    if calibrated.marker_names and not nominal.marker_names:
        calibrated = dataclasses.replace(
            calibrated, markers=None, tool=None if nominal.tool is None else np.array(
                nominal.tool, dtype=float), joint_limits=np.array(calibrated.joint_limits),
            tolerances=dict(calibrated.tolerances or {}),
            fixed=tuple(f for f in calibrated.fixed if not f.startswith("tool.")))
    if list(calibrated.parameter_names) != list(nominal.parameter_names):
        raise InputError(
            "tool='nominal' needs a calibrated model with the nominal model's parameters (a "
            "result JSON or a --model-out file of it), not another description of the arm",
            option="--tool")
    if calibrated.marker_names:
        raise InputError("tool='nominal' needs a nominal model with the program's tool, not "
                         "markers: give nominal= the model the controller runs (--nominal)",
                         option="--tool")
    idx = nominal.index(_tool_names(nominal))
    p = calibrated.nominal
    p[idx] = nominal.nominal[idx]
    return calibrated.with_params(p, name=calibrated.name)


def program_models(calibrated: Any, nominal: SerialModel | None) -> tuple[SerialModel, SerialModel]:
    """(nominal, calibrated) from a model, a CalibrationResult or a parameter vector; a
    model file, a result JSON or a bundled name given as a path is loaded (`as_calibrated`,
    `as_model`)."""
    if nominal is not None:
        nominal = as_model(nominal, "nominal")
    calibrated = as_calibrated(calibrated, nominal)
    if hasattr(calibrated, "nominal_model") and hasattr(calibrated, "model"):  # a result
        nom = calibrated.nominal_model if nominal is None else nominal
        cal = calibrated.model
    elif isinstance(calibrated, SerialModel):
        if nominal is None:
            raise InputError("compensate needs the nominal model (what the controller runs) "
                             "beside a calibrated model", option="--nominal")
        nom, cal = nominal, calibrated
    elif isinstance(calibrated, dict) or np.asarray(calibrated).dtype.kind not in "biuf":
        raise TypeError(f"calibrated: expected a SerialModel, a CalibrationResult (or "
                        "kinecal.load_result), a model or result file path or a parameter "
                        f"vector, got {type(calibrated).__name__}")
    else:
        if nominal is None:
            raise InputError("a calibrated parameter vector needs its nominal model",
                             option="--nominal")
        p = np.asarray(calibrated, dtype=float)
        if p.shape != (nominal.n_params,) or not np.isfinite(p).all():
            raise InputError(f"calibrated parameters: expected {nominal.n_params} finite "
                             f"values, got shape {p.shape}")
        nom = nominal
        cal = nominal.with_params(p, name=f"{nominal.name}-calibrated")
    if not isinstance(nom, SerialModel):
        raise InputError(f"nominal: expected a SerialModel, got {type(nom).__name__}")
    return nom, in_length_unit(cal, nom.length_unit)


def program_targets(targets: ArrayLike) -> Array:
    """(N, 3) points, (N, 7) x,y,z,qw,qx,qy,qz or (N, 4, 4) frames -> (N, 3) / (N, 4, 4)."""
    if is_path(targets):
        raise TypeError("targets: expected an array (N, 3), (N, 7) or (N, 4, 4); read a "
                        "targets CSV with kinecal.io.csvtable.read_table")
    t = np.asarray(targets, dtype=float)
    if t.ndim == 2 and t.shape[1] == 7:
        q = t[:, 3:]
        norm = np.linalg.norm(q, axis=1)
        bad = np.abs(norm - 1.0) > 1e-3
        if bad.any() or not np.isfinite(t).all():
            row = int(np.argmax(bad | ~np.isfinite(t).all(axis=1))) + 1
            raise InputError("targets: qw, qx, qy, qz must be a unit quaternion", row=row)
        return transform_from_pq(np.column_stack([t[:, :3], q / norm[:, None]]))
    if t.ndim == 2 and t.shape[1] == 3:
        if not np.isfinite(t).all():
            raise InputError("targets contain NaN or infinite values")
        return t
    if t.ndim == 3 and t.shape[1:] == (4, 4):
        return check_transform(t, name="target")
    raise InputError(f"targets: expected (N, 3) points, (N, 7) x,y,z,qw,qx,qy,qz or (N, 4, 4) "
                     f"frames, got shape {t.shape}")


def program_joints(model: SerialModel, q: ArrayLike, what: str, warn: Any) -> Array:
    """Joint values `q` ``(N, n_joints)`` (or one row) of `what` (program joints, seed
    joints), finite; rows outside the joint limits warn (``joints-outside-limits``)."""
    if is_path(q):
        raise TypeError(f"{what}: expected an array (N, {model.n_joints}) in radians; read a "
                        "joints CSV with kinecal.io.measurements.read_joints(path, model)")
    a = np.asarray(q, dtype=float)
    if a.ndim == 1 and a.size == model.n_joints:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != model.n_joints:
        raise InputError(f"{what}: expected (N, {model.n_joints}) joint values, got shape "
                         f"{np.shape(q)}")
    if not np.isfinite(a).all():
        raise InputError(f"{what} contain NaN or infinite values",
                         row=int(np.argmax(~np.isfinite(a).all(axis=1))) + 1)
    lim = model.joint_limits
    out = (a < lim[:, 0]) | (a > lim[:, 1])
    if out.any():
        rows = np.flatnonzero(out.any(axis=1))
        warn("joints-outside-limits", outside_limits_message(rows.size, rows[0] + 1, what))
    return a

