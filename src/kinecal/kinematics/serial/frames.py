"""The base and tool frames of a serial model as transforms, and parameters that put them.

The base (``base.x .. base.rz``) and a tool frame (``tool.x .. tool.rz``) are parametrised
locally about their nominal orientation (`kinecal.kinematics.serial.motions.
local_pose_motions`): the frame is ``T(x, y, z) R(rpy_0) R(w)`` with ``rpy_0`` the model's
nominal roll-pitch-yaw (a constant of the model) and ``w = (rx, ry, rz)`` the parameters'
local rotation error, ``R(a) = Rz(a_z) Ry(a_y) Rx(a_x)``. These functions give the composed
transform (what a result reports, what exports write) and the parameter values that make a
wanted transform in that chart.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import BASE_NAMES, TOOL_NAMES
from kinecal.spatial import matrix_from_rpy, rpy_from_matrix, transform_from

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["FRAMES", "frame_pose", "frame_transform", "local_rotation", "with_frame_transform"]

Array = NDArray[np.float64]

#: the frames parametrised locally: their parameter names
FRAMES = {"base": BASE_NAMES, "tool": TOOL_NAMES}


def _nominal_rpy(model: SerialModel, which: str) -> tuple[float, float, float]:
    if which not in FRAMES:
        raise InputError(f"frame {which!r}: expected base or tool")
    return model.chain.base_rpy if which == "base" else model.chain.tool_rpy


def _names(model: SerialModel, which: str) -> tuple[str, ...]:
    names = FRAMES[which]
    have = [n for n in names if n in model.parameter_names]
    return tuple(have)


def frame_transform(model: SerialModel, params: ArrayLike | None = None,
                    which: str = "base") -> Array:
    """The base (measurement <- robot base) or tool (flange <- tool) frame ``(4, 4)`` at
    `params` (default nominal), its nominal orientation and local error composed.

    A tool point (3 parameters) gives a pure translation; a model with several markers
    has no single tool frame (`InputError`).
    """
    if which == "tool" and model.marker_names:
        raise InputError(f"model {model.name!r} has several markers, no single tool frame")
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    names = _names(model, which)
    v = p[model.index(list(names))]
    R = matrix_from_rpy(np.asarray(_nominal_rpy(model, which)))
    if len(v) == 6:
        R = R @ matrix_from_rpy(v[3:])
    return transform_from(R, v[:3])


def frame_pose(model: SerialModel, params: ArrayLike | None = None,
               which: str = "base") -> Array:
    """`frame_transform` as ``(x, y, z, rx, ry, rz)`` (length unit, rad; ``R = Rz Ry Rx``)."""
    T = frame_transform(model, params, which)
    return np.r_[T[:3, 3], rpy_from_matrix(T[:3, :3])]


def local_rotation(rpy0: ArrayLike, R: ArrayLike) -> Array:
    """The local rotation error ``w`` ``(3,)`` (rad) with ``R(rpy0) R(w) = R``."""
    R0 = matrix_from_rpy(np.asarray(rpy0, dtype=float))
    return rpy_from_matrix(R0.T @ np.asarray(R, dtype=float))


def with_frame_transform(model: SerialModel, params: ArrayLike, T: ArrayLike,
                         which: str = "base") -> Array:
    """A copy of `params` whose base (or tool) frame is the transform `T` ``(4, 4)``,
    in the model's chart (its nominal orientation held; the local error takes the rest)."""
    p = np.array(params, dtype=float)
    T = np.asarray(T, dtype=float)
    names = _names(model, which)
    idx = model.index(list(names))
    p[idx[:3]] = T[:3, 3]
    if len(idx) == 6:
        p[idx[3:]] = local_rotation(_nominal_rpy(model, which), T[:3, :3])
    return p
