"""The identified values of a serial-arm calibration result (``kinecal calibrate --out``) put
back on its model: the helpers of `kinecal.io.results.load_result` and of the commands that
take a result (``fk --params``, ``export``, ``compensate``, ``iso9283 --params``).

A result holds the identified value of every parameter of its model in the model file's
units, not the model itself: reading it needs the nominal model (the bundled model the
result names, or the model file or URDF it was calibrated from).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope, envelope_from_entry
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_rpy

__all__ = ["STEWART_KEYS", "model_for_data", "model_for_result", "parameters_from_data",
           "parameters_from_result", "read_result_envelope", "result_envelope", "result_markers",
           "serial_result_parameters"]

Array = NDArray[np.float64]

#: parameters only a Stewart-platform result has
STEWART_KEYS = {"b1.x", "p1.x"}


def serial_result_parameters(data: object, path: Path) -> dict:
    """The ``parameters`` mapping of a serial-arm calibration result (``calibrate --out``).

    Raises
    ------
    InputError
        A hand-eye or Stewart-platform result (named as such: their JSON is easily passed
        where an arm's result is expected), or JSON without a non-empty ``parameters``.
    """
    params = data.get("parameters") if isinstance(data, dict) else None
    other = None
    if isinstance(data, dict) and "X" in data and params is None:
        other = "a hand-eye calibration result (kinecal handeye)"
    elif isinstance(params, dict) and STEWART_KEYS <= set(params):
        other = "a Stewart-platform calibration result (kinecal stewart calibrate)"
    if other is not None:
        raise InputError(f"{other}, expected a serial-arm calibration result (kinecal "
                         "calibrate --out)", file=path)
    if not isinstance(params, dict) or not params:
        raise InputError("expected a calibration result (kinecal calibrate --out) with a "
                         "non-empty 'parameters' mapping", file=path)
    return params


def result_markers(params: dict) -> list[str]:
    """Marker names of a result's ``tool.NAME.x`` parameters (several markers)."""
    return [n[5:-2] for n in params if n.startswith("tool.") and n.endswith(".x")
            and n.count(".") >= 2]


def model_for_result(model: SerialModel, path: str | Path) -> SerialModel:
    """`model` with what a result file adds to it: the joint-error terms it declares and
    one tool point per marker when it has several markers."""
    path = Path(path)
    return model_for_data(model, read_json(path), path)


def model_for_data(model: SerialModel, data: Any, path: Path) -> SerialModel:
    from kinecal.kinematics.serial.markers import model_for_markers

    params = serial_result_parameters(data, path)
    # the markers first: the terms' reference geometry names the markers' tool points
    model = model_for_markers(model, result_markers(params))
    return _with_result_joint_errors(model, data, path)


def parameters_from_result(model: SerialModel, path: str | Path) -> Array:
    """Full parameter vector from a calibration result JSON (``identified`` values, in the
    Python API's units: the model's length unit and radians).

    Refuses (`InputError`) a result without parameters, with a parameter the model does not
    have, a value that is not a finite number, other units, or nominal values that differ
    from the model's (a result of another model). `model` is the model the result
    calibrated, with its markers and joint-error terms (`model_for_result`).
    """
    path = Path(path)
    return parameters_from_data(model, read_json(path), path)


def parameters_from_data(model: SerialModel, data: Any, path: Path) -> Array:
    params = serial_result_parameters(data, path)
    for key, mine in (("length_unit", model.length_unit), ("angle_unit", model.angle_unit)):
        theirs = data.get(key)
        if theirs is not None and theirs != mine:
            raise InputError(f"the result's {key} is {theirs!r}, model {model.name!r} uses "
                             f"{mine!r}: a result of another model", file=path)
    angle = model.is_angle()
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    p = model.nominal
    if "frames" not in data:  # written before the base and tool were local (docs/conventions)
        params = _absolute_frames(model, params, scale)
    for name, entry in params.items():
        k = model.index([name])[0] if name in model.parameter_names else None
        if k is None:
            raise InputError(f"parameter {name!r} does not belong to model {model.name!r}",
                             file=path)
        conv = scale if angle[k] else 1.0
        try:
            raw = entry["identified"] if isinstance(entry, dict) else entry
            value = float(raw)
            nominal = float(entry["nominal"]) if isinstance(entry, dict) and entry.get(
                "nominal") is not None else None
        except (KeyError, TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'identified'",
                             file=path) from None
        if isinstance(raw, bool) or not np.isfinite(value) or (
                nominal is not None and not np.isfinite(nominal)):
            raise InputError(f"parameter {name!r}: expected a finite number, got {raw!r}",
                             file=path)
        mine = p[k] / conv
        if nominal is not None and abs(nominal - mine) > 1e-6 * max(1.0, abs(mine)):
            raise InputError(f"parameter {name!r} has nominal {nominal:.6g} in the result but "
                             f"{mine:.6g} in model {model.name!r}: a result of another model",
                             file=path)
        p[k] = value * conv
    if "kinecal" in data and isinstance(data.get("free"), list):
        # a result written by calibrate lists every parameter of the chain it calibrated:
        # one without some of this model's is of another chain (a URDF read with other
        # --base-link / --tip-link), whose base frame means something else here
        geometric = model.parameter_names[: getattr(model, "_n_geometric", model.n_params)]
        # an origin's local rotation error (wx, wy, wz) is zero in a result written before
        # origins had one: its roll, pitch and yaw carry the same geometry
        missing = [n for n in geometric if n not in params and not (
            n.rsplit(".", 1)[-1] in ("wx", "wy", "wz") and p[model.index([n])[0]] == 0)]
        if missing:
            raise InputError(
                f"the result has no values for {len(missing)} parameters of model "
                f"{model.name!r} ({', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''})"
                ": it calibrated another chain; give the --base-link / --tip-link (or model) "
                "it was calibrated with", file=path)
    return p


def result_envelope(model: SerialModel, data: Any, path: str | Path) -> JointEnvelope | None:
    """The joint envelope a result stores (``envelope``: per joint the lowest and highest
    calibration reading, model units) for `model`; None when the result has none (written
    before results stored it) or is a robot system's read for one of its chains."""
    entry = data.get("envelope") if isinstance(data, dict) else None
    if entry is None:
        return None
    low = entry.get("low") if isinstance(entry, dict) else None
    if isinstance(low, list) and len(low) != model.n_joints and "system" in data:
        return None  # a robot system's joints, read for one of its chains: not mapped
    try:
        return envelope_from_entry(model, entry)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None


def read_result_envelope(model: SerialModel, path: str | Path) -> JointEnvelope | None:
    """`result_envelope` of a result file."""
    return result_envelope(model, read_json(Path(path)), path)


def _absolute_frames(model: SerialModel, params: dict, scale: float) -> dict:
    """`params` of a result written while ``base.rx .. base.rz`` (and ``tool.rx .. tool.rz``)
    were the frame's absolute roll-pitch-yaw, as this model's local rotation errors about
    its nominal orientation: the same frame. Unchanged where the nominal orientation is
    zero (both readings agree) or the entries are not those of such a result."""
    from kinecal.kinematics.serial.frames import local_rotation

    out = dict(params)
    for prefix, rpy0 in (("base", model.chain.base_rpy), ("tool", model.chain.tool_rpy)):
        names = [f"{prefix}.{k}" for k in ("rx", "ry", "rz")]
        entries = [params.get(n) for n in names]
        if not any(rpy0) or not all(isinstance(e, dict) for e in entries):
            continue
        try:
            old = np.array([float(e["identified"]) for e in entries]) * scale
        except (KeyError, TypeError, ValueError):
            continue  # refused with its name by the caller
        if not np.isfinite(old).all():
            continue
        w = local_rotation(rpy0, matrix_from_rpy(old)) / scale
        for n, e, v in zip(names, entries, w, strict=True):
            out[n] = {**e, "identified": float(v), "nominal": None}
    return out


def _with_result_joint_errors(model: SerialModel, data: Any, path: Path) -> SerialModel:
    """`model` with the joint-error terms a calibration result JSON declares (``joint_errors.
    model``, written by ``--error-model``), so that its parameters fit; else `model`."""
    section = data.get("joint_errors")
    if not isinstance(section, dict) or "model" not in section:
        return model
    from kinecal.io.joint_errors_file import joint_errors_from_file

    plain = dataclasses.replace(model, joint_errors=None)
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    try:
        je = joint_errors_from_file(plain, section["model"], scale)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    return dataclasses.replace(plain, joint_errors=je)
