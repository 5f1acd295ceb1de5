"""The summary block at the top of a calibration report: the result a reader wants first.

Validation error before -> after (mean, RMS, 95th percentile, max), the improvement, the
orientation error when measured, the model uncertainty left by the calibration (1 sigma
and expanded, k = 2) and the warnings; on the calibration poses, said so, when there are no
validation poses. Also the one sentence every report uses to state its uncertainties.
"""

from __future__ import annotations

import html
from typing import Any

from kinecal.report.markup import fmt

__all__ = ["COVERAGE_K", "calibration_summary", "expanded_note", "summary_block"]

#: coverage factor of the expanded uncertainties (GUM, JCGM 100:2008, 6.2-6.3)
COVERAGE_K = 2.0


def expanded_note(what: str = "Standard errors") -> str:
    """One ``<p>`` saying what the 1-sigma and the expanded (k = 2) values are."""
    return (f"<p>{html.escape(what)} are standard uncertainties u (1 sigma, from the fit's "
            "residuals: a type A evaluation); U = k u is the expanded uncertainty with "
            "coverage factor <strong>k = 2</strong> (about 95 % coverage for a normal "
            "distribution, GUM JCGM 100:2008). Neither includes the measuring instrument's own "
            "uncertainty unless it was stated (<code>--sigma</code>).</p>")


def summary_block(paragraphs: list[str]) -> str:
    """The highlighted ``<section id="overview" class="summary">`` (paragraphs are HTML)."""
    body = "".join(f"<p>{p}</p>" for p in paragraphs if p)
    return f'<section id="overview" class="summary"><h2>Summary</h2>{body}</section>'


def _arrow(st: dict[str, dict[str, float]], key: str, unit: str) -> str:
    return (f"{html.escape(fmt(st['before'][key]))} &rarr; "
            f"<strong>{html.escape(fmt(st['after'][key]))}</strong> {html.escape(unit)}")


def _warnings(warnings: Any) -> str:
    items = list(warnings or [])
    if not items:
        return "Warnings: none."
    codes = sorted({str(w.get("code", "") if isinstance(w, dict) else getattr(w, "code", ""))
                    for w in items})
    return (f'<strong>{len(items)} warning{"s" if len(items) > 1 else ""}</strong> '
            f"({html.escape(', '.join(c for c in codes if c))}): see "
            '<a href="#warnings">Warnings</a> before trusting the numbers.')


def calibration_summary(result: Any) -> str:
    """The summary block of a `CalibrationResult` (see the module docstring)."""
    unit = result.nominal_model.length_unit
    val = result.validation_stats
    st, where = (val, "validation") if val is not None else (result.calibration_stats,
                                                             "calibration")
    n = int(st["before"]["n"])
    lines = [f"<strong>Position error on the {n} {where} poses</strong> (before &rarr; after "
             f"calibration): mean {_arrow(st, 'mean', unit)}; RMS {_arrow(st, 'rms', unit)}; "
             f"95th percentile {_arrow(st, 'p95', unit)}; max {_arrow(st, 'max', unit)}.",
             f"Improvement of the mean error: <strong>{result.improvement_percent:.2f} %"
             "</strong>."]
    if val is None:
        lines.append("No validation poses: these are the poses the model was fitted to, "
                     "which flatter it; hold out poses (<code>--validate</code>) to measure "
                     "the accuracy a user will see.")
    rot = result.rotation_groups().get(where)
    if rot:
        lines.append(f"Orientation error (mean): {_arrow(rot, 'mean', 'deg')}.")
    pred = result.predicted_error_summary()
    value = pred.get(f"{where}_mean")
    if value is not None:
        lines.append(f"Uncertainty the calibration leaves in the model (RMS position error "
                     f"on these poses): u = {html.escape(fmt(value))} {html.escape(unit)} "
                     f"(1 sigma), U = {html.escape(fmt(COVERAGE_K * value))} "
                     f"{html.escape(unit)} (k = 2).")
    lines.append(_warnings(getattr(result, "warnings", None)))
    return summary_block(lines)
