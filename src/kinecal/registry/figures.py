"""The history figure (``registry history --plot``): a robot's checks on a time axis.

The systematic error each check found (``deviation``) against its date, coloured by
verdict, the limit as a line, calibrations as vertical lines (the current one solid),
the trend of the checks since the current calibration and its projected crossing.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any

__all__ = ["VERDICT_COLOURS", "history_axes", "history_figure"]

VERDICT_COLOURS = {"valid": "#2ca02c", "drifted": "#ff7f0e", "recalibrate": "#d62728"}


def _when(date: str) -> datetime:
    return datetime.fromisoformat(date)


def history_axes(ax: Any, hist: dict[str, Any], drift: dict[str, Any]) -> None:
    """Draw `hist` (and its `drift`) on the matplotlib axes `ax`."""
    events = hist["events"]
    unit = ""
    for ev in events:
        if ev["kind"] == "calibration" and ev.get("subject") == "arm":
            ax.axvline(_when(ev["date"]), color="#555" if ev.get("current") else "#bbb",
                       lw=1.2 if ev.get("current") else 0.8, ls="-" if ev.get("current")
                       else "--", zorder=1)
            unit = (ev.get("summary") or {}).get("length_unit") or unit
    checks = [e for e in events if e["kind"] == "check" and e["deviation"] is not None]
    for verdict, colour in VERDICT_COLOURS.items():
        pts = [(_when(e["date"]), e["deviation"]) for e in checks if e["verdict"] == verdict]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", color=colour, ms=5,
                    label=verdict, zorder=3)
    limits = [(_when(e["date"]), e["limit"]) for e in checks if e["limit"] is not None]
    if limits:
        ax.step([p[0] for p in limits], [p[1] for p in limits], where="post", color="#d62728",
                lw=1, ls=":", label="limit")
    dev = drift["deviation"]
    if dev.get("projected_crossing") and drift.get("since"):
        ax.plot([_when(drift["since"]), _when(dev["projected_crossing"])],
                _trend_values(drift), color="#777", lw=1, ls="-.", label="trend")
    ax.set_xlabel("date")
    ax.set_ylabel(f"systematic error [{unit}]" if unit else "systematic error")
    ax.set_title(f"{hist['serial']}: checks since its calibrations")
    ax.grid(True, alpha=0.3)
    if checks or limits:
        ax.legend(loc="upper left", fontsize=8)
    ax.figure.autofmt_xdate()


def _trend_values(drift: dict[str, Any]) -> list[float]:
    """The trend line's values at the calibration and at the projected crossing."""
    dev = drift["deviation"]
    start = _when(drift["since"]).timestamp()
    end = _when(dev["projected_crossing"]).timestamp()
    years = (end - start) / (365.25 * 86400.0)
    return [drift["limit"] - dev["rate_per_year"] * years, drift["limit"]]


def history_figure(hist: dict[str, Any], drift: dict[str, Any], path: str | Path) -> Path:
    """Write the history figure to `path` (PNG, SVG or PDF by its suffix)."""
    from kinecal._files import atomic_open
    from kinecal.errors import InputError
    from kinecal.report.figures import new_figure

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in ("png", "svg", "pdf"):
        raise InputError(f"a figure {path.name!r}: name it .png, .svg or .pdf",
                         option="--plot")
    fig, ax = new_figure()
    history_axes(ax, hist, drift)
    fig.tight_layout()
    with atomic_open(path, "wb", encoding=None) as fh:
        fig.savefig(fh, format=fmt, metadata={"Date": None} if fmt in ("pdf", "svg")
                    else None)
    return path
