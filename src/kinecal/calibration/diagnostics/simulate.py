"""Plausibility check of `kinecal.simulate`'s ``errors=``: deviations, not absolute values.

Code ``absolute-errors`` (docs/diagnostics.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.diagnostics import warn
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["check_absolute_errors"]

#: a parameter is "large" when its nominal value exceeds this many tolerances: a link length
#: or a joint offset far bigger than any geometric error
LARGE = 10.0


def check_absolute_errors(model: SerialModel, errors: NDArray[np.float64]) -> bool:
    """``absolute-errors``: an error vector that repeats the nominal values.

    Among the parameters whose nominal value is large (beyond `LARGE` tolerances), errors
    within half their nominal value of it on at least half of them are the nominal values
    themselves (``errors=sim.true_params`` instead of ``true_params - model.nominal``): the
    simulated arm would be about twice its size. Returns True when it warned.
    """
    e = np.asarray(errors, dtype=float)
    nominal = model.nominal
    tol = np.where(model.is_angle(), model.tolerances["angle"], model.tolerances["length"])
    large = np.abs(nominal) > LARGE * tol
    if not large.any():
        return False
    like = np.abs(e[large] - nominal[large]) <= 0.5 * np.abs(nominal[large])
    if like.mean() < 0.5:
        return False
    k = int(np.flatnonzero(large)[0])
    name = model.parameter_names[k]
    conv = (180.0 / np.pi if model.angle_unit == "deg" else 1.0) if model.is_angle()[k] else 1.0
    unit = model.angle_unit if model.is_angle()[k] else model.length_unit
    warn("absolute-errors",
         f"errors= looks like absolute parameter values ({name} error {e[k] * conv:.4g} {unit} "
         f"where its nominal value is {nominal[k] * conv:.4g} {unit}; {int(like.sum())} of "
         f"{int(large.sum())} large parameters alike): the simulated arm would be far off; "
         "pass deviations from nominal, e.g. true_params - model.nominal")
    return True
