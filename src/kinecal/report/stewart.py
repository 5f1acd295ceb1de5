"""HTML report of a Stewart-platform geometry calibration (``kinecal stewart calibrate
--report``): warnings, summary, leg residuals before and after, the 42 parameters with
their standard errors, and the per-pose residual figure."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from kinecal.errors import InputError
from kinecal.report.document import write_report
from kinecal.report.figures import _per_pose, figure_png, new_figure
from kinecal.report.markup import image_tag, kv, page, section, table
from kinecal.report.provenance import Provenance, collect, provenance_section, time_rows
from kinecal.report.summary import COVERAGE_K, expanded_note
from kinecal.report.warnings import warnings_section

__all__ = ["stewart_report"]


def stewart_report(result: Any, path: str | Path, provenance: Provenance | None = None) -> Path:
    """Write the report of a `StewartCalibrationResult` to `path` (atomic; PDF for a
    ``.pdf`` path) with its record (`provenance`: date and version when omitted); returns
    it."""
    from kinecal.kinematics.stewart.platform import PARAMETER_NAMES

    path = Path(path)
    if path.is_dir():
        raise InputError("is a directory; expected a file path to write", file=path)
    u = result.length_unit
    name = result.nominal.name or "Stewart platform"
    cal = result.calibration
    summary = kv([
        ("geometry", name), ("length unit", u), ("calibration poses", cal["n"]),
        ("validation poses", None if result.validation is None else result.validation["n"]),
        ("rank (42 parameters)", f"{result.rank} of 42"),
        ("condition number", float(result.condition_number)),
        ("uncertainty bounded", bool(result.bounded)),
        ("outlier poses (0-based)", ", ".join(map(str, result.outliers)) or "none"),
        ("iterations", int(result.iterations)), ("evaluations", int(result.evaluations)),
        *time_rows(result.seconds),
    ])
    rows = []
    for label, part in (("calibration", cal), ("validation", result.validation)):
        if part is None:
            continue
        for when in ("before", "after"):
            s = part[when]
            rows.append((f"{label}, {when}", part["n"], s["mean"], s["rms"], s["std"], s["max"]))
    legs = table(["poses", "n", f"mean |r| [{u}]", f"rms [{u}]", f"std [{u}]", f"max [{u}]"],
                 rows)
    legs += ("<p>Leg residual: reading predicted by the geometry's inverse kinematics from the "
             "measured pose minus the reading (Liu, Liu and Wei 2008, eq. 4-5), every leg of "
             "every pose.</p>")
    prow = []
    for n, a, b, s in zip(PARAMETER_NAMES, result.nominal.parameters,
                          result.geometry.parameters, result.std, strict=True):
        ok = math.isfinite(s)
        prow.append((n, u, float(a), float(b), float(b - a),
                     float(s) if ok else "not identifiable",
                     COVERAGE_K * float(s) if ok else "not identifiable"))
    params = table(["parameter", "unit", "nominal", "identified", "delta",
                    "std. error u (1 sigma)", "U (k = 2)"], prow, left=2, digits=6)
    params += expanded_note()
    provenance = collect() if provenance is None else provenance
    sections = [warnings_section(result.warnings), provenance_section(provenance),
                section("summary", "Geometry and data", summary),
                section("errors", "Leg residuals before and after", legs),
                section("parameters", "Parameters", params)]
    if result.errors_before is not None and result.errors_after is not None:
        fig, ax = new_figure()
        _per_pose(ax, result.errors_before, result.errors_after, u,
                  f"Calibration poses ({len(result.errors_before)}): norm of the 6 leg residuals")
        sections.append(section("figures", "Figures", image_tag(
            figure_png(fig), "per-pose leg residuals",
            "Per-pose leg residual (norm over the six legs) before (grey) and after (blue).",
            "fig-errors")))
    doc = page(f"Calibration of {name}", f"{cal['n']} calibration poses, lengths in {u}",
               sections, provenance.created)
    return write_report(path, doc)
