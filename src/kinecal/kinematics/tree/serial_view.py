"""One tip's chain as a `SerialModel`: what inverse kinematics and compensation work on.

The chain of a tip at one parameter vector is folded into the URDF convention exactly:
the constant motions before the first joint become the base frame, those between two
joints the next joint's origin (``x, y, z, roll, pitch, yaw``), each joint motion a URDF
joint about (along) its unit axis with its value as the ``offset``, and what follows the
last joint (with the tool) a tool frame. The serial model has the chain's joints, named by
the system's joint names, and reproduces the system's forward kinematics of that tip to
round-off; its parameters are its own (origins merged), not the system's.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.compose import transforms
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC, ROTATION
from kinecal.spatial import xyz_rpy_from_transform

__all__ = ["tip_model"]

Array = NDArray[np.float64]


def _constant(chain, a: int, b: int, p: Array) -> Array:
    """The transform of the chain's motions strictly between positions `a` and `b`."""
    sub = chain.motions[a + 1:b]
    if not sub:
        return np.eye(4)
    return transforms(sub, chain._motion_index[a + 1:b], np.zeros((1, chain.n_joints)), p)[0]


def _pose(T: Array) -> list[float]:
    return [float(v) + 0.0 for v in xyz_rpy_from_transform(T)]


def tip_model(system, tip: str, params: Array | None = None) -> SerialModel:
    """The chain of `tip` at `params` (default nominal) as a ``urdf`` `SerialModel`
    (module docstring).

    Raises
    ------
    InputError
        A coupled (mimic) joint on the chain: its reading follows another joint, which a
        serial model cannot express.
    """
    p = system._one_vector(params)
    chain = system._chains[system.tip_number(tip)]
    if chain.coupled:
        coupled = [system.joint_names[s] for s, m in zip(chain.source, chain.multiplier,
                                                          strict=True) if m >= 0]
        raise InputError(f"tip {tip}: its chain has coupled (mimic) joints following "
                         f"{', '.join(coupled)}: inverse kinematics and compensation of such "
                         "a chain are not supported")
    at = {m.joint: i for i, m in enumerate(chain.motions) if m.joint is not None}
    order = [at[j] for j in range(chain.n_joints)]
    cuts = [-1, *order, len(chain.motions)]
    consts = [_constant(chain, a, b, p) for a, b in pairwise(cuts)]
    names = [system.joint_names[s] for s in chain.source]
    kinds = [system.joint_kinds[s] for s in chain.source]
    entries = []
    for j, i in enumerate(order):
        m = chain.motions[i]
        axis = np.eye(3)[m.axis] if m.direction is None else np.asarray(m.direction, float)
        x, y, z, roll, pitch, yaw = _pose(consts[j]) if j else [0.0] * 6
        entries.append({"name": names[j], "type": PRISMATIC if m.kind != ROTATION else
                        "revolute", "x": x, "y": y, "z": z, "roll": roll, "pitch": pitch,
                        "yaw": yaw, "offset": float(p[chain._motion_index[i]]),
                        "axis": [float(v) for v in axis]})
        if (m.kind != ROTATION) != (kinds[j] == PRISMATIC):  # pragma: no cover - layout
            raise InputError(f"joint {names[j]}: its motion and its kind disagree")
    limits = system.joint_limits[chain.source]
    return SerialModel(
        name=f"{system.name}:{tip}", convention="urdf", joints=entries,
        base=np.array(_pose(consts[0])), tool=np.array(_pose(consts[-1])),
        length_unit=system.length_unit, angle_unit=system.angle_unit, joint_limits=limits,
        tolerances=dict(system.tolerances), description=f"tip {tip} of system {system.name}")
