"""The report's *Residual against temperature and time* section.

When the measurement file has ``temperature`` (deg C) or ``time`` columns
(`kinecal.io.conditions`), the calibration keeps them per pose
(`CalibrationResult.conditions`), and the report plots each pose's distance error after the
calibration against them (calibration poses blue, validation poses orange, the mean in
bins as a line), with the least-squares slope of the error against each: a residual that
grows with temperature or drifts with time is thermal expansion or a moving set-up, which a
geometric model does not hold.
"""

from __future__ import annotations

import html
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["conditions_section", "plot_conditions", "trend"]

Array = NDArray[np.float64]
_CAL = "#1f77b4"
_VAL = "#ff7f0e"
#: pixels per inch
_DPI = 100


def trend(x: Array, y: Array) -> tuple[float, float]:
    """Least-squares slope of `y` against `x` and their correlation (NaN when `x` does not
    vary)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    sx = np.std(x)
    if x.size < 2 or sx == 0 or np.std(y) == 0:
        return float("nan"), float("nan")
    c = np.mean((x - x.mean()) * (y - y.mean()))
    return float(c / sx ** 2), float(c / (sx * np.std(y)))


def _series(result: Any) -> list[tuple[str, str, Array, list]]:
    """Per condition: its name, unit, and the (label, x, errors, colour) of the poses."""
    cond = getattr(result, "conditions", None) or {}
    out = []
    t0 = min((float(np.min(cond[k])) for k in ("time", "validation_time") if k in cond),
             default=0.0)
    for name, unit in (("temperature", "deg C"), ("time", "h")):
        sets = []
        for label, key, errors, colour in (
                ("calibration", name, result.errors_after, _CAL),
                ("validation", "validation_" + name, result.val_after, _VAL)):
            if key in cond and errors is not None and len(cond[key]) == len(errors):
                x = np.asarray(cond[key], dtype=float)
                if name == "time":
                    x = (x - t0) / 3600.0
                sets.append((label, x, np.asarray(errors, dtype=float), colour))
        if sets:
            out.append((name, unit, sets))
    return out


def plot_conditions(result: Any) -> Any:
    """The residual against each condition as one matplotlib figure (None without any)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from kinecal.report.residual_maps import _binned

    series = _series(result)
    if not series:
        return None
    unit = result.nominal_model.length_unit
    fig = Figure(figsize=(4.2 * len(series), 3.0), dpi=_DPI)
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(1, len(series)))
    for ax, (name, cunit, sets) in zip(axes, series, strict=True):
        for label, x, e, colour in sets:
            _binned(ax, x, e, colour)
            ax.plot([], [], color=colour, label=label)
        ax.set_xlabel(f"{name} [{cunit}]" + (" since the first pose" if name == "time"
                                             else ""), fontsize=8)
        ax.set_ylabel(f"error after [{unit}]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def conditions_section(result: Any) -> list[str]:
    """The section (empty list when the poses have no temperature or time)."""
    from kinecal.report.markup import fmt, section, table
    from kinecal.report.residual_maps import _png_tag

    series = _series(result)
    if not series:
        return []
    unit = result.nominal_model.length_unit
    rows = []
    for name, cunit, sets in series:
        for label, x, e, _ in sets:
            slope, r = trend(x, e)
            rows.append((f"{name}, {label} poses", f"{fmt(x.min())} .. {fmt(x.max())} {cunit}",
                         slope, r))
    body = ("<p>Each pose's distance error after the calibration against the measurement "
            "conditions the file gave; the line is the mean in bins. A slope that the "
            "spread of the poses does not hide (thermal expansion, a set-up moving with "
            "time) is beyond what a geometric model holds.</p>"
            + table(["condition", "range", f"slope [{html.escape(unit)} per unit]",
                     "correlation"], rows, digits=3)
            + _png_tag(plot_conditions(result), "residual against temperature and time",
                       "Distance error after calibration against temperature and time.",
                       "fig-conditions"))
    return [section("conditions", "Residual against temperature and time", body)]
