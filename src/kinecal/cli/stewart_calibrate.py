"""``kinecal stewart simulate|calibrate``: calibration data of a perturbed parallel-link CMM,
and the identification of its 42 geometric parameters (Liu, Liu and Wei 2008). Registered on
the ``stewart`` group of `kinecal.cli.stewart`, which imports this module."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count
from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import (
    check_unit,
    instrument_option,
    note_option,
    operator_option,
    quiet_option,
    report_option,
    seed_option,
    strict_option,
    unit_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.cli._stewart_common import (
    LEG_COLUMNS,
    POSE_COLUMNS,
    load_geometry_arg,
    poses_rad,
    read_columns,
    stewart_app,
)
from kinecal.errors import InputError

#: peak memory of ``stewart simulate`` per pose: measured 2.6 kB (rejection sampling of
#: the workspace), with a margin
_SIM_POSE_BYTES = 6144


@stewart_app.command("simulate")
def simulate(
    geometry: str = typer.Argument(..., help="Nominal geometry (bundled name or YAML path)."),
    poses: int = typer.Option(60, "--poses", help="Number of random workspace poses."),
    errors: str = typer.Option(
        "1e-3", "--errors", metavar="AMPLITUDE|TRUE.yaml", help="Amplitude of uniform "
        "geometry errors (geometry length unit), or a TRUE.yaml geometry."
    ),
    noise_position: float = typer.Option(1e-6, "--noise-position", help="Tip position std "
                                         "(geometry length unit; at most the machine's size)."),
    noise_rotation: float = typer.Option(1.0, "--noise-rotation", help="Orientation std, "
                                         "arcsec (at most 1 rad = 206265 arcsec)."),
    noise_legs: float = typer.Option(1e-6, "--noise-legs", help="Leg reading std (geometry "
                                     "length unit; at most the machine's size)."),
    seed: int = seed_option(),
    out: Path = typer.Option(..., "--out", help="DATA.csv: x..gamma (deg) and l1..l6."),
    truth_out: Path | None = typer.Option(None, "--truth-out", help="Write the true geometry."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
) -> None:
    """Simulate calibration data: measured poses and leg readings of a perturbed machine."""
    from kinecal.calibration.diagnostics.sizes import (
        check_angle_noise,
        check_length_noise,
        stewart_size,
    )
    from kinecal.calibration.stewart.calibrate import ARCSEC, perturb_geometry, simulate_stewart
    from kinecal.io.csvtable import write_table
    from kinecal.io.geometry import load_geometry, save_geometry
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    try:
        float(errors)
        errors_file = None
    except ValueError:
        errors_file = errors
    check_paths({"GEOMETRY": geometry, "--errors": errors_file},
                {"--out": out, "--truth-out": truth_out})
    with warnings_scope(strict):
        geom = load_geometry_arg(geometry)
        check_count(poses, "--poses", bytes_per_item=_SIM_POSE_BYTES)
        for name, v in (("--noise-position", noise_position), ("--noise-rotation", noise_rotation),
                        ("--noise-legs", noise_legs)):  # fmt: skip
            if not (np.isfinite(v) and v >= 0):
                raise InputError("expected a non-negative number", option=name)
        # plausible for the machine's size (kinecal.calibration.diagnostics.sizes)
        size, unit = stewart_size(geom), _geometry_unit(geometry)
        check_length_noise(noise_position, size, "--noise-position", unit)
        check_length_noise(noise_legs, size, "--noise-legs", unit)
        check_angle_noise(noise_rotation * ARCSEC, "--noise-rotation", f"{noise_rotation:g} arcsec")
        rng = np.random.default_rng(seed)
        try:
            amplitude = float(errors)
        except ValueError:
            true = load_geometry(errors)
        else:
            if not (np.isfinite(amplitude) and amplitude >= 0):
                raise InputError("expected a non-negative amplitude or a YAML file",
                                 option="--errors")
            check_length_noise(amplitude, size, "--errors", unit, "geometry error amplitude")
            true = perturb_geometry(geom, amplitude, rng)
        data = simulate_stewart(
            true,
            poses,
            rng=rng,
            position_noise=noise_position,
            rotation_noise=noise_rotation * ARCSEC,
            leg_noise=noise_legs,
        )
        deg = radians_to_degrees(data.poses)
        cols = {c: deg[:, k] for k, c in enumerate(POSE_COLUMNS)}
        cols.update({c: data.legs[:, k] for k, c in enumerate(LEG_COLUMNS)})
        write_outputs(more=[(out, lambda path: write_table(path, cols)),
                            (truth_out, lambda path: save_geometry(true, path))], quiet=quiet)
    if not quiet:
        typer.echo(f"wrote {poses} poses to {out}", err=True)


def _geometry_unit(spec: str) -> str:
    """The length unit a geometry file declares (``m`` when it says nothing)."""
    from kinecal._yaml import read_yaml_mapping
    from kinecal.io.geometry import geometry_path

    unit = read_yaml_mapping(geometry_path(spec)).get("length_unit", "m")
    return unit if isinstance(unit, str) else "m"


@stewart_app.command("calibrate")
def calibrate(
    geometry: str = typer.Argument(..., help="Nominal geometry (bundled name or YAML path)."),
    data: str = typer.Argument(..., help="CSV: x,y,z,alpha,beta,gamma (deg) and l1..l6."),
    validate: str | None = typer.Option(None, "--validate", help="Held-out DATA.csv."),
    out: Path | None = typer.Option(None, "--out", help="RESULT.json."),
    geometry_out: Path | None = typer.Option(
        None, "--geometry-out", help="Calibrated geometry YAML (load_geometry reads it)."
    ),
    report: Path | None = report_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the result JSON."),
    unit: str = unit_option(),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    instrument: str | None = instrument_option(),
    operator: str | None = operator_option(),
    note: str | None = note_option(),
) -> None:
    """Identify the 42 geometric parameters from measured poses and leg readings."""
    from kinecal.calibration.stewart.calibrate import StewartData, calibrate_stewart
    from kinecal.io.geometry import save_geometry

    shown = check_unit(unit)
    check_paths({"GEOMETRY": geometry, "DATA": data, "--validate": validate},
                {"--out": out, "--geometry-out": geometry_out, "--report": report})
    record = report_record(report, {"GEOMETRY": geometry, "DATA": data, "--validate": validate},
                           instrument, operator, note)
    with warnings_scope(strict) as found:
        geom = load_geometry_arg(geometry)
        unit = _geometry_unit(geometry)

        def load(spec: str, option: str) -> StewartData:
            x = poses_rad(read_columns(spec, POSE_COLUMNS, option))
            L = read_columns(spec, LEG_COLUMNS, option)
            return StewartData(x, L)

        cal = load(data, "DATA")
        val = load(validate, "--validate") if validate is not None else None
        try:
            res = calibrate_stewart(geom, cal, validate=val, length_unit=unit)
        except InputError as exc:
            raise InputError(exc.message, file=data) from None
        res.warnings = list(found)
        result = with_warnings(res.to_dict(), found)
        write_outputs(out=out, result=result, report=report,
                      write_report=lambda path: _report(res, path, record),
                      more=[(geometry_out, lambda path: save_geometry(res.geometry, path, unit))],
                      quiet=quiet or json_out)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(res.summary(shown))


def _report(res, path: Path, record) -> None:
    from kinecal.report.stewart import stewart_report

    stewart_report(res, path, provenance=record)
