"""Matplotlib figures of calibration, hand-eye and reproduction results (Agg backend).

Every figure is drawn on a `matplotlib.figure.Figure` created without pyplot, so that
report generation never touches pyplot's global state or needs a display; only
`plot_calibration` with ``ax=None`` (the notebook entry point behind
`CalibrationResult.plot`) goes through pyplot, which then picks the notebook's backend.

Figure size is fixed: ``FIGSIZE`` inches at ``DPI`` dots per inch, i.e. 720 x 320 pixels,
which the report and its browser test rely on.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError

__all__ = [
    "CALIBRATION_KINDS",
    "DPI",
    "FIGSIZE",
    "calibration_figures",
    "figure_png",
    "new_figure",
    "plot_calibration",
    "plot_handeye_stations",
    "plot_histories",
    "save_calibration_figures",
]

#: figure size in inches and resolution: 720 x 320 pixels
FIGSIZE = (7.2, 3.2)
DPI = 100
#: kinds of `plot_calibration`
CALIBRATION_KINDS = ("errors", "validation", "sorted", "histogram", "convergence")

_BEFORE = "#b0b0b0"
_AFTER = "#1f77b4"


def new_figure(nrows: int = 1, ncols: int = 1) -> tuple[Any, Any]:
    """A pyplot-free Agg figure of size `FIGSIZE` and its axes (array when several)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIGSIZE, dpi=DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols)
    return fig, axes


def figure_png(fig: Any) -> bytes:
    """PNG bytes of `fig` at `DPI` (size kept: no tight bounding box)."""
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


#: up to this many poses the per-pose figure draws bars; beyond, points
BAR_POSES = 100


def _per_pose(ax: Any, before: NDArray, after: NDArray, unit: str, title: str) -> None:
    """Per-pose distance errors before (grey) and after (blue), in pose order.

    Up to `BAR_POSES` poses: a pair of bars per pose (pose numbers from 1, integer ticks),
    on a logarithmic axis when every after error is below a tenth of the largest error (the
    after bars would not show on a linear one). Beyond: one point per pose and set, still
    in pose order (a pose is found by its number), on a logarithmic axis, so that the after
    errors, often a hundred times smaller, are not
    flattened against the before ones. `_sorted` draws the same errors sorted.
    """
    from matplotlib.ticker import MaxNLocator

    before = np.asarray(before, dtype=float)
    after = np.asarray(after, dtype=float)
    n = before.size
    idx = np.arange(1, n + 1)
    if n <= BAR_POSES:
        ax.bar(idx - 0.2, before, width=0.4, color=_BEFORE, label="before")
        ax.bar(idx + 0.2, after, width=0.4, color=_AFTER, label="after")
        ax.set_xlim(0.4, n + 0.6)
        both = np.concatenate([before, after])
        top = float(both.max(initial=0.0))
        if top > 0 and (both > 0).all() and after.max(initial=0.0) < 0.1 * top:
            # the after bars would be invisible on a linear axis: a logarithmic one
            ax.set_yscale("log")
            ax.set_ylim(float(both.min()) / 2.0, top * 4.0)  # room for the legend
            ax.grid(True, which="major", axis="y", alpha=0.3)
        else:
            ax.set_ylim(0.0, 1.25 * top if top > 0 else 1.0)  # room for the legend
    else:
        floor = max(float(np.concatenate([before, after]).max(initial=0.0)) * 1e-12, 1e-300)
        for values, color, label in ((before, _BEFORE, "before"), (after, _AFTER, "after")):
            ax.plot(idx, np.maximum(values, floor), linestyle="none", marker=".",
                    markersize=3, color=color, label=label)
        ax.set_yscale("log")
        ax.set_xlim(0.0, n + 1.0)
        ax.grid(True, which="major", axis="y", alpha=0.3)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
    ax.set_xlabel("pose (file order)")
    ax.set_ylabel(f"position error [{unit}]")
    ax.set_title(title)
    ax.legend(loc="upper right", ncol=2, markerscale=3)


def _sorted(ax: Any, groups: dict[str, tuple[NDArray, NDArray]], unit: str) -> None:
    """Each set of errors sorted in decreasing order against the share of poses, on a
    logarithmic axis: before (grey) and after (blue), calibration solid, validation dashed."""
    from matplotlib.ticker import PercentFormatter

    every = np.concatenate([np.asarray(v, float) for pair in groups.values() for v in pair])
    floor = max(float(every.max(initial=0.0)) * 1e-12, 1e-300)
    for (label, pair), style in zip(groups.items(), ("-", "--"), strict=False):
        for values, color, when in ((pair[0], _BEFORE, "before"), (pair[1], _AFTER, "after")):
            v = np.asarray(values, dtype=float)
            share = (np.arange(v.size) + 0.5) / max(v.size, 1)
            ax.plot(share, np.maximum(np.sort(v)[::-1], floor), color=color, linewidth=2,
                    linestyle=style, label=f"{label}, {when}")
    ax.set_yscale("log")
    ax.set_xlim(0.0, 1.0)
    ax.xaxis.set_major_formatter(PercentFormatter(1.0))
    ax.set_xlabel("share of poses, sorted by error")
    ax.set_ylabel(f"position error [{unit}]")
    ax.set_title("Sorted errors")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right", ncol=2, fontsize="small")


