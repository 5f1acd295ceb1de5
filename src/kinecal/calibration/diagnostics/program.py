"""Plausibility of a robot program's Cartesian targets against the arm (code
``target-units``, docs/diagnostics.md).

Targets in metres given to a millimetre arm (``0.45, 0, 0.55``) lie within a millimetre of
its base: inverse kinematics folds the arm onto itself and reports the rows converged.
The targets are compared with the arm's workspace, the band of distances from its base
that the tool point reaches (sampled over the joint ranges); when none lies in it but all
would in another length unit, the unit is named.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.calibration.diagnostics._common import UNIT_FACTORS
from kinecal.calibration.serial.simulate import random_configurations
from kinecal.diagnostics import warn
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["INNER_FRACTION", "OUTER_FRACTION", "check_target_units", "workspace_band"]

Array = NDArray[np.float64]

#: the workspace band: from this fraction of the reach (an arm hardly reaches its own
#: base) to this multiple of it (round-off and tool offsets)
INNER_FRACTION = 0.05
OUTER_FRACTION = 1.1
#: configurations sampled for the reach (fixed seed: the same verdict every run)
SAMPLES = 512


def workspace_band(model: SerialModel) -> tuple[Array, float, float]:
    """The base origin ``(3,)`` in the model's measurement frame and the band
    ``(inner, outer)`` of tool-point distances from it (length unit)."""
    q = random_configurations(model, SAMPLES, np.random.default_rng(0))
    origin = model.nominal[model.index(BASE_NAMES[:3])]
    reach = float(np.linalg.norm(model.positions(q) - origin, axis=1).max())
    return origin, INNER_FRACTION * reach, OUTER_FRACTION * reach


def check_target_units(model: SerialModel, points: ArrayLike, what: str = "targets") -> bool:
    """``target-units``: no target point within the arm's workspace band, every one of
    them inside it in another length unit. Returns True when it warned.

    Parameters
    ----------
    model : SerialModel
        The arm, in the frame of the targets.
    points : array_like, shape (N, 3)
        Target positions (the model's length unit, as given).
    what : str
        What the points are, for the message.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if p.size == 0 or not np.isfinite(p).all():
        return False
    origin, inner, outer = workspace_band(model)

    def inside(x: Array) -> Array:
        d = np.linalg.norm(x - origin, axis=1)
        return (d >= inner) & (d <= outer)

    if inside(p).any():
        return False
    word = {"mm": "a millimetre", "m": "a metre"}.get(model.length_unit, "")
    for ratio, name in UNIT_FACTORS.items():
        if name.endswith(f" in {word} model") and inside(p / ratio).all():
            d = np.linalg.norm(p - origin, axis=1)
            warn("target-units",
                 f"the {what} lie {d.min():.4g} to {d.max():.4g} {model.length_unit} from the "
                 f"arm's base, outside its reach of {inner:.4g} to {outer:.4g} "
                 f"{model.length_unit}, and inside it scaled by {1 / ratio:g}: they look like "
                 f"{name}; give them in {model.length_unit}")
            return True
    return False
