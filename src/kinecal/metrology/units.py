"""Length units of printed results: a result keeps its model's unit (files, JSON, the
Python API); a summary may show its lengths in another (``--unit mm|um|m``).

A URDF model is in metres, and a calibration's errors are fractions of a millimetre:
``1.405e-05 m`` reads worse than ``0.01405 mm``. `display_unit` chooses the unit a text
summary uses: the one asked for, or by default the model's, except that a model in metres
whose errors stay below 1 m is shown in millimetres.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

__all__ = ["DISPLAY_UNITS", "LENGTH_UNITS", "DisplayUnit", "display_unit"]

#: metres per unit of every length unit a model or a display may use
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "mm": 1e-3, "um": 1e-6}
#: the values of ``--unit`` (auto: `display_unit`'s default rule)
DISPLAY_UNITS = ("auto", "mm", "um", "m")


class DisplayUnit(NamedTuple):
    """A length of the model's unit ``v`` is shown as ``v * factor`` followed by `name`."""

    name: str
    factor: float


def display_unit(model_unit: str, unit: str | None = None,
                 lengths: Iterable[float] = ()) -> DisplayUnit:
    """The unit a summary shows lengths of `model_unit` in.

    Parameters
    ----------
    model_unit : str
        The model's (or geometry's) length unit.
    unit : {"auto", "mm", "um", "m"}, optional
        Asked for; ``auto`` or None: `model_unit`, but millimetres for a model in metres
        when every length of `lengths` (model unit: the errors shown) is below 1 m.
    lengths : iterable of float
        The lengths to be shown (for the ``auto`` rule); non-finite ones are ignored.

    Raises
    ------
    ValueError
        An unknown `unit`, or a conversion from a model unit that is not a length unit
        kinecal knows (`LENGTH_UNITS`).
    """
    if unit is None or unit == "auto":
        if model_unit == "m":
            values = np.asarray(list(lengths), dtype=float)
            values = values[np.isfinite(values)]
            if values.size == 0 or np.abs(values).max() < 1.0:
                return DisplayUnit("mm", 1e3)
        return DisplayUnit(model_unit, 1.0)
    if unit not in LENGTH_UNITS:
        raise ValueError(f"unknown unit {unit!r}; expected one of {', '.join(DISPLAY_UNITS)}")
    if model_unit not in LENGTH_UNITS:
        raise ValueError(f"cannot show lengths of unit {model_unit!r} in {unit}: known units "
                         f"are {', '.join(LENGTH_UNITS)}")
    return DisplayUnit(unit, LENGTH_UNITS[model_unit] / LENGTH_UNITS[unit])
