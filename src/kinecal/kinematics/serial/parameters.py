"""`ParameterVector`: the named parameter vector a kinematic model is calibrated in, shared
by a serial chain (`kinecal.kinematics.serial.model.SerialModel`) and a robot system
(`kinecal.kinematics.tree.system.SystemModel`). The class that uses it holds ``_names``
(tuple of str), ``_nominal`` (ndarray ``(n_params,)``) and ``_fixed`` (frozenset of str)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["ParameterVector"]


class ParameterVector:
    """Names, nominal values and the fixed set of a model's parameters (module docstring)."""

    _names: tuple[str, ...]
    _nominal: NDArray[np.float64]
    _fixed: frozenset[str]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the full parameter vector, in order."""
        return self._names

    @property
    def n_params(self) -> int:
        """Length of the full parameter vector."""
        return len(self._names)

    @property
    def nominal(self) -> NDArray[np.float64]:
        """Nominal parameter vector ``(n_params,)`` (lengths in the model unit, angles in rad)."""
        return self._nominal.copy()

    @property
    def fixed_names(self) -> frozenset[str]:
        """Parameters fixed by the model's design (not calibrated by default)."""
        return self._fixed

    @property
    def calibratable(self) -> tuple[str, ...]:
        """Parameters calibrated by default (all but the fixed ones), in vector order."""
        return tuple(n for n in self._names if n not in self._fixed)
