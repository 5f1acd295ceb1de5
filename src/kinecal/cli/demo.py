"""``kinecal demo``: the main job on bundled real data, no arguments needed.

Calibrates the UR5 model on the 1000 laser-tracker grid poses of the bundled
``ur5-laser-tracker`` dataset, validates on its 20 random poses, prints the before/after
table and writes ``result.json``, the calibrated model, ``report.html`` and the figures;
then goes beyond geometry (``--error-model auto``: joint compliance, harmonic transmission
errors and encoder scale chosen by cross-validation on the calibration poses; writes
``error-model.json``, ``ur5-calibrated-auto.yaml`` and ``report-error-model.html``) and
finally compensates the 20 held-out poses as a joint program (``compensated.csv``).
"""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, echo_json, progress

#: what the demo runs on
DEMO_MODEL = "ur5"
DEMO_DATA = "ur5-laser-tracker:grid"
DEMO_VALIDATION = "ur5-laser-tracker:random"


def demo_record() -> object:
    """The record of the demo's reports: the command line and the bundled inputs (model,
    calibration and validation poses) with their SHA-256."""
    from kinecal.cli._common import report_record

    return report_record(Path("report.html"), {"MODEL": DEMO_MODEL, "DATA": DEMO_DATA,
                                               "--validate": DEMO_VALIDATION})


def error_model_step(model, data, val, out: Path) -> tuple[object, list[Path]]:
    """The demo's second step: ``--error-model auto`` on the same poses; its files."""
    from kinecal.calibration.serial.error_model import calibrate_error_model
    from kinecal.report.html import calibration_report

    res = calibrate_error_model(model, data, "auto", validate=val, rng=0)
    res.extra["data"] = f"{DEMO_DATA} (validation: {DEMO_VALIDATION})"
    written = [out / "error-model.json", out / f"{model.name}-calibrated-auto.yaml"]
    res.to_json(written[0])
    res.save_model(written[1])
    written.append(calibration_report(res, out / "report-error-model.html",
                                      provenance=demo_record()))
    return res, written


def run_demo(out: Path, quiet: bool = False) -> tuple[object, list[Path], tuple, object]:
    """Run the demo calibration and write its files into `out`.

    Returns
    -------
    result : CalibrationResult
    written : list of Path
        ``result.json``, ``<model>-calibrated.yaml``, ``report.html``, the PNGs and
        ``compensated.csv``.
    compensation : tuple
        The `CompensationResult` of the held-out poses, its CSV path and its text.
    error_model : ErrorModelResult
        The ``--error-model auto`` calibration of the same poses.
    """
    from kinecal.calibration.serial.api import calibrate
    from kinecal.io.measurements import read_measurements
    from kinecal.io.models import load_model
    from kinecal.report.figures import CALIBRATION_KINDS

    check_paths({}, {}, folders={"--out": (out, [
        "result.json", f"{DEMO_MODEL}-calibrated.yaml", "report.html", "compensated.csv",
        "error-model.json", f"{DEMO_MODEL}-calibrated-auto.yaml", "report-error-model.html",
        *(f"{kind}.png" for kind in CALIBRATION_KINDS)])})
    from kinecal._files import all_or_nothing

    # the demo's files all new or all as they were (kinecal.cli._outputs)
    with all_or_nothing(), progress("demo: calibrate ur5 on laser-tracker data", 4,
                                    quiet) as update:
        model = load_model(DEMO_MODEL)
        data = read_measurements(DEMO_DATA, model)
        val = read_measurements(DEMO_VALIDATION, model)
        update()
        res = calibrate(model, data, "lm", validate=val, rng=0,
                        progress=lambda it, best: update(0, best))
        res.extra["data"] = f"{DEMO_DATA} (validation: {DEMO_VALIDATION})"
        update(1, float(res.errors_after.mean()))
        from kinecal.report.figures import calibration_figures, save_calibration_figures
        from kinecal.report.html import calibration_report

        pngs = calibration_figures(res)
        update()
        written = [out / "result.json", out / f"{model.name}-calibrated.yaml"]
        res.to_json(written[0])
        res.save_model(written[1])
        written.append(calibration_report(res, out / "report.html", pngs,
                                          provenance=demo_record()))
        written += save_calibration_figures(res, out, pngs)
        auto, files = error_model_step(model, data, val, out)
        written += files
        from kinecal.cli.compensate import demo_compensation

        compensation = demo_compensation(res, out, DEMO_VALIDATION)
        written.append(compensation[1])
        update()
    return res, written, compensation, auto


@app.command()
def demo(
    out: Path = typer.Option(Path("kinecal-demo"), "--out",
                             help="Directory for result.json, the calibrated model, "
                                  "report.html and the figures."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
    json_out: bool = typer.Option(False, "--json", help="Print the result JSON (with the "
                                  "written files under 'files') instead of the table."),
) -> None:
    """Calibrate a UR5 on bundled laser-tracker data and write a report (no arguments needed).
    """
    res, written, (comp, _, comp_text), auto = run_demo(out, quiet or json_out)
    if json_out:
        echo_json({**res.to_dict(), "compensation": comp.stats(),
                   "error_model": {**auto.extra["error_model"],
                                   "validation": auto.validation_stats},
                   "files": [str(p) for p in written]})
        return
    typer.echo(f"kinecal demo: UR5 calibrated on {DEMO_DATA} (1000 poses), validated on "
               f"{DEMO_VALIDATION} (20 held-out poses)\n")
    typer.echo(res.summary())
    from kinecal.calibration.serial.error_model import error_model_text

    typer.echo("\nbeyond geometry (--error-model auto): joint compliance, harmonic transmission "
               "errors and encoder scale, chosen on the calibration poses only"
               + error_model_text(auto)[1:])
    typer.echo("\n" + comp_text)
    typer.echo(f"\nwrote {len(written)} files to {out}/:")
    for path in written:
        typer.echo(f"  {path}")
    typer.echo(f"open {out / 'report.html'} in a browser for the full report "
               f"({out / 'report-error-model.html'}: the error model and its residual maps)")
