"""``kinecal stewart ik|fk|simulate|calibrate``: the parallel-link CMM of Liu, Liu and Wei (2008).

Poses CSV: ``x,y,z,alpha,beta,gamma`` (probe tip, length unit of the geometry, angles in
degrees, R = Rz(gamma) Ry(beta) Rx(alpha)); legs CSV: ``l1..l6``; calibration data CSV:
both. GEOMETRY is a bundled name (``liu2008-cmm``) or a YAML path.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count
from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    resolve_data_path,
    warnings_scope,
    with_warnings,
    write_json,
)
from kinecal.cli._csv_out import format_rows, write_columns, write_csv
from kinecal.cli._options import (
    check_unit,
    choices,
    instrument_option,
    note_option,
    operator_option,
    quiet_option,
    report_option,
    seed_option,
    strict_option,
    unit_option,
)
from kinecal.diagnostics import expect
from kinecal.errors import InputError

#: peak memory of ``stewart simulate`` per pose: measured 2.6 kB (rejection sampling of
#: the workspace), with a margin
_SIM_POSE_BYTES = 6144

stewart_app = typer.Typer(
    help="Parallel-link CMM (Stewart platform; Liu, Liu, Wei 2008): ik, fk, simulate, "
         "calibrate.",
    no_args_is_help=True,
)
app.add_typer(stewart_app, name="stewart")

POSE_COLUMNS = ("x", "y", "z", "alpha", "beta", "gamma")
LEG_COLUMNS = tuple(f"l{i}" for i in range(1, 7))


def _geometry(spec: str):
    from kinecal.io.geometry import load_geometry

    return load_geometry(spec)


def _read(path: str, columns: tuple[str, ...], option: str) -> np.ndarray:
    from kinecal.io.csvtable import read_table

    p = resolve_data_path(path, option)
    table = read_table(p, columns)
    return np.column_stack([table[c] for c in columns])


def _poses_rad(deg: np.ndarray) -> np.ndarray:
    from kinecal.kinematics.stewart.platform import degrees_to_radians

    return degrees_to_radians(deg)


#: rows per block of ``stewart fk``: one block solves while the one before is formatted
FK_BLOCK = 16384


@stewart_app.command("ik")
def ik(
    geometry: str = typer.Argument(..., help="Bundled geometry name or YAML path."),
    poses: str = typer.Argument(..., help="CSV with x,y,z,alpha,beta,gamma (deg)."),
    check_range: bool = typer.Option(
        True, "--check-range/--no-check-range",
        help="Reject poses whose legs leave the range by more than 1 % of the stroke "
        "(closer: warning leg-range)."),
    strict: bool = strict_option(),
) -> None:
    """Inverse kinematics: leg readings l1..l6 on stdout (Liu, Liu, Wei 2008, eqs 4-5)."""
    geom = _geometry(geometry)
    x = _poses_rad(_read(poses, POSE_COLUMNS, "POSES"))
    legs = geom.inverse(x)
    with warnings_scope(strict):
        if check_range:  # the row of the first pose whose legs leave the range
            geom.check_legs(legs, file=poses)
        write_columns(list(LEG_COLUMNS), list(legs.T))


@stewart_app.command("fk")
def fk(
    geometry: str = typer.Argument(..., help="Bundled geometry name or YAML path."),
    legs: str = typer.Argument(..., help="CSV with l1..l6."),
    method: str = typer.Option("newton", "--method", metavar=choices("newton", "pso"),
                               help="Exact Newton solver or the PSO of Liu, Liu, Wei 2008."),
    all_modes: bool = typer.Option(False, "--all", help="Every real assembly mode, one row each."),
    seed: int = seed_option("Random seed (pso, --all; an integer >= 0)."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON instead of CSV."),
    strict: bool = strict_option(),
) -> None:
    """Forward kinematics: probe poses x,y,z,alpha,beta,gamma (deg) from leg readings."""
    if method not in ("newton", "pso"):
        raise InputError(f"unknown method {method!r}; expected newton or pso", option="--method")
    if all_modes and method != "newton":
        raise InputError("--all finds every assembly mode by multi-start Newton; it does not "
                         f"take --method {method}", option="--method")
    geom = _geometry(geometry)
    path = str(resolve_data_path(legs, "LEGS"))
    L = _read(legs, LEG_COLUMNS, "LEGS")
    with warnings_scope(strict) as found:
        L = geom.check_legs(L, file=path)
        with expect("leg-range"):  # judged once above, not again per solve
            if all_modes:
                _fk_all(geom, L, path, seed, json_out, found)
            else:
                _fk_solve(geom, L, path, method, seed, json_out, found)


def _fk_solve(geom, L: np.ndarray, path: str, method: str, seed: int, json_out: bool,
              found: list) -> None:
    """`stewart fk` after its checks: Newton in blocks (CSV) or one call (PSO, JSON)."""
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    if method == "newton" and not json_out:
        _fk_blocks(geom, L, path)
        return
    # a row without any real solution is an input error, whatever the method
    newton = geom.forward(L, on_failure="flag")
    if not newton.converged.all():
        i = int(np.argmin(newton.converged))
        raise InputError(
            f"leg lengths {np.array2string(L[i], precision=6)} have no real assembly "
            f"(closest residual {newton.residual[i]:.3g})",
            file=path,
            row=i + 1,
        )
    res = newton if method == "newton" else geom.forward(L, "pso", rng=seed, on_failure="flag")
    deg = radians_to_degrees(res.poses)
    if json_out:
        rows = [
            {**dict(zip(POSE_COLUMNS, d, strict=True)), "converged": bool(c), "residual": float(r),
             "iterations": int(k)}
            for d, c, r, k in zip(deg, res.converged, res.residual, res.iterations, strict=True)
        ]  # fmt: skip
        echo_json(with_warnings({"method": method, "elapsed": res.elapsed, "poses": rows},
                                found))
        return
    write_columns([*POSE_COLUMNS, "converged", "residual"],
                   [*deg.T, np.where(res.converged, "true", "false").tolist(), res.residual])


def _fk_blocks(geom, L: np.ndarray, path: str) -> None:
    """Newton forward kinematics as CSV, a block of `FK_BLOCK` rows at a time: a worker
    thread solves the next block while this one formats the last (the solver's numpy work
    runs without the GIL, the float formatting needs it), so that the command's throughput
    approaches the API's. The whole CSV is written only once every row has converged (a
    row without a real solution is an input error; nothing is half-written). The tolerance
    is the one a single call takes over all rows."""
    import contextvars
    from concurrent.futures import ThreadPoolExecutor

    from kinecal.kinematics.stewart.forward import default_tol
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    tol = default_tol(L + geom.leg_offsets)
    blocks = [slice(s, min(s + FK_BLOCK, len(L))) for s in range(0, len(L), FK_BLOCK)]

    def solve(b: slice):
        return geom.forward(L[b], on_failure="flag", options={"tol": tol})

    text = []
    ctx = contextvars.copy_context()  # the worker sees the command's diagnostics scope
    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = pool.submit(ctx.run, solve, blocks[0]) if blocks else None
        for k, b in enumerate(blocks):
            res = pending.result()
            pending = (pool.submit(ctx.run, solve, blocks[k + 1]) if k + 1 < len(blocks)
                       else None)
            if not res.converged.all():
                i = int(np.argmin(res.converged))
                if pending is not None:
                    pending.cancel()
                raise InputError(
                    f"leg lengths {np.array2string(L[b][i], precision=6)} have no real "
                    f"assembly (closest residual {res.residual[i]:.3g})",
                    file=path, row=b.start + i + 1)
            deg = radians_to_degrees(res.poses)
            text.append(format_rows([*deg.T, ["true"] * len(deg), res.residual]))
    sys.stdout.write(",".join([*POSE_COLUMNS, "converged", "residual"]) + "\n")
    sys.stdout.write("".join(text))


def _fk_all(geom, L: np.ndarray, path: str, seed: int, json_out: bool, found: list) -> None:
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    out = []
    for i in range(L.shape[0]):  # one multi-start batch per reading
        modes = geom.forward_all(L[i], rng=seed)
        if len(modes) == 0:
            raise InputError(
                f"leg lengths {np.array2string(L[i], precision=6)} have no real assembly",
                file=path,
                row=i + 1,
            )
        out.append(modes)
    if json_out:
        echo_json(with_warnings(
            {
                "method": "newton-multistart",
                "rows": [
                    {
                        "row": i + 1,
                        "modes": [
                            {**dict(zip(POSE_COLUMNS, d, strict=True)), "above": bool(a),
                             "residual": float(r), "converged": True}
                            for d, a, r in zip(radians_to_degrees(m.poses), m.above, m.residual,
                                               strict=True)
                        ],
                    }
                    for i, m in enumerate(out)
                ],
            },
            found))  # fmt: skip
        return
    header = ["row", "mode", *POSE_COLUMNS, "above", "converged", "residual"]
    rows = []
    for i, m in enumerate(out):
        for k, (d, a, r) in enumerate(
            zip(radians_to_degrees(m.poses), m.above, m.residual, strict=True)
        ):
            rows.append([str(i + 1), str(k + 1), *d.tolist(), str(bool(a)).lower(), "true", r])
    write_csv(header, rows)


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
        geom = _geometry(geometry)
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
        write_table(out, cols)
        if truth_out is not None:
            save_geometry(true, truth_out)
    if not quiet:
        typer.echo(f"wrote {poses} poses to {out}", err=True)


def _geometry_unit(spec: str) -> str:
    """The length unit a geometry file declares (``m`` when it says nothing)."""
    from kinecal._files import read_yaml_mapping
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
        geom = _geometry(geometry)
        unit = _geometry_unit(geometry)

        def load(spec: str, option: str) -> StewartData:
            x = _poses_rad(_read(spec, POSE_COLUMNS, option))
            L = _read(spec, LEG_COLUMNS, option)
            return StewartData(x, L)

        cal = load(data, "DATA")
        val = load(validate, "--validate") if validate is not None else None
        try:
            res = calibrate_stewart(geom, cal, validate=val, length_unit=unit)
        except InputError as exc:
            raise InputError(exc.message, file=data) from None
        res.warnings = list(found)
        result = with_warnings(res.to_dict(), found)
        if out is not None:
            write_json(out, result)
        if geometry_out is not None:
            save_geometry(res.geometry, geometry_out, unit)
        if report is not None:
            from kinecal.report.stewart import stewart_report

            stewart_report(res, report, provenance=record)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(res.summary(shown))
