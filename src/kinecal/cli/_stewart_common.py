"""What the ``kinecal stewart`` commands share: the command group, the column names of the
poses and legs CSV files and their readers (`kinecal.cli.stewart`: ik, fk;
`kinecal.cli.stewart_calibrate`: simulate, calibrate)."""

from __future__ import annotations

import typer

from kinecal.cli._app import app
from kinecal.cli._stewart_io import (
    LEG_COLUMNS,
    POSE_COLUMNS,
    load_geometry_arg,
    poses_rad,
    read_columns,
)

__all__ = ["LEG_COLUMNS", "POSE_COLUMNS", "load_geometry_arg", "poses_rad", "read_columns",
           "stewart_app"]

stewart_app = typer.Typer(
    help="Parallel-link CMM (Stewart platform; Liu, Liu, Wei 2008): ik, fk, simulate, "
         "calibrate.",
    no_args_is_help=True,
)
app.add_typer(stewart_app, name="stewart")
