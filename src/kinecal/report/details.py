"""Report sections beyond the core tables: per-axis errors, parameter correlations, and the
confounding table with units (used by `kinecal.report.html.calibration_report`)."""

from __future__ import annotations

import html
from typing import Any

import numpy as np

__all__ = ["axis_section", "confounded_rows", "correlation_section"]

#: correlations beyond this magnitude are listed as pairs under the matrix
STRONG = 0.9


def _unit(model: Any, name: str) -> str:
    """Unit of a parameter in the confounding coefficients (length unit or rad)."""
    angle = bool(model.is_angle()[model.index([name])[0]])
    return "rad" if angle else model.length_unit


def confounded_rows(result: Any) -> list[tuple[str, str]]:
    """``(parameter, combination)`` rows of the unidentifiable parameters, each term with
    its coefficient's unit (e.g. ``+100 mm/rad * a6``): a unit change of the parameter
    equals the combination's change."""
    rep = result.identifiability
    model = result.nominal_model
    rows = []
    for name in rep.unidentifiable:
        terms = sorted(rep.confounded_with.get(name, {}).items(), key=lambda kv: -abs(kv[1]))[:4]
        mine = _unit(model, name)
        text = ", ".join(f"{c:+.3g} {_unit(model, other)}/{mine} * {other}"
                         for other, c in terms) or "no effect on the measured points"
        rows.append((name, text))
    return rows


def axis_section(result: Any, table) -> str:
    """Per-axis (x, y, z) position errors before and after, from ``extra["axis_errors"]``
    (`kinecal.metrology.stats.axis_stats`); empty when the result has none."""
    axes = (result.extra or {}).get("axis_errors")
    if not axes:
        return ""
    unit = result.nominal_model.length_unit
    rows = []
    for label, group in axes.items():
        for when in ("before", "after"):
            s = group[when]
            rows.append((f"{label}, {when}", *(s[a][k] for a in "xyz" for k in ("mean", "rms",
                                                                              "max"))))
    head = ["poses"] + [f"{k} d{a} [{unit}]" for a in "xyz" for k in ("mean", "rms", "max |.|")]
    body = table(head, rows)
    return (f'<section id="axes"><h2>Position error per axis</h2>{body}'
            "<p>Model minus measured, per axis of the measurement frame. A mean far from zero "
            "on one axis after calibration is a systematic offset (a frame or scale "
            "error).</p></section>")


def _color(r: float) -> str:
    """Background colour of a correlation: white at 0, red (+1) or blue (-1) at the ends."""
    a = min(abs(r), 1.0)
    if r >= 0:
        return f"rgb(255,{int(255 * (1 - a))},{int(255 * (1 - a))})"
    return f"rgb({int(255 * (1 - a))},{int(255 * (1 - a))},255)"


def correlation_section(result: Any) -> str:
    """The correlation matrix of the free, identifiable parameters (from the covariance),
    colour-coded, with the pairs beyond `STRONG` listed; empty without a usable covariance."""
    C = np.asarray(result.covariance, dtype=float)
    free = list(result.free)
    if C.ndim != 2 or C.shape[0] != len(free) or len(free) < 2 or not np.isfinite(C).all():
        return ""
    idx = result.nominal_model.index(free)
    ok = np.isfinite(result.std[idx]) & (np.diag(C) > 0)
    names = [n for n, k in zip(free, ok, strict=True) if k]
    if len(names) < 2:
        return ""
    sub = C[np.ix_(ok, ok)]
    s = np.sqrt(np.diag(sub))
    R = np.clip(sub / s[:, None] / s[None, :], -1.0, 1.0)
    head = "".join(f'<th style="writing-mode:vertical-rl">{html.escape(n)}</th>' for n in names)
    body = []
    for i, n in enumerate(names):
        cells = "".join(f'<td style="background:{_color(R[i, j])};font-size:.75em">'
                        f"{R[i, j]:+.2f}</td>" for j in range(len(names)))
        body.append(f'<tr><th class="l">{html.escape(n)}</th>{cells}</tr>')
    pairs = [(names[i], names[j], R[i, j]) for i in range(len(names))
             for j in range(i + 1, len(names)) if abs(R[i, j]) > STRONG]
    pairs.sort(key=lambda p: -abs(p[2]))
    strong = ("<p>Strongly correlated pairs (|r| &gt; " f"{STRONG}): "
              + html.escape(", ".join(f"{a} / {b} ({r:+.3f})" for a, b, r in pairs[:12]))
              + ("" if len(pairs) <= 12 else ", ...") + ".</p>" if pairs else
              f"<p>No pair is correlated beyond |r| = {STRONG}.</p>")
    return ('<section id="correlation"><h2>Parameter correlations</h2>'
            "<p>Correlation coefficients of the identified parameters (from their covariance). "
            "Values near +-1 mean the data separate the two parameters poorly.</p>"
            f'<div style="overflow-x:auto"><table><thead><tr><th></th>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>{strong}</section>")