def _histogram(ax: Any, before: NDArray, after: NDArray, unit: str) -> None:
    """Histograms of the distance errors on log-spaced bins (before and after differ by
    orders of magnitude)."""
    both = np.concatenate([np.asarray(before, float), np.asarray(after, float)])
    positive = both[both > 0]
    if positive.size == 0:
        ax.text(0.5, 0.5, "all errors are zero", ha="center", transform=ax.transAxes)
        return
    lo, hi = positive.min(), positive.max()
    if hi <= lo * 1.0001:
        lo, hi = lo / 2.0, hi * 2.0
    bins = np.geomspace(lo, hi, 41)
    ax.hist(np.clip(before, lo, hi), bins=bins, color=_BEFORE, alpha=0.9, label="before")
    ax.hist(np.clip(after, lo, hi), bins=bins, color=_AFTER, alpha=0.8, label="after")
    ax.set_xscale("log")
    ax.set_xlabel(f"position error [{unit}]")
    ax.set_ylabel("poses")
    ax.set_title("Error distribution, calibration poses")
    ax.legend()


def _convergence(ax: Any, history: Sequence[float], unit: str, label: str = "") -> None:
    h = np.asarray(history, dtype=float)
    if h.size == 0:
        ax.text(0.5, 0.5, "no iteration history", ha="center", transform=ax.transAxes)
        return
    ax.semilogy(np.arange(h.size), np.maximum(h, 1e-300), marker="o", markersize=3,
                label=label or None)
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"mean position error [{unit}]")
    ax.set_title("Convergence")
    ax.grid(True, which="both", alpha=0.3)


def plot_calibration(result: Any, kind: str = "errors", ax: Any = None) -> Any:
    """Draw one figure of a `CalibrationResult`.

    Parameters
    ----------
    result : CalibrationResult
        The calibration outcome.
    kind : {"errors", "validation", "sorted", "histogram", "convergence"}
        ``errors``: per-pose distance errors on the calibration poses before and after, in
        pose order; ``validation``: the same on the validation poses; ``sorted``: the
        errors of both sets sorted by size; ``histogram``: distribution of
        the calibration errors before and after; ``convergence``: mean distance error
        (model length unit) per iteration.
    ax : matplotlib Axes, optional
        Where to draw; a new pyplot figure when omitted (notebooks).

    Returns
    -------
    matplotlib Axes
    """
    if kind not in CALIBRATION_KINDS:
        raise InputError(f"unknown plot kind {kind!r}; expected one of "
                         f"{', '.join(CALIBRATION_KINDS)}", option="kind")
    if kind == "validation" and result.val_before is None:
        raise InputError("no validation poses in this result", option="kind")
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=FIGSIZE, dpi=DPI)
    unit = result.nominal_model.length_unit
    if kind == "errors":
        _per_pose(ax, result.errors_before, result.errors_after, unit,
                  f"Calibration poses ({result.errors_before.size})")
    elif kind == "validation":
        _per_pose(ax, result.val_before, result.val_after, unit,
                  f"Validation poses ({result.val_before.size})")
    elif kind == "sorted":
        groups = {"calibration": (result.errors_before, result.errors_after)}
        if result.val_before is not None:
            groups["validation"] = (result.val_before, result.val_after)
        _sorted(ax, groups, unit)
    elif kind == "histogram":
        _histogram(ax, result.errors_before, result.errors_after, unit)
    else:
        _convergence(ax, result.history, unit)
    return ax


def calibration_figures(result: Any) -> dict[str, bytes]:
    """PNG bytes of every applicable `plot_calibration` kind, keyed by kind."""
    out = {}
    for kind in CALIBRATION_KINDS:
        if kind == "validation" and result.val_before is None:
            continue
        fig, ax = new_figure()
        plot_calibration(result, kind, ax)
        out[kind] = figure_png(fig)
    return out


def save_calibration_figures(result: Any, out_dir: str | Path,
                             pngs: dict[str, bytes] | None = None) -> list[Path]:
    """Write ``<kind>.png`` for every kind of `calibration_figures` (atomically).

    Returns the written paths.
    """
    from kinecal._files import write_bytes_atomic

    out_dir = Path(out_dir)
    pngs = calibration_figures(result) if pngs is None else pngs
    paths = []
    for kind, data in pngs.items():
        path = out_dir / f"{kind}.png"
        write_bytes_atomic(path, data)
        paths.append(path)
    return paths


def plot_handeye_stations(result: dict[str, Any]) -> Any:
    """Per-station residuals of a hand-eye result dict (``kinecal handeye --json``).

    Two panels: rotation residual [deg] and translation residual [length unit of the
    pose file] per station; outlier stations in red. Returns the Figure.
    """
    stations = result.get("stations") or []
    rot = np.array([float(s.get("rotation_deg", np.nan)) for s in stations])
    tra = np.array([float(s.get("translation", np.nan)) for s in stations])
    outliers = {int(i) for i in result.get("outliers") or []}
    colors = ["#d62728" if k in outliers else _AFTER for k in range(rot.size)]
    fig, (a1, a2) = new_figure(1, 2)
    idx = np.arange(rot.size)
    a1.bar(idx, rot, color=colors)
    a1.set_xlabel("station")
    a1.set_ylabel("rotation residual [deg]")
    a2.bar(idx, tra, color=colors)
    a2.set_xlabel("station")
    a2.set_ylabel("translation residual")
    a1.set_title("Per-station residuals" + (" (red: outliers)" if outliers else ""))
    return fig


def plot_histories(histories: dict[str, Sequence[float]]) -> Any:
    """Convergence curves (log scale) of several named histories; returns the Figure."""
    fig, ax = new_figure()
    for name, h in histories.items():
        h = np.asarray(h, dtype=float)
        ax.semilogy(np.arange(h.size), np.maximum(np.abs(h), 1e-300), label=name)
    ax.set_xlabel("iteration")
    ax.set_ylabel("best cost")
    ax.set_title("Convergence")
    ax.grid(True, which="both", alpha=0.3)
    if histories:
        ax.legend(fontsize="small")
    return fig
