"""The plain-text summary of a serial-arm `CalibrationResult`: identifiability, the
before/after tables, uncertainty left, noise, prior, outliers and warnings."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kinecal._reproducible import seconds_text
from kinecal.metrology.stats import stat_rows

if TYPE_CHECKING:
    from kinecal.calibration.serial.result import CalibrationResult

__all__ = ["summary_text"]


def summary_text(res: CalibrationResult, unit: str | None = None) -> str:
    """Plain-text summary of `res` (`CalibrationResult.summary`); `unit`: the length unit of
    the text (``mm``, ``um``, ``m``, or ``auto``/None: `CalibrationResult.display_unit`)."""
    shown = res.display_unit(unit)
    unit, f = shown.name, shown.factor
    rep = res.identifiability
    lines = [
        f"model {res.nominal_model.name} ({res.nominal_model.convention}), method "
        f"{res.method}: {len(res.free)} free parameters, rank {rep.rank} of "
        f"{len(rep.names)}, condition number {rep.condition_number:.3g}",
    ]
    free = set(res.free)
    held = [n for n in res.unidentifiable() if n not in free]
    loose = res.unidentifiable_free()  # a prior bounds the rest (its own lines)
    if held:
        lines.append("not identifiable (held at nominal): " + ", ".join(held))
    if loose:
        lines.append("not identifiable (free, value arbitrary, no standard error): "
                     + ", ".join(loose))
    head = f"{'':12s} {'n':>5s} {'mean':>10s} {'rms':>10s} {'std':>10s} {'max':>10s}"
    tables = [(f"position error [{unit}]", res.position_groups())]
    if res.rotation_groups():
        tables.append(("orientation error [deg]", res.rotation_groups()))
    for k, (title, groups) in enumerate(tables):
        lines += ["", title, head]
        g = f if k == 0 else 1.0  # orientation errors stay in degrees
        for label, when, s in stat_rows(groups):
            lines.append(f"{label[:3] + '. ' + when:12s} {s['n']:5d} {s['mean'] * g:10.4g} "
                         f"{s['rms'] * g:10.4g} {s['std'] * g:10.4g} {s['max'] * g:10.4g}")
    lines.append(f"improvement of the mean error: {res.improvement_percent:.2f} %")
    pred = res.predicted_error_summary()
    if not res.bounded:
        lines.append("model uncertainty left: not bounded (these poses do not determine "
                     + ", ".join(res.lost) + ")")
    elif pred["calibration_mean"] is not None:
        def size(v: float) -> str:
            return f"{v * f:.3g} {unit}" if np.isfinite(v) else "not bounded"

        where = f"{size(pred['calibration_mean'])} on the calibration poses"
        if pred["validation_mean"] is not None:
            where += f", {size(pred['validation_mean'])} on the validation poses"
        lines.append(f"model uncertainty left (1 sigma, first order): {where}")
    if "noise" in res.extra:
        from kinecal.calibration.diagnostics.noise import noise_lines

        lines += noise_lines(res, shown)
    if res.extra.get("prior"):
        from kinecal.calibration.serial.prior_fit import prior_lines

        lines += prior_lines(res.extra["prior"], [n for n in res.unidentifiable()
                                                   if n in free and n not in loose])
    lines.append(f"{res.iterations} iterations, {res.evaluations} evaluations"
                 + seconds_text(res.seconds))
    if res.outliers:
        how = ("left out of the last fit" if res.extra.get("loss", "linear") !=
               "linear" else "chi-square rule")
        lines.append(f"outlier rows (0-based, {how}): {res.outliers}")
    if res.warnings:
        lines += ["", f"warnings ({len(res.warnings)}):"]
        lines += [f"  [{d.code}] {d.message}" for d in res.warnings]
    return "\n".join(lines)
