"""Drift over time: the checks of a robot's current calibration as time series.

Per parameter direction (each joint's offset, the base frame: what every check estimates
with its standard error, `kinecal.registry.check`) the drift rate is the slope of a
weighted least-squares line through the checks' estimates (weights ``1 / std^2``), with
its standard error, per year. The systematic error a check finds (``deviation``) is
fitted by a straight line in time as well; when it grows (slope above twice its standard
error) the projected date of crossing the limit is where the line reaches it. A robot
whose last check exceeds the limit has crossed it already (``crossed``: the first such
check's date). Linear drift of the parameters makes the error grow linearly once it is
well above the noise; a projection is no promise, and says how many checks it rests on.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np

__all__ = ["SECONDS_PER_YEAR", "deviation_trend", "direction_rates", "drift_summary"]

SECONDS_PER_YEAR = 365.25 * 86400.0
#: a slope counts as growth above this many standard errors
SIGNIFICANT = 2.0


def _at(date: str) -> float:
    return datetime.fromisoformat(date).timestamp()


def _date(at: float) -> str:
    return (datetime(1970, 1, 1, tzinfo=UTC) + timedelta(seconds=at)).isoformat(
        timespec="seconds")


def _line(t: np.ndarray, y: np.ndarray, w: np.ndarray | None = None
          ) -> tuple[float, float, float] | None:
    """Weighted straight line ``y = a + b t``: ``(a, b, std of b)``; None below 2 points
    or without spread in `t`. Without weights the scatter about the line gives the
    standard error (with 3 points or more)."""
    if t.size < 2 or np.ptp(t) <= 0:
        return None
    scatter = w is None
    w = np.ones_like(t) if w is None else w
    X = np.column_stack([np.ones_like(t), t])
    G = X.T @ (X * w[:, None])
    coef = np.linalg.solve(G, X.T @ (w * y))
    cov = np.linalg.inv(G)
    if scatter:
        dof = t.size - 2
        s2 = float(np.sum((y - X @ coef) ** 2) / dof) if dof > 0 else float("nan")
        cov = cov * s2
    return float(coef[0]), float(coef[1]), float(math.sqrt(max(cov[1, 1], 0.0)))


def deviation_trend(points: list[tuple[float, float]], start: float, limit: float | None
                    ) -> dict[str, Any]:
    """The trend of the systematic error: ``points`` ``(at, deviation)`` (epoch seconds,
    length unit) of the checks since the calibration at `start`; module docstring."""
    pts = [(a, d) for a, d in points if d is not None and math.isfinite(d)]
    out: dict[str, Any] = {"checks": len(pts), "rate_per_year": None, "rate_std": None,
                           "growing": False, "projected_crossing": None, "crossed": None}
    if limit is not None:
        over = [a for a, d in pts if d > limit]
        if pts and pts[-1][1] > limit:
            out["crossed"] = _date(over[0])
    t = np.array([(a - start) / SECONDS_PER_YEAR for a, _ in pts])
    y = np.array([d for _, d in pts])
    fit = _line(t, y)
    if fit is None:
        return out
    a, b, sb = fit
    out.update(rate_per_year=b, rate_std=None if math.isnan(sb) else sb)
    growing = b > 0 and (not math.isnan(sb) and b > SIGNIFICANT * sb)
    out["growing"] = bool(growing)
    if growing and limit is not None and out["crossed"] is None:
        years = (limit - a) / b
        out["projected_crossing"] = _date(start + years * SECONDS_PER_YEAR)
    return out


def direction_rates(checks: list[dict[str, Any]], start: float) -> dict[str, dict]:
    """Drift rate per parameter direction (per year, the direction's unit) over `checks`
    (history events) since `start`."""
    series: dict[str, list[tuple[float, float, float, str]]] = {}
    for ev in checks:
        t = (_at(ev["date"]) - start) / SECONDS_PER_YEAR
        for name, est in ((ev.get("summary") or {}).get("directions") or {}).items():
            if est.get("std") and est["std"] > 0 and math.isfinite(est["change"]):
                series.setdefault(name, []).append((t, est["change"], est["std"],
                                                    est.get("unit", "")))
    out = {}
    for name, pts in series.items():
        t = np.array([p[0] for p in pts])
        y = np.array([p[1] for p in pts])
        w = 1.0 / np.array([p[2] for p in pts]) ** 2
        fit = _line(t, y, w)
        if fit is None:
            continue
        _, b, sb = fit
        out[name] = {"rate_per_year": b, "rate_std": sb, "unit": f"{pts[0][3]}/year",
                     "checks": len(pts), "significant": bool(abs(b) > SIGNIFICANT * sb)}
    return dict(sorted(out.items(), key=lambda kv: -abs(kv[1]["rate_per_year"])
                       / max(kv[1]["rate_std"], 1e-300)))


def drift_summary(history: dict[str, Any]) -> dict[str, Any]:
    """The drift of a robot's current arm calibration from its history (module
    docstring): ``{calibration, since, limit, deviation: {...}, directions: {...}}``."""
    events = history.get("events") or []
    current = (history.get("current") or {}).get("arm")
    cal = next((e for e in events if e["id"] == current), None)
    if cal is None:
        return {"calibration": None, "since": None, "limit": None,
                "deviation": deviation_trend([], 0.0, None), "directions": {}}
    start = _at(cal["date"])
    checks = [e for e in events if e["kind"] == "check" and e.get("calibration") == current]
    limit = checks[-1]["limit"] if checks else None
    return {
        "calibration": current, "since": cal["date"], "limit": limit,
        "deviation": deviation_trend([(_at(e["date"]), e["deviation"]) for e in checks],
                                     start, limit),
        "directions": direction_rates(checks, start),
    }
