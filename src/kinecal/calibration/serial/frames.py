"""The frames a serial calibration result reports: the base and tool frames composed.

The parameters ``base.rx .. base.rz`` (and ``tool.rx .. tool.rz``) are local rotation errors
about the model's nominal orientation (`kinecal.kinematics.serial.frames`); the result
also gives each frame as a whole pose, nominal and calibrated, in the model file's units
(``frames`` of the result JSON; docs/conventions.md). Its presence marks a result written
with local frames (`kinecal.io.result_values` reads older ones).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal.kinematics.serial.frames import frame_pose
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["file_pose", "frames_entry"]


def file_pose(model: SerialModel, pose: np.ndarray) -> list[float]:
    """A pose ``(x, y, z, rx, ry, rz)`` (rad) in the model file's angle unit, as a list."""
    s = 180.0 / np.pi if model.angle_unit == "deg" else 1.0
    return [float(v) for v in np.r_[pose[:3], np.asarray(pose[3:]) * s]]


def frames_entry(model: SerialModel, params: np.ndarray) -> dict[str, Any]:
    """``{"base": {"nominal", "calibrated"}, "tool": ...}``: each frame as ``[x, y, z, rx,
    ry, rz]`` (``R = Rz Ry Rx``; the model file's units); the tool only for a tool frame."""
    out: dict[str, Any] = {}
    which = ["base"] + (["tool"] if "tool.rx" in model.parameter_names else [])
    for w in which:
        out[w] = {"nominal": file_pose(model, frame_pose(model, None, w)),
                  "calibrated": file_pose(model, frame_pose(model, params, w))}
    return out
