"""Is a calibrated model a calibration of the nominal arm, and where is its base?

The rule itself is `kinecal.kinematics.serial.same_arm.compare_arms` (one function for the
calibration's ``implausible-change`` warning, ``fk --params``, ``export``, `load_result` and
compensation). Compensation adds what a program needs: one tool point (a model with several
markers is refused here), and the registration that tells how far the calibrated base
frame is from the nominal one, and moves it there when the program's frame is the robot's
own (``base="nominal"`` in `kinecal.compensation.api`).
"""

from __future__ import annotations

from kinecal.errors import InputError
from kinecal.kinematics.serial import same_arm as _rule
from kinecal.kinematics.serial.frames import frame_transform, with_frame_transform
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.same_arm import (
    LENGTH_UNITS,
    SAME_ARM_ANGLE,
    SAME_ARM_LENGTH,
    Registration,
    in_length_unit,
)

__all__ = [
    "LENGTH_UNITS",
    "SAME_ARM_ANGLE",
    "SAME_ARM_LENGTH",
    "Registration",
    "check_same_arm",
    "in_length_unit",
    "register",
    "with_registered_base",
]


def _one_tool_point(*models: SerialModel) -> None:
    for m in models:
        if m.marker_names:
            raise InputError(f"model {m.name!r} has several markers "
                             f"({', '.join(m.marker_names)}): a program is compensated for "
                             "one tool point; put the program's tool on the calibrated arm "
                             "with tool='nominal' (--tool nominal)")


def register(nominal: SerialModel, calibrated: SerialModel) -> Registration:
    """`kinecal.kinematics.serial.same_arm.register` for models of one tool point.

    Raises
    ------
    InputError
        Different joints, or a model with several markers.
    """
    _one_tool_point(calibrated, nominal)
    return _rule.register(nominal, calibrated)


def check_same_arm(nominal: SerialModel, calibrated: SerialModel) -> Registration:
    """Refuse a calibrated model of another arm than `nominal` (the one rule,
    `kinecal.kinematics.serial.same_arm.compare_arms`) or with several markers; returns the
    registration.

    Raises
    ------
    InputError
        Naming what differs and by how much.
    """
    _one_tool_point(calibrated, nominal)
    return _rule.check_same_arm(nominal, calibrated)


def with_registered_base(calibrated: SerialModel, reg: Registration) -> SerialModel:
    """`calibrated` with its base frame moved by the registration ``X``: its tool poses
    then fit the nominal model's frame best (base errors and the instrument's placement
    left out)."""
    p = calibrated.nominal
    B = frame_transform(calibrated, p, "base")
    return calibrated.with_params(with_frame_transform(calibrated, p, reg.transform @ B))
