"""``scale-mismatch`` of a hand-eye calibration from images: the board poses take their
lengths from the board's size, so a factor between the robot's translations and what the
images measure names the ``--board`` size (or the robot poses' unit)
(`kinecal.calibration.diagnostics.handeye.translation_scale`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.diagnostics.handeye import _units, translation_scale

Array = NDArray[np.float64]

__all__ = ["warn_board_scale"]


def warn_board_scale(spec: str, pitch: float, G: Array, C: Array, X: Array,
                     fallback: str) -> None:
    """Warn ``scale-mismatch`` naming the board `spec` (corner spacing `pitch`) when a
    unit factor explains the stations (robot poses `G`, board poses `C`, X); else the
    pose-level check's own message `fallback`."""
    sc = translation_scale(G, C, X)
    if sc is None or not sc.unit_factor:
        diagnostics.warn("scale-mismatch", fallback)
        return
    board_words = (f"the board's size is probably {sc.s:.4g} times larger (corner spacing "
                   f"{pitch * sc.s:.4g}, not {pitch:g}: measure the print)")
    units = min((1e3, 1e-3, 25.4, 1 / 25.4, 10.0, 0.1), key=lambda f: abs(np.log(sc.s / f)))
    if abs(np.log(sc.s / units)) < np.log(1.05):  # a unit factor: that first
        why = f"{_units(1.0 / sc.s)} (give both in one unit), or {board_words}"
    else:
        why = f"{board_words}, or the robot poses are in another length unit"
    diagnostics.warn("scale-mismatch",
                     f"the robot's translations are {sc.s:.4g} times what the images measure "
                     f"with the board {spec}: {why}")
