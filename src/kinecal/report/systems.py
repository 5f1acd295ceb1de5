"""The report sections of a robot system's calibration (docs/systems.md): one per chain
(its errors before and after, on the calibration and validation rows, and the parameters
its rows identify alone) and one for the shared part (the parameters chains share, the
chains that see each alone, what only the combination identifies, and confounding
across chains)."""

from __future__ import annotations

import html
from typing import Any

from kinecal.report.markup import section, table

__all__ = ["system_sections"]


def _errors(by_tip: dict, tip: str, unit: str) -> str:
    rows = []
    for which, entries in by_tip.items():
        e = entries.get(tip)
        if e and e["n"]:
            rows.append((which, e["n"], e["before"]["rms"], e["after"]["rms"],
                         e["after"]["max"]))
    if not rows:
        return "<p>No rows of this chain were measured.</p>"
    return table(["rows", "observations", f"rms before [{unit}]", f"rms after [{unit}]",
                  f"max after [{unit}]"], rows)


def _chain(result: Any, tip: str, entry: dict, by_tip: dict) -> str:
    unit = result.nominal_model.length_unit
    ident = entry["identifiable"]
    body = _errors(by_tip, tip, unit)
    body += (f"<p>{entry['rows']} residual rows of this chain's data alone; they identify "
             f"{len(ident)} of the chain's {entry['parameters']} parameters"
             + (f": {html.escape(', '.join(ident))}" if ident else "") + ".</p>")
    return section(f"chain-{tip}", f"Chain {tip}", body)


def _shared(result: Any, sys: dict) -> str:
    table_ = result.parameter_table()
    rows = []
    for name, tips in sys["shared_seen_by"].items():
        p = table_[name]
        rows.append((name, p["nominal"], p["identified"], p["std"],
                     ", ".join(tips) or "the combination only"))
    head = (f"<p>{len(sys['shared'])} parameters belong to two or more chains (the links "
            "and joints they share)")
    if rows:
        body = (head + "; those calibrated, and the chains whose rows alone identify "
                "each:</p>" + table(["parameter", "nominal", "identified", "std. error",
                                     "seen alone by"], rows))
    else:
        body = head + "; none of them is calibrated.</p>"
    only = sys["combination_only"]
    if only:
        body += ("<p><strong>Identified only by the combination of chains</strong> (rows "
                 "that tie chains together, or one chain's rows separating what another's "
                 f"confound): {html.escape(', '.join(only))}.</p>")
    across = sys["confounded_across_chains"]
    if across:
        items = "".join(f"<li>{html.escape(n)} ~ {html.escape(', '.join(p))}</li>"
                        for n, p in across.items())
        body += f"<p>Held, confounded with parameters of other chains:</p><ul>{items}</ul>"
    return section("shared", "The shared part", body)


def system_sections(result: Any) -> list[str]:
    """The sections, none for a calibration that is not a robot system's."""
    extra = getattr(result, "extra", None) or {}
    sys = extra.get("system")
    if not sys:
        return []
    by_tip = extra.get("by_tip") or {}
    return [_chain(result, tip, entry, by_tip) for tip, entry in sys["tips"].items()] + [
        _shared(result, sys)]
