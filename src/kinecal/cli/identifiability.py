"""Serial-arm command ``identifiability``: rank, identifiable and unidentifiable parameters,
condition number and observability indices of a model on poses or data files."""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal._limits import check_count
from kinecal.cli._app import app
from kinecal.cli._calibrate_options import ERROR_MODELS, FIXTURE_HELP
from kinecal.cli._common import (
    echo_json,
    resolve_data_path,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    choices,
    load_model_arg,
    quiet_option,
    single_tip,
    strict_option,
    tip_links_option,
    tip_option,
)
from kinecal.cli._serial_common import POSE_BYTES, free_option
from kinecal.cli.calibrate_kinds import (
    file_kind,
    identifiability_files,
)
from kinecal.cli.tracker_options import (
    has_station_column,
)
from kinecal.errors import InputError


@app.command()
def identifiability(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    tip: str | None = tip_option(),
    data: list[str] | None = typer.Option(
        None, "--data", help="CSV of the poses to analyse: measurements of any kind, or "
        "joint values q1..qn alone (e.g. from select-poses); repeat it for a mix of kinds "
        "(docs/measurement-kinds.md)."),
    poses: int | None = typer.Option(None, "--poses", help="Random poses when no --data is "
                                     "given (default 50)."),
    free: str = typer.Option("all", "--free", metavar=choices("all", "identifiable", "NAMES"),
                             help="All parameters, the identifiable ones or comma-separated "
                             "names."),
    seed: int | None = typer.Option(None, "--seed", min=0, help="Random seed for the poses "
                                    "(without --data; default 0)."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    error_model: str | None = typer.Option(
        None, "--error-model", metavar=choices(*ERROR_MODELS[:-1]), help="Also analyse "
        "joint-error terms, or families joined by '+' (default: the model file's "
        "joint_errors)."),
    harmonics: int | None = typer.Option(None, "--harmonics",
                                         help="Harmonic order (default 2)."),
    fixture: list[Path] | None = typer.Option(None, "--fixture", help=FIXTURE_HELP),
    angle_unit: str | None = angle_unit_option("the --data files' joint columns"),
) -> None:
    """Rank, identifiable and unidentifiable parameters, condition number, O1-O5; with
    --data, what calibrate would free from those poses."""
    from kinecal.cli.systems import is_system_arg

    if is_system_arg(model, base_link, tip_link):
        from kinecal.cli.systems import system_identifiability

        return system_identifiability({**locals(), "free": free_option(free)})
    if tip is not None:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    tip_link = single_tip(tip_link)
    from kinecal.calibration.diagnostics.serial import check_pose_set
    from kinecal.calibration.serial.api import CALIBRATION_RANK_TOL
    from kinecal.calibration.serial.problem import resolve_free
    from kinecal.calibration.serial.simulate import simulate as run
    from kinecal.kinematics.serial.markers import model_for_markers

    for option, value in (("--poses", poses), ("--seed", seed)):
        if data and value is not None:
            raise InputError("applies to random poses only, not with --data", option=option)
    if fixture and not data:
        raise InputError("applies to --data point and plane files", option="--fixture")
    if check_angle_unit(angle_unit) and not data:
        raise InputError("applies to --data files", option="--angle-unit")
    if data and (len(data) > 1 or fixture or file_kind(data[0], "--data") != "tracker"
                 or has_station_column(data[0], "--data")):
        if error_model is not None or harmonics is not None:
            raise InputError("applies to one tracker file only", option="--error-model")
        return identifiability_files(model, data, base_link=base_link, tip_link=tip_link,
                                     free=free_option(free), json_out=json_out, quiet=quiet,
                                     strict=strict, fixture=fixture, angle_unit=angle_unit)
    data = data[0] if data else None
    with warnings_scope(strict) as found:
        m = load_model_arg(model, base_link, tip_link)
        if data is not None:
            meas = _poses_to_analyse(m, resolve_data_path(data, "--data"), angle_unit)
        else:
            poses = check_count(50 if poses is None else poses, "--poses",
                                bytes_per_item=POSE_BYTES * (m.n_joints + 10))
            meas = run(m, poses, errors="zero", rng=seed or 0).data
        m = model_for_markers(m, meas.marker_names)  # one tool point per marker measured
        if error_model is not None or harmonics is not None or m.joint_errors is not None:
            from kinecal.calibration.serial.joint_identifiability import identifiability_with_terms

            # the geometry first, then the joint-error coefficients beyond it
            m, report = identifiability_with_terms(m, meas, free_option(free), error_model,
                                                   harmonics)
        elif data is not None:  # what calibrate frees from these poses: its own rule
            from kinecal.calibration.serial.solve import data_identifiability

            report = data_identifiability(m, meas, free_option(free),
                                          rank_tol=CALIBRATION_RANK_TOL)
        else:
            _, report = resolve_free(m, meas, free_option(free))
        if data is not None:
            check_pose_set(m, meas, report, CALIBRATION_RANK_TOL)
    if json_out:
        echo_json(with_warnings(report.to_dict(), found))
        return
    if quiet:
        return
    typer.echo(report.explain())
    typer.echo("identifiable: " + ", ".join(report.identifiable))
    typer.echo("observability: " + ", ".join(f"{k}={v:.4g}"
                                             for k, v in report.observability.items()))


def _poses_to_analyse(model, path, angle_unit: str | None = None):
    """The `Measurements` of ``identifiability --data``: a measurement file as it is, or a
    joints-only file (``q1..qn``, what ``select-poses`` writes) measured by the nominal
    model (only the poses matter to the analysis)."""
    from kinecal.calibration.serial.simulate import simulate as run
    from kinecal.io.measurements import read_joints, read_markers, read_measurements
    from kinecal.io.poses import first_csv_row
    from kinecal.io.wide import is_wide

    header = first_csv_row(path)
    if set(header) & {"x", "y", "z", "x_t"} or is_wide(header):
        return read_measurements(path, model, angle_unit=angle_unit)
    q = read_joints(path, model, angle_unit=angle_unit)
    marker, _ = read_markers(path, model)
    return run(model, len(q), errors="zero", q=q, marker=marker).data
