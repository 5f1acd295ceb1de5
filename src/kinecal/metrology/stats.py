"""Error statistics of calibrations: ISO 9283-style summaries of distance errors.

Kept apart from `kinecal.calibration.serial.result` so that the report layer can format them
without importing the result type (no import circle between results and reports).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["axis_stats", "error_stats", "stat_rows"]

Array = NDArray[np.float64]


def stat_rows(groups: dict[str, dict[str, dict[str, float]]]) -> list[tuple[str, str, dict]]:
    """``(label, "before"|"after", stats)`` rows of before/after statistics groups."""
    return [(label, when, stats[when]) for label, stats in groups.items()
            for when in ("before", "after")]


def error_stats(distances: Array) -> dict[str, float]:
    """``{n, mean, rms, std, p95, max}`` of Euclidean distance errors ``(N,)`` (ISO 9283
    style; ``p95``: the 95th percentile, linear interpolation)."""
    d = np.asarray(distances, dtype=float)
    if d.size == 0:
        return {"n": 0, "mean": float("nan"), "rms": float("nan"), "std": float("nan"),
                "p95": float("nan"), "max": float("nan")}
    return {"n": int(d.size), "mean": float(d.mean()), "rms": float(np.sqrt((d * d).mean())),
            "std": float(d.std(ddof=1)) if d.size > 1 else 0.0,
            "p95": float(np.percentile(d, 95.0)), "max": float(d.max())}


def axis_stats(errors: Array) -> dict[str, dict[str, float]]:
    """Per-axis statistics of error vectors ``(N, 3)`` (model minus measured, length unit):
    ``{"x": {mean, rms, max}, "y": ..., "z": ...}`` with ``max`` the largest absolute value.

    A mean far from zero on one axis is a systematic offset (a frame or a scale error).
    """
    e = np.asarray(errors, dtype=float).reshape(-1, 3)
    out = {}
    for k, axis in enumerate("xyz"):
        v = e[:, k]
        out[axis] = ({"mean": float(v.mean()), "rms": float(np.sqrt((v * v).mean())),
                      "max": float(np.abs(v).max())} if v.size else
                     {"mean": float("nan"), "rms": float("nan"), "max": float("nan")})
    return out
