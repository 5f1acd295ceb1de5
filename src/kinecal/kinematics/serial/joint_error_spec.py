"""The description of a model's joint-error terms: `JointErrors`, `PointMass`.

Which terms a model has (gravity compliance, harmonics of order ``H``, joint scale), on
which joints, with which gravity direction and mass model, their coefficient values and
the reference geometry of the gravity forces. `kinecal.kinematics.serial.joint_errors` binds it
to a model's chain (`JointErrorTerms`) and computes the corrections.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.motions import PRISMATIC

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["FAMILIES", "JointErrors", "PointMass", "joint_errors_for"]

#: the term families, in the order their coefficients are appended
FAMILIES = ("compliance", "harmonic", "scale")


@dataclass(frozen=True)
class PointMass:
    """A mass of the mass model.

    Attributes
    ----------
    joint : int
        1-based joint whose link carries the mass (the link moved by that joint).
    mass : float
        Mass (any consistent unit, e.g. kg).
    com : tuple of 3 floats
        Centre of mass in that link's frame (the frame at the end of the joint's chain
        entry), length unit. For the payload: in the flange frame, None for the tool point.
    """

    joint: int
    mass: float
    com: tuple[float, float, float] | None = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class JointErrors:
    """Which joint-error terms a model has, their values and the data they need.

    Attributes
    ----------
    compliance : tuple of int
        1-based joints with gravity compliance.
    harmonics : int
        Order ``H`` of the harmonic terms (0: none).
    harmonic_joints : tuple of int
        1-based revolute joints with harmonic terms.
    scale : tuple of int
        1-based joints with a scale term.
    gravity : tuple of 3 floats
        Gravity direction in the robot base frame (normalised; default -z).
    masses : tuple of PointMass or None
        Mass model (link masses); None: the generic basis.
    payload : PointMass or None
        Payload of the mass model (its ``joint`` is ignored; ``com`` in the flange frame,
        None for the tool point).
    values : mapping of str to float
        Coefficient values (rad-based: angles in rad, compliance in rad per mass x length);
        absent names are 0.
    reference : mapping of str to float or None
        The geometry the gravity forces are computed on (parameter name -> value, rad);
        None: the model's own nominal geometry. A calibrated model keeps the reference of
        the model it was calibrated from, so that it reproduces the calibration exactly.
    envelope : JointEnvelope or None
        The joint readings the coefficients were fitted on: beyond them every term is held
        at the edge (`kinecal.kinematics.serial.joint_errors_envelope`). None: the terms
        apply as they are at any reading.
    """

    compliance: tuple[int, ...] = ()
    harmonics: int = 0
    harmonic_joints: tuple[int, ...] = ()
    scale: tuple[int, ...] = ()
    gravity: tuple[float, float, float] = (0.0, 0.0, -1.0)
    masses: tuple[PointMass, ...] | None = None
    payload: PointMass | None = None
    values: Mapping[str, float] = field(default_factory=dict)
    reference: Mapping[str, float] | None = None
    envelope: JointEnvelope | None = None

    def __post_init__(self) -> None:
        g = np.asarray(self.gravity, dtype=float)
        norm = float(np.linalg.norm(g)) if g.shape == (3,) else 0.0
        if not (np.isfinite(g).all() and norm > 0):
            raise InputError(f"joint_errors.gravity: expected a non-zero direction "
                             f"[x, y, z], got {self.gravity!r}")
        object.__setattr__(self, "gravity", tuple(float(v) for v in g / norm))
        if not isinstance(self.harmonics, int | np.integer) or self.harmonics < 0:
            raise InputError(f"joint_errors.harmonics: expected an order >= 0, got "
                             f"{self.harmonics!r}")
        for key in ("compliance", "harmonic_joints", "scale"):
            object.__setattr__(self, key, tuple(int(j) for j in getattr(self, key)))
        if self.masses is not None:
            object.__setattr__(self, "masses", tuple(self.masses))
        for name, v in self.values.items():
            if not np.isfinite(float(v)):
                raise InputError(f"joint_errors.values.{name}: expected a finite number")

    @property
    def families(self) -> tuple[str, ...]:
        """The families present (`FAMILIES` order)."""
        have = {"compliance": bool(self.compliance),
                "harmonic": bool(self.harmonics and self.harmonic_joints),
                "scale": bool(self.scale)}
        return tuple(f for f in FAMILIES if have[f])

    def with_values(self, values: Mapping[str, float],
                    reference: Mapping[str, float] | None = None) -> JointErrors:
        """A copy with coefficient `values` (and `reference`, if given)."""
        return replace(self, values=dict(values),
                       reference=self.reference if reference is None else dict(reference))

    def within(self, envelope: JointEnvelope | None) -> JointErrors:
        """A copy whose terms are held at the edges of `envelope` (None: nowhere)."""
        return replace(self, envelope=envelope)


def joint_errors_for(model: SerialModel, families: Iterable[str], harmonics: int = 2,
                     base: JointErrors | None = None) -> JointErrors | None:
    """The joint-error terms of `families` for `model` (None for no family).

    Compliance on every joint, harmonics of order `harmonics` on every revolute joint,
    scale on every joint; gravity, mass model, values and reference are taken from `base`
    (default: `model.joint_errors`, if any).

    Raises
    ------
    InputError
        An unknown family name.
    """
    families = list(families)
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        raise InputError(f"unknown joint-error family {unknown[0]!r}; expected one of "
                         f"{', '.join(FAMILIES)}")
    if not families:
        return None
    base = base if base is not None else getattr(model, "joint_errors", None)
    joints = tuple(range(1, model.n_joints + 1))
    revolute = tuple(j for j, k in zip(joints, model.joint_kinds, strict=True)
                     if k != PRISMATIC)
    use_h = "harmonic" in families and harmonics > 0
    kw = {} if base is None else {"gravity": base.gravity, "masses": base.masses,
                                  "payload": base.payload, "values": dict(base.values),
                                  "reference": base.reference, "envelope": base.envelope}
    return JointErrors(
        compliance=joints if "compliance" in families else (),
        harmonics=int(harmonics) if use_h else 0,
        harmonic_joints=revolute if use_h else (),
        scale=joints if "scale" in families else (),
        **kw,
    )
