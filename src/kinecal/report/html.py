"""Self-contained HTML reports: calibration, hand-eye and paper reproduction.

A report is one HTML file: inline CSS, figures embedded as base64 PNG ``data:`` URIs, no
script and no network access. Every user-supplied string (model names, file names,
parameter names, messages) goes through `html.escape`. Files are written atomically.
The building blocks (`fmt`, `table`, `image_tag`, `section`, `page`) are in
`kinecal.report.markup` and re-exported here.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

from kinecal.errors import InputError
from kinecal.metrology.stats import stat_rows
from kinecal.report.details import axis_section, confounded_rows, correlation_section
from kinecal.report.document import write_report
from kinecal.report.figures import (
    calibration_figures,
    figure_png,
    plot_handeye_stations,
    plot_histories,
)
from kinecal.report.markup import (
    FIG_HEIGHT,
    FIG_WIDTH,
    fmt,
    image_tag,
    kv,
    page,
    section,
    table,
)
from kinecal.report.provenance import Provenance, collect, provenance_section, time_rows
from kinecal.report.summary import COVERAGE_K, calibration_summary, expanded_note
from kinecal.report.warnings import warnings_section

__all__ = [
    "FIG_HEIGHT",
    "FIG_WIDTH",
    "calibration_report",
    "fmt",
    "handeye_report",
    "image_tag",
    "page",
    "reproduce_report",
    "section",
    "table",
]

# --------------------------------------------------------------------- calibration
def _model_and_data(result: Any) -> str:
    """The "Model and data" table: model, units, method, pose counts, solver figures."""
    nom = result.nominal_model
    angle = "deg" if nom.angle_unit == "deg" else "rad"
    n_val = None if result.val_before is None else int(result.val_before.size)
    data_src = result.extra.get("data") if isinstance(result.extra, dict) else None
    return kv([
        ("model", nom.name), ("convention", nom.convention), ("joints", nom.n_joints),
        ("parameters", nom.n_params), ("units", f"{nom.length_unit}, {angle}"),
        ("method", result.method), ("seed", result.seed),
        ("calibration poses", int(result.errors_before.size)), ("validation poses", n_val),
        *([("data", data_src)] if data_src else []),
        ("iterations", int(result.iterations)), ("evaluations", int(result.evaluations)),
        *time_rows(result.seconds), ("solver message", result.message or "-"),
    ])


def _identifiability(result: Any) -> str:
    """Rank, condition number, observability and what is confounded with what."""
    rep = result.identifiability
    confounded = confounded_rows(result)
    ident = kv([
        ("rank", f"{rep.rank} of {len(rep.names)}"),
        ("condition number (scaled Jacobian)", float(rep.condition_number)),
        ("free parameters", len(result.free)),
        *[(k, float(v)) for k, v in rep.observability.items()],
    ])
    if confounded:
        return ident + ("<p>Not identifiable from these poses (held at nominal; when freed "
                        "explicitly, free with an arbitrary value), with the identifiable "
                        "parameters each is a combination of:</p>"
                        + table(["parameter", "combination of"], confounded, left=2))
    return ident + "<p>Every candidate parameter is identifiable from these poses.</p>"


def _parameters(result: Any) -> str:
    """Nominal, identified, delta, u (1 sigma) and U (k = 2) of every parameter."""
    nom = result.nominal_model
    angle = "deg" if nom.angle_unit == "deg" else "rad"
    ptab = result.parameter_table()
    is_angle = dict(zip(nom.parameter_names, nom.is_angle(), strict=True))

    def u(e: dict, k: float) -> Any:
        if not e["free"]:
            return None
        return k * e["std"] if math.isfinite(e["std"]) else "not identifiable"

    prow = [(n, angle if is_angle[n] else nom.length_unit, e["nominal"], e["identified"],
             e["identified"] - e["nominal"], u(e, 1.0), u(e, COVERAGE_K),
             "free" if e["free"] else "fixed") for n, e in ptab.items()]
    return table(["parameter", "unit", "nominal", "identified", "delta",
                  "std. error u (1 sigma)", "U (k = 2)", "status"], prow, left=2,
                 row_classes=["" if e["free"] else "fixed" for e in ptab.values()]
                 ) + expanded_note()


def _errors(result: Any) -> str:
    """Position (and orientation) error statistics before and after, the uncertainty left
    in the model and, with a stated noise, its test."""
    unit = result.nominal_model.length_unit
    rows = [(f"{label}, {when}", st["n"], st["mean"], st["rms"], st["std"], st.get("p95"),
             st["max"]) for label, when, st in stat_rows(result.position_groups())]
    errors = (table(["poses", "n", f"mean [{unit}]", f"rms [{unit}]", f"std [{unit}]",
                     f"95th percentile [{unit}]", f"max [{unit}]"], rows)
              + "<p>Mean error reduced by "
              f"<strong>{result.improvement_percent:.2f} %</strong> on the "
              f"{'validation' if result.validation_stats else 'calibration'} poses "
              "(distance errors, ISO 9283-style position accuracy statistics).</p>")
    if result.rotation_groups():
        rot_rows = [(f"{label}, {when}", st["n"], st["mean"], st["rms"], st["std"], st["max"])
                    for label, when, st in stat_rows(result.rotation_groups())]
        errors += ("<p>Orientation error (geodesic angle between the model's and the measured "
                   "tool frame):</p>"
                   + table(["poses", "n", "mean [deg]", "rms [deg]", "std [deg]", "max [deg]"],
                           rot_rows))
    pred = result.predicted_error_summary()
    if pred["calibration_mean"] is not None:
        parts = [(k, pred[f"{k}_mean"]) for k in ("calibration", "validation")
                 if pred[f"{k}_mean"] is not None]
        text = ", ".join(f"u = {v:.3g} {unit}, U = {COVERAGE_K * v:.3g} {unit} on the {k} poses"
                         for k, v in parts)
        errors += ("<p>Uncertainty the calibration leaves in the model (RMS position error "
                   "from the parameter covariance, first order; u: 1 sigma, U: expanded, "
                   f"k = 2): {html.escape(text)}.</p>")
    if "noise" in getattr(result, "extra", {}):  # --sigma: the test, known-noise uncertainty
        from kinecal.calibration.diagnostics.noise import noise_lines

        errors += "".join(f"<p>{html.escape(line)}.</p>" for line in noise_lines(result))
    return errors


#: figure captions of the calibration report, by figure kind
CAPTIONS = {
    "errors": "Per-pose position error on the calibration poses in file order (pose 1 "
              "is the first data row), before (grey) and after (blue) calibration.",
    "validation": "Per-pose position error on the held-out validation poses, in file order.",
    "sorted": "The same errors sorted by size (calibration solid, validation dashed), "
              "before (grey) and after (blue).",
    "histogram": "Distribution of the calibration errors (log-spaced bins).",
    "convergence": "Mean position error after each solver iteration.",
}


def _calibration_sections(result: Any, pngs: dict[str, bytes],
                          provenance: Provenance | None = None,
                          validation: Any = None) -> list[str]:
    from kinecal.report.compensation import compensation_section
    from kinecal.report.conditions import conditions_section
    from kinecal.report.iso9283 import validation_iso9283_section
    from kinecal.report.kinds import kinds_section
    from kinecal.report.residual_maps import error_model_section
    from kinecal.report.systems import system_sections

    figs = "".join(image_tag(png, f"{kind} figure", CAPTIONS[kind], f"fig-{kind}")
                   for kind, png in pngs.items())
    return [
        calibration_summary(result),
        warnings_section(getattr(result, "warnings", None)),
        provenance_section(provenance),
        section("summary", "Model and data", _model_and_data(result)),
        section("errors", "Position error before and after", _errors(result)),
        kinds_section(result),
        *system_sections(result),
        validation_iso9283_section(result, validation),
        section("identifiability", "Identifiability", _identifiability(result)),
        section("parameters", "Parameters", _parameters(result)),
        compensation_section(result),
        section("figures", "Figures", figs),
        axis_section(result, table),
        correlation_section(result),
        *error_model_section(result),
        *conditions_section(result),
    ]


def calibration_report(result: Any, path: str | Path,
                       pngs: dict[str, bytes] | None = None,
                       provenance: Provenance | None = None, validation: Any = None) -> Path:
    """Write the report of a `CalibrationResult` (HTML, or PDF for a ``.pdf`` path);
    returns `path`.

    Sections: the summary (validation error before -> after, improvement, uncertainty,
    warnings), the warnings, the record (`provenance`: date, version, command line, input
    files with their SHA-256, operator, instrument, note; date and version only when
    omitted), model and data, before/after statistics on the calibration and validation
    poses, ISO 9283 figures when the validation `Measurements` (`validation`) repeat poses
    (`kinecal.report.iso9283.repeated_validation`), identifiability (rank,
    unidentifiable parameters and what they are confounded with, condition number, O1-O5),
    parameter table (nominal, identified, delta, standard error u and expanded U with
    k = 2), and the figures of `kinecal.report.figures.plot_calibration` (`pngs`, computed
    when omitted).
    """
    path = Path(path)
    if path.is_dir():  # before the figures: fail fast on a user mistake
        raise InputError("is a directory; expected a file path to write", file=path)
    pngs = calibration_figures(result) if pngs is None else pngs
    provenance = collect() if provenance is None else provenance
    nom = result.nominal_model
    doc = page(f"Calibration of {nom.name}",
               f"method {result.method}, {int(result.errors_before.size)} calibration poses",
               _calibration_sections(result, pngs, provenance, validation),
               provenance.created)
    return write_report(path, doc)


# ----------------------------------------------------------------------- hand-eye
def handeye_report(result: dict[str, Any], path: str | Path,
                   provenance: Provenance | None = None) -> Path:
    """Write the report of a hand-eye result dict (``kinecal handeye --json``), HTML or
    PDF (``.pdf``), with its record (`provenance`, date and version when omitted).

    Sections: setup and solver (length unit, first-order uncertainty of X), the transform X,
    the target pose, residual statistics, per-station residual table and figure (outliers
    marked).
    """
    stations = result.get("stations") or []
    outliers = {int(i) for i in result.get("outliers") or []}
    setup = str(result.get("setup", "eye-in-hand"))
    frame = "cam2flange" if setup == "eye-in-hand" else "cam2base"
    tframe = "target2base" if setup == "eye-in-hand" else "target2flange"
    u = str(result.get("length_unit") or "input unit")
    xu = result.get("x_uncertainty") or {}
    summary = kv([
        ("file", result.get("file", "-")), ("setup", setup),
        ("method", result.get("method", "-")), ("refinement", result.get("refine", "-")),
        ("stations", len(stations)), ("seed", result.get("seed")), ("length unit", u),
        ("rotation rms [deg]", result.get("rotation_rms_deg")),
        (f"translation rms [{u}]", result.get("translation_rms")),
        ("X uncertainty, rotation [deg] (1 sigma, worst axis)", xu.get("rotation_deg")),
        (f"X uncertainty, translation [{u}] (1 sigma, worst direction)",
         xu.get("translation")),
        ("X uncertainty, rotation [deg] (expanded, k = 2)", _twice(xu.get("rotation_deg"))),
        (f"X uncertainty, translation [{u}] (expanded, k = 2)",
         _twice(xu.get("translation"))),
        ("outlier stations (0-based)", ", ".join(str(i) for i in sorted(outliers)) or "none"),
    ])

    def transform_table(T: Any) -> str:
        return table(["", "c1", "c2", "c3", f"t [{u}]"],
                     [[f"r{i + 1}", *[float(v) for v in row]] for i, row in enumerate(T or [])])

    xtab = transform_table(result.get("X"))
    ttab = transform_table(result.get("target"))
    srows = [(k, s.get("rotation_deg"), s.get("translation"),
              "outlier" if k in outliers else "") for k, s in enumerate(stations)]
    stab = table(["station", "rotation [deg]", f"translation [{u}]", ""], srows)
    fig = image_tag(figure_png(plot_handeye_stations(result)), "per-station residuals",
                    "Rotation and translation residual of every station (red: outliers).",
                    "fig-stations")
    provenance = collect() if provenance is None else provenance
    doc = page("Hand-eye calibration", f"{setup}, method {result.get('method', '-')}", [
        warnings_section(result.get("warnings")),
        provenance_section(provenance),
        section("summary", "Setup and solver", summary),
        section("transform", f"X ({frame})", xtab),
        section("target", f"Target pose ({tframe})", ttab),
        section("figures", "Per-station residuals", fig),
        section("stations", "Stations", stab),
    ], provenance.created)
    return write_report(path, doc)


def _twice(value: Any) -> Any:
    return COVERAGE_K * float(value) if isinstance(value, int | float) else None


# ---------------------------------------------------------------------- reproduce
def _histories(obj: Any, prefix: str = "") -> dict[str, list[float]]:
    """Every numeric list stored under a key containing ``history`` (nested dicts)."""
    found: dict[str, list[float]] = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            name = f"{prefix}.{k}" if prefix else str(k)
            if ("history" in str(k) and isinstance(v, list) and len(v) > 1
                    and all(isinstance(x, int | float) for x in v)):
                found[name] = [float(x) for x in v]
            else:
                found.update(_histories(v, name))
    return found


def _flat(obj: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """Scalars of nested dicts as ``(dotted.key, value)``; long lists summarised."""
    out: list[tuple[str, Any]] = []
    for k, v in obj.items():
        name = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, dict):
            out += _flat(v, name)
        elif isinstance(v, list):
            if len(v) <= 8 and all(isinstance(x, int | float | str) for x in v):
                out.append((name, ", ".join(fmt(x) for x in v)))
            else:
                out.append((name, f"[{len(v)} values]"))
        else:
            out.append((name, v))
    return out


def reproduce_report(result: dict[str, Any], path: str | Path,
                     provenance: Provenance | None = None) -> Path:
    """Write the HTML report of a paper reproduction (``experiments.<paper>.run()``).

    Sections: the rows table (the paper's values beside kinecal's), the experiment's own
    text rendering when its module is importable, the other numbers, and convergence
    curves of every ``*history*`` list found in the result.
    """
    paper = str(result.get("paper", "?"))
    rows = [r for r in result.get("rows") or [] if isinstance(r, dict)]
    cols: list[str] = []
    for r in rows:
        cols += [c for c in r if c not in cols]
    rtab = (table(cols, [[r.get(c) for c in cols] for r in rows], digits=10) if rows
            else "<p>no rows</p>")
    provenance = collect() if provenance is None else provenance
    sections = [provenance_section(provenance), section("rows", "Table", rtab)]
    try:
        from kinecal.experiments import experiment_module

        text = experiment_module(paper).render(result)
        sections.append(section("rendered", "As printed by kinecal reproduce",
                                f"<pre>{html.escape(text)}</pre>"))
    except Exception:  # the report must not fail on an unknown or older result dict
        pass
    other = {k: v for k, v in result.items() if k not in ("rows", "paper")}
    sections.append(section("details", "Details", table(None, _flat(other), digits=6)))
    hist = _histories(result)
    if hist:
        png = figure_png(plot_histories(hist))
        sections.append(section("figures", "Convergence",
                                image_tag(png, "convergence", ", ".join(hist), "fig-history")))
    doc = page(f"Reproduction of {paper}", str(result.get("source", "")), sections,
               provenance.created)
    return write_report(path, doc)
