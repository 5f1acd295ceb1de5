"""Plausibility of an ISO 9283 test (`kinecal.metrology.iso9283.iso9283`; codes in
docs/diagnostics.md).

- ``scale-mismatch``: the commanded poses span less than a millimetre or more than 100 m
  in the unit the file is labelled with (a file in metres read as millimetres, or the
  other way round); the standard's test poses span a cube of most of the workspace.
- ``far-from-commanded``: a pose's accuracy AP beyond a tenth of the span of the commanded
  poses: a typo in a commanded or measured cell, measured and commanded positions in
  different frames or units, or the wrong model or joint order.
- ``cycle-scatter``: a pose's repeatability RP beyond a tenth of that span: a measured cell
  of one cycle that is wrong, or poses mislabelled between cycles.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinecal.diagnostics import warn
from kinecal.metrology.units import LENGTH_UNITS

__all__ = ["FAR_FRACTION", "SPAN_RANGE", "check_test"]

#: AP or RP beyond this fraction of the commanded poses' span is not a robot's error
#: (an uncalibrated arm misses by millimetres on a span of a metre: 1 %)
FAR_FRACTION = 0.1
#: plausible span of a test's commanded poses [m]: the ISO 9283 cube is most of the
#: workspace of the arm under test
SPAN_RANGE = (1e-3, 100.0)


def _worst(values: np.ndarray, labels: tuple[str, ...], limit: float) -> str:
    bad = np.flatnonzero(values > limit)
    order = bad[np.argsort(-values[bad])][:4]
    return ", ".join(f"{labels[i]} {values[i]:.4g}" for i in order) + (
        ", ..." if bad.size > 4 else "")


def check_test(res: Any) -> None:
    """Warn on an implausible test (module docstring); `res` is an `Iso9283Result`."""
    d = res.data
    if len(d.labels) < 2:
        return
    name = Path(d.source).name or "the test"
    unit = d.length_unit
    commanded = np.asarray(d.commanded, dtype=float)
    span = float(np.linalg.norm(np.ptp(commanded, axis=0)))
    if not span > 0:
        return
    if unit in LENGTH_UNITS:
        metres = span * LENGTH_UNITS[unit]
        if not SPAN_RANGE[0] <= metres <= SPAN_RANGE[1]:
            warn("scale-mismatch",
                 f"{name}: the commanded poses span {span:.4g} {unit} ({metres:.3g} m): "
                 f"expected {SPAN_RANGE[0] * 1e3:g} mm to {SPAN_RANGE[1]:g} m for a robot's "
                 f"test poses; positions in another unit than {unit}? (--length-unit labels "
                 "a file without --model; with --model the file is in the model's unit)")
    limit = FAR_FRACTION * span
    for key, code, what in (
            ("AP", "far-from-commanded", "from their commanded positions (a typo in a "
             "commanded or measured cell, measured and commanded positions in different "
             "frames or units, or the wrong model or joint order)"),
            ("RP", "cycle-scatter", "between cycles (a wrong measured cell in one cycle, "
             "or poses mislabelled between cycles)")):
        values = np.asarray(res.poses[key], dtype=float)
        if np.any(values > limit):
            warn(code, f"{name}: {key} of pose {_worst(values, d.labels, limit)} {unit}, beyond "
                       f"{FAR_FRACTION:g} of the span of the commanded poses ({span:.4g} "
                       f"{unit}): the measured positions are far {what}")
