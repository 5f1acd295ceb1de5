"""Helpers shared by the serial-arm paper reproductions (Hu, Xiao and Li 2005 and Zhao and Yang).

Rows of the ``kinecal reproduce`` JSON, error statistics, checkpoints of a convergence
history, text tables and the convergence figure (PNG, written atomically).
"""

from __future__ import annotations

import io
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.result import CalibrationResult
from kinecal.metrology.stats import error_stats

__all__ = [
    "checkpoints",
    "format_table",
    "progress_bar",
    "result_row",
    "stats_block",
    "write_convergence_png",
]

Array = NDArray[np.float64]


def checkpoints(
    history: Sequence[float], iterations: Sequence[int], finished: bool = True
) -> dict[str, float | None]:
    """Best mean error at the paper's iteration numbers (Hu, Xiao and Li 2005, Table 2).

    The paper counts the start as iteration 1 (its least-squares row begins with the nominal
    error 25.0 mm, the GA's with the best initial individual), so paper iteration ``k`` is
    ``history[k - 1]``. Beyond the end of the history, a `finished` run (converged or at the
    threshold) keeps its last value; an unfinished one (budget exhausted) gives ``None``.

    Parameters
    ----------
    history : sequence of float
        Mean distance error after each iteration, ``history[0]`` the start (mm).
    iterations : sequence of int
        Paper iteration numbers (>= 1).
    finished : bool
        Whether the run stopped because it converged or reached its threshold.

    Returns
    -------
    dict
        ``{str(k): error}`` (mm), JSON-able.
    """
    h = list(history)
    out: dict[str, float | None] = {}
    for k in iterations:
        if k - 1 < len(h):
            out[str(k)] = float(h[k - 1])
        else:
            out[str(k)] = float(h[-1]) if h and finished else None
    return out


def result_row(
    method: str,
    res: CalibrationResult,
    paper_value: float | None,
    **extra: Any,
) -> dict[str, Any]:
    """One JSON row of ``kinecal reproduce`` from a calibration result.

    Errors are the mean Euclidean distance errors (model length unit, mm here) on the
    calibration poses and on the held-out validation poses.
    """
    cal = res.calibration_stats
    val = res.validation_stats
    row: dict[str, Any] = {
        "method": method,
        "free": len(res.free),
        "iterations": int(res.iterations),
        "evaluations": int(res.evaluations),
        "seconds": float(res.seconds),
        "calibration_mean": float(cal["after"]["mean"]),
        "validation_mean": float(val["after"]["mean"]) if val else None,
        "paper_value": paper_value,
    }
    row.update(extra)
    return row


def stats_block(before: Array, after: Array) -> dict[str, Any]:
    """Before/after ``{n, mean, rms, std, max}`` and the mean's improvement in percent."""
    b, a = error_stats(before), error_stats(after)
    imp = 100.0 * (b["mean"] - a["mean"]) / b["mean"] if b["mean"] > 0 else float("nan")
    return {"before": b, "after": a, "improvement_percent": float(imp)}


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if v != v:  # NaN
            return "nan"
        if v == 0.0 or 1e-3 <= abs(v) < 1e5:
            return f"{v:.4g}" if abs(v) < 1 else f"{v:.5g}"
        return f"{v:.2e}"
    return str(v)


def format_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """Markdown-style text table of `rows` (numbers with 4-5 significant digits)."""
    cells = [[_fmt(v) for v in r] for r in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) if cells else len(h)
              for i, h in enumerate(headers)]
    line = "| " + " | ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)) + " |"
    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    body = ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |"
            for r in cells]
    return "\n".join([line, sep, *body])


@contextmanager
def progress_bar(
    label: str, total: int | None, quiet: bool
) -> Iterator[Callable[[int, float], None]]:
    """``progress(iteration, best)`` callback for `kinecal.calibrate` driving a rich bar.

    The bar (stderr, via `kinecal.cli._common.progress`) is silent when `quiet` or when
    stderr is not a terminal.
    """
    from kinecal.cli._common import progress

    with progress(label, total, quiet) as update:
        last = [0]

        def callback(iteration: int, best: float) -> None:
            update(advance=max(iteration - last[0], 0), best=best)
            last[0] = iteration

        yield callback


def write_convergence_png(
    path: Path,
    curves: dict[str, Sequence[float]],
    title: str,
    evaluations: dict[str, int] | None = None,
    hline: float | None = None,
) -> Path:
    """Plot ``log10`` error curves vs iteration (and vs evaluations); write a PNG atomically.

    Parameters
    ----------
    path : Path
        Output file (its directory is created).
    curves : dict
        Label -> mean distance error after each iteration (mm), start first; values <= 0
        are clipped to 1e-16 for the log axis.
    title : str
        Figure title.
    evaluations : dict, optional
        Label -> total objective evaluations of that run; adds a second panel against
        evaluations, spread evenly over the iterations (exact for the GA's fixed L per
        generation, an average for the fish swarms).
    hline : float, optional
        A threshold drawn as a dashed line (Hu, Xiao and Li 2005's eps).
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from kinecal._files import write_bytes_atomic

    panels = 2 if evaluations else 1
    fig = Figure(figsize=(7.0 * panels, 4.8), dpi=100)
    axes = [fig.add_subplot(1, panels, k + 1) for k in range(panels)]
    for label, h in curves.items():
        y = np.maximum(np.asarray(h, dtype=float), 1e-16)
        style = {"lw": 1.4, "marker": "o" if y.size < 12 else None, "ms": 3}
        axes[0].plot(np.arange(1, y.size + 1), y, label=label, **style)
        if evaluations:
            n = max(int(evaluations.get(label, y.size)), 1)
            axes[1].plot(np.linspace(n / y.size, n, y.size), y, label=label, **style)
    axes[0].set_xlabel("iteration (paper numbering: start = 1)")
    if evaluations:
        axes[1].set_xlabel("objective evaluations")
    for ax in axes:
        if hline is not None:
            ax.axhline(hline, color="k", ls="--", lw=0.8, label=f"eps = {hline:g} mm")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylabel("mean distance error [mm]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, buf.getvalue())
    return path
