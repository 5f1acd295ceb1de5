"""``kinecal stewart ik|fk|simulate|calibrate``: the parallel-link CMM of Liu, Liu and Wei (2008).

Poses CSV: ``x,y,z,alpha,beta,gamma`` (probe tip, length unit of the geometry, angles in
degrees, R = Rz(gamma) Ry(beta) Rx(alpha)); legs CSV: ``l1..l6``; calibration data CSV:
both. GEOMETRY is a bundled name (``liu2008-cmm``) or a YAML path.
"""

from __future__ import annotations

import typer

from kinecal.cli._common import (
    warnings_scope,
)
from kinecal.cli._csv_out import write_columns
from kinecal.cli._options import (
    choices,
    seed_option,
    strict_option,
)
from kinecal.cli._stewart_common import (
    LEG_COLUMNS,
    POSE_COLUMNS,
    load_geometry_arg,
    poses_rad,
    read_columns,
    stewart_app,
)


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
    geom = load_geometry_arg(geometry)
    x = poses_rad(read_columns(poses, POSE_COLUMNS, "POSES"))
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
    given = dict(locals())
    from kinecal.cli._stewart_fk import run_fk

    return run_fk(**given)


# simulate and calibrate: kinecal.cli.stewart_calibrate (registered on the same group)
import kinecal.cli.stewart_calibrate  # noqa: E402, F401
