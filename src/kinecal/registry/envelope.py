"""Which of a check's poses lie beyond the joint range the calibration saw
(``outside-calibrated-range``, docs/diagnostics.md).

A calibration identifies its parameters from the poses it measured; beyond their joint
envelope its prediction is an extrapolation, and a check there judges the extrapolation as
much as the robot. Results record that envelope, and one shared function issues the
warning for fk, compensate, validate and check; until a result carries its envelope, this
hook answers None (nothing known) and the check's poses carry no flag.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["outside_calibrated_range"]


def outside_calibrated_range(cal: Any, block: Any) -> NDArray[np.bool_] | None:
    """Per observation of `block`: beyond the calibration's joint envelope (None when
    the calibration's result records none)."""
    return None
