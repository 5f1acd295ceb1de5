"""Serial-arm model files (YAML): schema, `load_model`, `save_model`.

A model file (see ``docs/file-formats.md``)::

    name: irb120
    convention: hayati            # dh | craig | hayati
    length_unit: mm
    angle_unit: deg               # deg | rad: every angle in this file
    joints:
      - {theta: 0, d: 290, a: 0, alpha: -90}
      - {theta: -90, d: 0, a: 270, alpha: 0, beta: 0}
    base: [x, y, z, rx, ry, rz]   # optional: robot base in the measurement frame
    tool: [x, y, z]               # optional: tool point in the flange frame (or 6 values)
    joint_limits: [[-165, 165], ...]   # optional
    tolerances: {length: 0.25, angle: 0.05}
    fixed: [tool.x]               # optional: parameters held at nominal by default

Bundled models live in ``kinecal/robots/NAME.yaml`` and are loaded by name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from kinecal._files import read_yaml_mapping, write_text_atomic
from kinecal.errors import InputError
from kinecal.io.bundled import bundled_names, resolve_machine_file
from kinecal.kinematics.serial import SerialModel

__all__ = ["ModelFile", "bundled_models", "load_model", "model_path", "read_yaml", "save_model"]


class JointSpec(BaseModel):
    """One joint: D-H values (length unit, angle unit of the file)."""

    model_config = ConfigDict(extra="forbid")
    theta: float = 0.0
    d: float
    a: float
    alpha: float
    beta: float | None = None


class Tolerances(BaseModel):
    """Half-widths of the metaheuristics' search box around nominal."""

    model_config = ConfigDict(extra="forbid")
    length: float = 1.0
    angle: float = 1.0

    @field_validator("length", "angle")
    @classmethod
    def _positive(cls, v: float) -> float:
        if not v > 0:
            raise ValueError("must be > 0")
        return v


class ModelFile(BaseModel):
    """Schema of a serial-arm model file."""

    model_config = ConfigDict(extra="forbid")
    name: str
    description: str = ""
    source: str = ""
    convention: Literal["dh", "craig", "hayati"]
    length_unit: Literal["mm", "m"] = "mm"
    angle_unit: Literal["deg", "rad"]
    joints: list[JointSpec]
    base: list[float] | None = None
    tool: list[float] | None = None
    joint_limits: list[tuple[float, float]] | None = None
    tolerances: Tolerances = Tolerances()
    fixed: list[str] = []

    @field_validator("joints")
    @classmethod
    def _some_joints(cls, v: list[JointSpec]) -> list[JointSpec]:
        if not v:
            raise ValueError("at least one joint is required")
        return v

    @field_validator("base")
    @classmethod
    def _base6(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) != 6:
            raise ValueError(f"expected 6 values [x, y, z, rx, ry, rz], got {len(v)}")
        return v

    @field_validator("tool")
    @classmethod
    def _tool36(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) not in (3, 6):
            raise ValueError(f"expected 3 values [x, y, z] or 6 with rx, ry, rz, got {len(v)}")
        return v


def bundled_models() -> list[str]:
    """Names of the bundled serial-arm models."""
    return bundled_names("model")


def model_path(name_or_path: str | Path) -> Path:
    """Path of a model file given a bundled name or a path; `InputError` if neither."""
    return resolve_machine_file(name_or_path, "model")


def read_yaml(path: Path) -> dict:
    """Read a YAML mapping; `InputError` with the file (and line) when unreadable."""
    return read_yaml_mapping(path)


def _validation_message(exc: ValidationError) -> str:
    err = exc.errors()[0]
    loc = ".".join(str(x) for x in err["loc"])
    return f"{loc}: {err['msg']}"


def load_model(name_or_path: str | Path) -> SerialModel:
    """Load a serial-arm model from a bundled name (``irb120``) or a YAML path.

    Angles are converted to radians; lengths stay in the file's unit.

    Raises
    ------
    InputError
        Unknown name, unreadable file, or a schema violation (named key and reason).
    """
    path = model_path(name_or_path)
    data = read_yaml(path)
    try:
        spec = ModelFile.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"invalid model file: {_validation_message(exc)}", file=path) from None
    scale = np.pi / 180.0 if spec.angle_unit == "deg" else 1.0
    joints = []
    for j in spec.joints:
        joint = {"theta": j.theta * scale, "d": j.d, "a": j.a, "alpha": j.alpha * scale}
        if j.beta is not None:
            if spec.convention != "hayati":
                raise InputError(
                    "invalid model file: beta is only allowed with convention hayati", file=path
                )
            joint["beta"] = j.beta * scale
        joints.append(joint)
    base = None if spec.base is None else np.r_[spec.base[:3], np.asarray(spec.base[3:]) * scale]
    tool = None
    if spec.tool is not None:
        tool = np.r_[spec.tool[:3], np.asarray(spec.tool[3:]) * scale]
    limits = None if spec.joint_limits is None else np.asarray(spec.joint_limits) * scale
    if limits is not None and limits.shape[0] != len(joints):
        raise InputError(
            f"invalid model file: joint_limits has {limits.shape[0]} rows, expected {len(joints)}",
            file=path,
        )
    try:
        return SerialModel(
            name=spec.name, convention=spec.convention, joints=joints, base=base, tool=tool,
            length_unit=spec.length_unit, angle_unit=spec.angle_unit, joint_limits=limits,
            tolerances={"length": spec.tolerances.length, "angle": spec.tolerances.angle * scale},
            fixed=tuple(spec.fixed), description=spec.description,
        )
    except InputError as exc:
        raise InputError(f"invalid model file: {exc.message}", file=path) from None


def model_to_dict(model: SerialModel, angle_unit: str = "deg") -> dict:
    """The model-file mapping of `model` (angles in `angle_unit`)."""
    s = 180.0 / np.pi if angle_unit == "deg" else 1.0
    angle_keys = ("theta", "alpha", "beta")
    joints = [{k: float(v) * (s if k in angle_keys else 1.0) for k, v in j.items()}
              for j in model.joints]
    data: dict = {
        "name": model.name,
        "description": model.description,
        "convention": model.convention,
        "length_unit": model.length_unit,
        "angle_unit": angle_unit,
        "joints": joints,
    }
    if model.base is not None:
        b = np.asarray(model.base, dtype=float)
        data["base"] = [float(x) for x in np.r_[b[:3], b[3:] * s]]
    if model.tool is not None:
        t = np.asarray(model.tool, dtype=float)
        data["tool"] = [float(x) for x in np.r_[t[:3], t[3:] * s]]
    data["joint_limits"] = [[float(lo * s), float(hi * s)] for lo, hi in model.joint_limits]
    tol = model.tolerances or {}
    data["tolerances"] = {"length": float(tol["length"]), "angle": float(tol["angle"] * s)}
    if model.fixed:
        data["fixed"] = sorted(model.fixed)
    return data


def save_model(model: SerialModel, path: str | Path, angle_unit: str | None = None) -> None:
    """Write `model` as a model file that `load_model` reads back (atomic write).

    Angles are written in `angle_unit` (default: the model's own file unit).
    """
    angle_unit = angle_unit or model.angle_unit
    text = yaml.safe_dump(model_to_dict(model, angle_unit), sort_keys=False, width=100)
    write_text_atomic(path, text)
