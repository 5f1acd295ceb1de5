"""The ``joint_errors`` section of a serial-arm model file (schema, read, write).

::

    joint_errors:
      gravity: [0, 0, -1]          # gravity direction in the robot base frame (default -z)
      compliance: all              # joints with gravity compliance: all, none or [2, 3, 4]
      masses:                      # optional mass model; without it, the generic basis
        - {joint: 2, mass: 8.393, com: [212.5, 0, 113.4]}   # com in that link's frame
        - {joint: 3, mass: 2.275, com: [119.9, 0, 26.5]}
      payload: {mass: 1.2, com: [0, 0, 40]}   # com in the flange frame (omit: tool point)
      harmonics: 2                 # order H of a_jh sin(h q_j) + b_jh cos(h q_j)
      harmonic_joints: all         # default: every revolute joint
      scale: [1, 2, 3]             # joints with an encoder-scale term s_j q_j
      values: {dq2.sin1: 0.0012, dq2.compliance.link3: 1.5e-07}   # coefficient values
      reference: {d1: 89.159, a2: -425.0}    # geometry the gravity forces are computed on
      envelope: {low: [-170, -120, ...], high: [170, 10, ...]}   # readings fitted on

Coefficients are named as in `kinecal.kinematics.serial.joint_errors`. Angle-valued coefficients
(harmonics, compliance of revolute joints) and the angles in ``reference`` are in the
file's ``angle_unit``; compliance is an angle per (mass x length unit) of gravity load;
scale coefficients are dimensionless. Absent values are 0. ``reference`` is written by
``kinecal calibrate --model-out`` so that the calibrated model computes the gravity forces
on the geometry it was calibrated with (its own nominal geometry when omitted).
``envelope`` (per joint the lowest and highest reading of the calibration poses, revolute
joints in the file's angle unit, prismatic ones in its length unit) is written by the
calibration too: beyond it the terms are held at the edge
(`kinecal.kinematics.serial.joint_errors_envelope`); without it they apply everywhere.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError, field_validator

from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import JointErrors, PointMass
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC

__all__ = ["JointErrorsSpec", "joint_errors_from_file", "joint_errors_to_file"]

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)

Joints = Literal["all", "none"] | list[int]


def _non_negative(v: float) -> float:
    if v < 0:
        raise ValueError("must be >= 0")
    return v


#: a mass (mass unit of the compliance coefficients), >= 0
Mass = Annotated[float, AfterValidator(_non_negative)]


class MassSpec(BaseModel):
    """A link mass: the joint whose link carries it, its mass and centre of mass."""

    model_config = _STRICT
    joint: int
    mass: Mass
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)


class PayloadSpec(BaseModel):
    """The payload: mass and centre of mass in the flange frame (None: the tool point)."""

    model_config = _STRICT
    mass: Mass
    com: tuple[float, float, float] | None = None


class JointErrorsSpec(BaseModel):
    """Schema of the ``joint_errors`` section (module docstring)."""

    model_config = _STRICT
    gravity: tuple[float, float, float] = (0.0, 0.0, -1.0)
    compliance: Joints = "none"
    masses: list[MassSpec] | None = None
    payload: PayloadSpec | None = None
    harmonics: int = 0
    harmonic_joints: Joints = "all"
    scale: Joints = "none"
    values: dict[str, float] = {}
    reference: dict[str, float] | None = None
    envelope: dict[str, list[float]] | None = None

    @field_validator("harmonics")
    @classmethod
    def _order(cls, v: int) -> int:
        if v < 0:
            raise ValueError("expected an order >= 0")
        return v


def _joints(value, all_joints: tuple[int, ...]) -> tuple[int, ...]:
    if value == "all":
        return all_joints
    if value == "none":
        return ()
    return tuple(int(j) for j in value)


def joint_errors_from_file(model: SerialModel, raw: object, angle_scale: float) -> JointErrors:
    """`JointErrors` of a model file's ``joint_errors`` mapping for `model` (its chain).

    Parameters
    ----------
    model : SerialModel
        The model's geometry (no joint errors yet): joint kinds and parameter names.
    raw : mapping
        The YAML section.
    angle_scale : float
        File angle unit to rad (``pi / 180`` for ``deg``).

    Raises
    ------
    InputError
        Schema violations and unknown names, as ``joint_errors.KEY: reason``.
    """
    try:
        spec = JointErrorsSpec.model_validate(raw)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        raise InputError(f"joint_errors.{loc}: {err['msg']}") from None
    joints = tuple(range(1, model.n_joints + 1))
    revolute = tuple(j for j, k in zip(joints, model.joint_kinds, strict=True)
                     if k != PRISMATIC)
    masses = None if spec.masses is None else tuple(
        PointMass(m.joint, m.mass, m.com) for m in spec.masses)
    payload = None if spec.payload is None else PointMass(model.n_joints, spec.payload.mass,
                                                          spec.payload.com)
    shape = JointErrors(
        compliance=_joints(spec.compliance, joints), harmonics=spec.harmonics,
        harmonic_joints=_joints(spec.harmonic_joints, revolute) if spec.harmonics else (),
        scale=_joints(spec.scale, joints), gravity=spec.gravity, masses=masses,
        payload=payload)
    terms = dataclasses.replace(model, joint_errors=shape)  # names and units of the terms
    n_geo = model.n_params
    names = terms.parameter_names[n_geo:]
    angle = dict(zip(names, terms.is_angle()[n_geo:].tolist(), strict=True))
    unknown = [k for k in spec.values if k not in angle]
    if unknown:
        raise InputError(f"joint_errors.values: {unknown[0]!r} is not a term of this model "
                         f"(terms: {', '.join(names) or 'none'})")
    values = {k: v * angle_scale if angle[k] else v for k, v in spec.values.items()}
    reference = None
    if spec.reference is not None:
        geo_angle = dict(zip(model.parameter_names, model.is_angle().tolist(), strict=True))
        bad = [k for k in spec.reference if k not in geo_angle]
        if bad:
            raise InputError(f"joint_errors.reference: {bad[0]!r} is not a parameter of "
                             f"this model")
        reference = {k: v * angle_scale if geo_angle[k] else v
                     for k, v in spec.reference.items()}
    envelope = None
    if spec.envelope is not None:
        envelope = JointEnvelope.from_dict(
            spec.envelope, _reading_scale(model, angle_scale),
            [k != PRISMATIC for k in model.joint_kinds], "joint_errors.envelope")
    return dataclasses.replace(shape, values=values, reference=reference, envelope=envelope)


def _reading_scale(model: SerialModel, angle_scale: float) -> list[float]:
    """Per joint, rad to the file's unit of a reading (revolute; `angle_scale` is file unit
    to rad) or 1 (prismatic)."""
    return [1.0 if k == PRISMATIC else 1.0 / angle_scale for k in model.joint_kinds]


def joint_errors_to_file(model: SerialModel, angle_scale: float) -> dict:
    """The ``joint_errors`` mapping of `model` (angles times `angle_scale`, rad to file).

    Every coefficient's value is written (zeros included); ``reference`` only with
    compliance terms whose gravity forces are computed on another geometry than the
    model's own (a calibrated model: the geometry it was calibrated from).
    """
    je = model.joint_errors
    terms = model._joint_terms
    n_geo = model._n_geometric
    joints = tuple(range(1, model.n_joints + 1))
    out: dict = {"gravity": [float(v) for v in je.gravity]}
    out["compliance"] = "all" if je.compliance == joints else list(je.compliance)
    if je.masses is not None:
        out["masses"] = [{"joint": m.joint, "mass": float(m.mass),
                          "com": [float(c) for c in m.com or (0.0, 0.0, 0.0)]}
                         for m in je.masses]
    if je.payload is not None:
        out["payload"] = {"mass": float(je.payload.mass)}
        if je.payload.com is not None:
            out["payload"]["com"] = [float(c) for c in je.payload.com]
    out["harmonics"] = int(je.harmonics)
    if je.harmonics:
        out["harmonic_joints"] = list(je.harmonic_joints)
    out["scale"] = "all" if je.scale == joints else list(je.scale)
    angle = model.is_angle()
    nominal = model.nominal
    out["values"] = {n: float(nominal[n_geo + k] * (angle_scale if angle[n_geo + k] else 1.0))
                     for k, n in enumerate(terms.names)}
    own = dict(zip(model.parameter_names[:n_geo], nominal[:n_geo].tolist(), strict=True))
    ref = terms.reference
    if je.compliance and any(ref[k] != own[k] for k in ref):
        out["reference"] = {k: float(v * (angle_scale if angle[model.index([k])[0]] else 1.0))
                            for k, v in ref.items() if not k.startswith("base.")}
    if je.envelope is not None:
        out["envelope"] = je.envelope.to_dict(_reading_scale(model, 1.0 / angle_scale))
    return out
