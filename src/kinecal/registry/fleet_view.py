"""The fleet's table (``registry report --fleet``): every robot with its current
calibration, last check and verdict, drift, worst drifters first.

Order: robots whose last check says ``recalibrate`` or that crossed their limit, then by
how soon the trend of their checks reaches the limit (`kinecal.registry.drift`), then by
their last deviation as a share of the limit; robots never checked last.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from kinecal.registry.drift import deviation_trend

__all__ = ["fleet_rows"]

_VERDICT_RANK = {"recalibrate": 0, "drifted": 1, "valid": 2, None: 3}


def fleet_rows(robots: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows of `kinecal.registry.store.Registry.robots`, with their drift, sorted worst
    first (module docstring)."""
    rows = []
    for r in robots:
        cur = r["current"]
        last = r["last_check"]
        trend = None
        if cur is not None:
            pts = [(at, dev) for at, dev, _lim, cal in r["deviations"] if cal == cur["id"]]
            limit = last["limit"] if last else None
            trend = deviation_trend(pts, cur["at"], limit)
        share = (last["deviation"] / last["limit"]) if last and last["limit"] else None
        rows.append({
            "serial": r["serial"], "model": r["model"], "calibrations": r["calibrations"],
            "checks": r["checks"],
            "current": None if cur is None else {"id": cur["id"], "date": cur["date"]},
            "last_check": last, "share_of_limit": share,
            "rate_per_year": None if trend is None else trend["rate_per_year"],
            "projected_crossing": None if trend is None else trend["projected_crossing"],
            "crossed": None if trend is None else trend["crossed"],
        })

    def key(row: dict[str, Any]) -> tuple:
        last = row["last_check"]
        verdict = None if last is None else last["verdict"]
        urgent = 0 if verdict == "recalibrate" or row["crossed"] else 1
        when = row["projected_crossing"]
        soon = datetime.fromisoformat(when).timestamp() if when else float("inf")
        return (urgent, soon, _VERDICT_RANK[verdict], -(row["share_of_limit"] or 0.0),
                row["serial"])

    return sorted(rows, key=key)
