"""HTML reports of the registry: a robot's history (``registry history --report``) and the
fleet (``registry report --fleet``), self-contained pages built with `kinecal.report`'s
markup (tables, an embedded figure, inline CSS)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from kinecal.report.markup import kv, page, section, table

__all__ = ["fleet_report", "history_report"]


def _stamp() -> str:
    from kinecal.registry.location import format_date, now

    return format_date(now())


def history_report(hist: dict[str, Any], drift: dict[str, Any], path: str | Path) -> Path:
    """Write `hist` with its figure, drift and records as an HTML (or PDF) report."""
    from kinecal.registry.figures import history_axes
    from kinecal.report.document import check_report_path, write_report
    from kinecal.report.figures import figure_png, new_figure
    from kinecal.report.markup import image_tag

    check_report_path(path)
    fig, ax = new_figure()
    history_axes(ax, hist, drift)
    figure = image_tag(figure_png(fig), f"checks of {hist['serial']} over time",
                       "Systematic error found by each check (colour: verdict), the limit "
                       "(dotted), calibrations (vertical lines; the current one solid) and "
                       "the trend since the current calibration.")
    dev = drift["deviation"]
    summary = kv([
        ("current calibration", drift["calibration"] or "-"),
        ("since", drift["since"] or "-"),
        ("checks since", dev["checks"]),
        ("limit", drift["limit"]),
        ("systematic error growth per year", dev["rate_per_year"]),
        ("its standard error", dev["rate_std"]),
        ("limit crossed on", dev["crossed"] or "-"),
        ("projected crossing", dev["projected_crossing"] or "-"),
    ])
    directions = table(["direction", "rate per year", "std", "unit", "checks",
                        "significant"],
                       [(n, d["rate_per_year"], d["rate_std"], d["unit"], d["checks"],
                         d["significant"]) for n, d in drift["directions"].items()])
    rows = []
    for ev in hist["events"]:
        if ev["kind"] == "calibration":
            s = ev.get("summary") or {}
            rows.append((ev["date"], ev["id"], "calibration" + (" (current)" if ev.get(
                "current") else ""), ev.get("model") or ev.get("subject"), s.get("rms"),
                         None, None, ev.get("operator") or ""))
        else:
            rows.append((ev["date"], ev["id"], "check", ev["verdict"], ev["deviation"],
                         ev["limit"], ev["p_value"], ev.get("operator") or ""))
    records = table(["date", "id", "record", "model / verdict", "RMS / deviation", "limit",
                     "p-value", "operator"], rows, left=4)
    doc = page(f"History of robot {hist['serial']}", "kinecal registry history",
               [section("figure", "Checks over time", figure),
                section("drift", "Drift since the current calibration", summary),
                section("directions", "Drift rate per parameter direction", directions),
                section("records", "Records", records)], created=_stamp())
    return write_report(path, doc)


def fleet_report(rows: list[dict[str, Any]], path: str | Path, where: str = "") -> Path:
    """Write the fleet's table (`kinecal.registry.fleet_view.fleet_rows`) as a report."""
    from kinecal.report.document import check_report_path, write_report

    check_report_path(path, "--fleet")
    body = []
    for r in rows:
        last = r["last_check"] or {}
        cur = r["current"] or {}
        body.append((r["serial"], r["model"] or "-", cur.get("id"), cur.get("date"),
                     last.get("date"), last.get("verdict"), last.get("deviation"),
                     last.get("limit"), r["rate_per_year"],
                     r["crossed"] or r["projected_crossing"] or "-"))
    counts: dict[str, int] = {}
    for r in rows:
        v = (r["last_check"] or {}).get("verdict") or "never checked"
        counts[v] = counts.get(v, 0) + 1
    summary = "<p>" + html.escape(", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
                                  ) + "</p>"
    tab = table(["serial", "model", "calibration", "calibrated", "last check", "verdict",
                 "deviation", "limit", "growth / year", "limit crossed / projected"], body,
                left=2)
    doc = page("Fleet", f"kinecal registry {where}".strip(),
               [section("summary", f"{len(rows)} robots, worst drifters first", summary),
                section("robots", "Robots", tab)], created=_stamp())
    return write_report(path, doc)
