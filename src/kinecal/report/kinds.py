"""The report section of a calibration from several measurement kinds: one table row per
measurement set (kind, file, observations, noise stated or estimated, error before and
after), the unknowns each set solved (pivots, points, planes), validation sets, and the
motions of the whole arm the mix does not see (docs/measurement-kinds.md)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from kinecal.report.markup import section, table

__all__ = ["kinds_section"]


def _rows(entries: list[dict], unit: str) -> list[tuple]:
    rows = []
    for e in entries:
        u = unit if e.get("unit") == "length" else e.get("unit")
        sigma = e.get("sigma")
        how = e.get("sigma_source", "")
        rows.append((e["kind"], Path(str(e["file"])).name, e["observations"],
                     f"{sigma:.4g} {u} ({how})" if sigma is not None else how,
                     e["before"]["rms"], e["after"]["rms"], e["after"]["max"]))
    return rows


def _unknowns(entries: list[dict]) -> list[tuple]:
    rows = []
    for e in entries:
        for u in e.get("unknowns") or []:
            if "matrix" in u:  # a camera's or board's mount (camera images, rigs)
                t = [row[3] for row in u["matrix"][:3]]
                rows.append((Path(str(e["file"])).name, f"{u['name']} ({u.get('frame', '')})",
                             "t = " + ", ".join(f"{v:.6g}" for v in t),
                             ", ".join(f"{v:.3g}" for v in u["std_translation"]) + "; "
                             + ", ".join(f"{v:.3g}" for v in u["std_rotation_deg"]) + " deg"))
                continue
            name = next((f"{k} {u[k]}" for k in ("pivot", "point", "plane") if k in u), None)
            if name is None:  # intrinsics and other unknowns without a place
                continue
            if "xyz" in u:
                where = ", ".join(f"{v:.6g}" for v in u["xyz"])
                std = ", ".join(f"{v:.3g}" for v in u["std"])
            else:
                where = ("normal " + ", ".join(f"{v:.6f}" for v in u["normal"])
                         + f"; offset {u['offset']:.6g}")
                std = f"tilt {u['std_tilt_rad']:.3g} rad, offset {u['std_offset']:.3g}"
            rows.append((Path(str(e["file"])).name, name, where, std))
    return rows


def kinds_section(result: Any) -> str:
    """The section, or the empty string for a calibration from one tracker file."""
    extra = getattr(result, "extra", None) or {}
    entries = extra.get("kinds")
    if not entries:
        return ""
    unit = result.nominal_model.length_unit
    head = ["kind", "file", "observations", "noise (1 sigma)", f"rms before [{unit}]",
            f"rms after [{unit}]", f"max after [{unit}]"]
    body = ("<p>Error per observation: a distance error (ballbar, pair), a touch's "
            "distance from its point or plane, a tracker point's distance error; each set's "
            "own unknowns fitted to it.</p>" + table(head, _rows(entries, unit), left=2))
    unknowns = _unknowns(entries)
    if unknowns:
        body += ("<p>Unknowns of the gauges and mounts, solved with the arm (measurement "
                 f"frame or the mount's link, {html.escape(unit)}; standard errors):</p>"
                 + table(["file", "gauge", "value", "std. error"], unknowns, left=4))
    if extra.get("validation_kinds"):
        body += ("<p>Validation sets (their own unknowns fitted with the arm held at the "
                 "nominal and at the calibrated geometry):</p>"
                 + table(head, _rows(extra["validation_kinds"], unit), left=2))
    if extra.get("not_seen_words"):
        body += ("<p><strong>Not seen by this mix of measurements:</strong> "
                 f"{html.escape(extra['not_seen_words'])}. The parameters that only move "
                 "those are held at nominal; the calibrated tool points are right up to "
                 "these motions.</p>")
    return section("kinds", "Measurement sets", body)
