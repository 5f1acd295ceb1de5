"""Nominal D-H tables of the Universal Robots arms and kinecal models built from them.

Every UR arm is a standard-D-H (``dh``) six-joint chain with ``alpha = (90, 0, 0, 90, -90, 0)``
degrees, ``theta = 0`` and the lengths below. The numbers are Universal Robots' published
D-H parameters (metres), as ur_description's ``config/<type>/default_kinematics.yaml`` encodes
them (``shoulder.z = d1``, ``forearm.x = a2``, ``wrist_1.x = a3``, ``wrist_1.z = d4``,
``wrist_2.y = -d5``, ``wrist_3.y = d6``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["UR_ALPHA", "UR_TYPES", "nominal_dh", "ur_model"]

Array = NDArray[np.float64]

#: d1, a2, a3, d4, d5, d6 (metres) of each UR type
UR_TYPES: dict[str, tuple[float, float, float, float, float, float]] = {
    "ur3": (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
    "ur3e": (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
    "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
    "ur5e": (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
    "ur10": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
    "ur10e": (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
    "ur16e": (0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
    "ur20": (0.2363, -0.862, -0.7287, 0.201, 0.1593, 0.1543),
    "ur30": (0.2363, -0.637, -0.5037, 0.201, 0.1593, 0.1543),
}

#: alpha of the six joints (rad)
UR_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)

#: model units -> metres
_PER_M = {"m": 1.0, "mm": 1000.0}


def _check_robot(robot: str) -> str:
    if not isinstance(robot, str):
        raise TypeError(f"robot: expected a UR type name (str), got {type(robot).__name__}")
    key = robot.strip().lower()
    if key not in UR_TYPES:
        raise InputError(f"unknown robot {robot!r}; expected one of {', '.join(UR_TYPES)}",
                         option="--robot")
    return key


def nominal_dh(robot: str) -> Array:
    """The nominal D-H table of a UR type, ``(6, 4)``: columns theta, a, d, alpha (rad, m).

    Raises
    ------
    InputError
        Unknown type (the valid names listed).
    """
    d1, a2, a3, d4, d5, d6 = UR_TYPES[_check_robot(robot)]
    table = np.zeros((6, 4))
    table[:, 1] = (0.0, a2, a3, 0.0, 0.0, 0.0)
    table[:, 2] = (d1, 0.0, 0.0, d4, d5, d6)
    table[:, 3] = UR_ALPHA
    return table


def ur_model(robot: str, deltas: ArrayLike | None = None, *, name: str | None = None,
             length_unit: str = "mm", description: str = "") -> SerialModel:
    """A kinecal ``dh`` model of a UR type, nominal or with the factory deltas added.

    Parameters
    ----------
    robot : str
        A key of `UR_TYPES`.
    deltas : array_like, shape (6, 4), optional
        Added to `nominal_dh`: columns theta, a, d, alpha (rad, m), as a controller's
        ``calibration.conf`` gives them (`kinecal.io.ur.conf.read_calibration_conf`).
    name : str, optional
        Model name (default: the type, with ``-factory`` when deltas are given).
    length_unit : {"mm", "m"}
        Unit of the model's lengths (angles are written in degrees).
    description : str
        Free text kept in the model file.

    Returns
    -------
    SerialModel
        Flange in the robot base frame (UR's ``base``): a zero base and tool point that
        a calibration may free (``kinecal calibrate`` identifies them with the arm).
    """
    table = nominal_dh(robot)
    if deltas is not None:
        try:
            d = np.asarray(deltas, dtype=float)
        except (TypeError, ValueError):
            d = np.zeros(0)
        if d.shape != (6, 4) or not np.isfinite(d).all():
            raise InputError(f"deltas: expected a (6, 4) table of finite numbers (theta, a, d, "
                             f"alpha per joint), got shape {d.shape}")
        table = table + d
    s = _PER_M[length_unit]
    joints = [{"theta": float(t), "d": float(d * s), "a": float(a * s), "alpha": float(al)}
              for t, a, d, al in table]
    return SerialModel(
        name=name or (robot.lower() + ("-factory" if deltas is not None else "")),
        convention="dh", joints=joints, base=np.zeros(6), tool=np.zeros(3),
        length_unit=length_unit, angle_unit="deg",
        joint_limits=np.tile([-2 * np.pi, 2 * np.pi], (6, 1)),
        tolerances={"length": 1.0 * s / 1000.0, "angle": np.radians(0.5)},
        description=description)
