"""Helpers shared by the serial-arm command modules (``fk``, ``simulate``, ``calibrate``).

Reading a calibration result (``fk --params``, ``export``, ``compensate``) is
`kinecal.io.result_values`. No command is registered here: importing it loads no command module.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinecal.errors import InputError

__all__ = ["POSE_BYTES", "free_option", "parameters_from_result"]

#: peak memory of simulate / identifiability per random pose and per joint (+10): measured
#: 330 B (irb120, 6 joints) and 580 B with orientations, taken with a margin
POSE_BYTES = 64


def free_option(free: str) -> str | list[str]:
    """A ``--free`` value: ``all``, ``identifiable`` or the list of comma-separated names."""
    if free in ("all", "identifiable"):
        return free
    names = [n.strip() for n in free.split(",") if n.strip()]
    if not names:
        raise InputError("expected all, identifiable or comma-separated parameter names",
                         option="--free")
    return names


def parameters_from_result(model, path: Path) -> np.ndarray:
    """`kinecal.io.result_values.parameters_from_result`, and the identified values checked to
    describe the same arm (`_check_same_arm`): what ``fk --params``, ``export``,
    ``compensate`` and ``iso9283 --params`` use."""
    from kinecal.io.result_values import parameters_from_result as read

    p = read(model, path)
    _check_same_arm(model, p, path)
    return p


def _check_same_arm(model, p: np.ndarray, path: Path) -> None:
    """Refuse identified values that make another arm of `model` (``identified: 1e12``):
    the one same-arm rule (`kinecal.kinematics.serial.same_arm`), which the calibration
    itself warned about as ``implausible-change``."""
    from kinecal.kinematics.serial.same_arm import check_same_arm

    try:
        check_same_arm(model, model.with_params(p, name=f"{model.name}-calibrated"))
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
