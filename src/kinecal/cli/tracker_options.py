"""Options of ``kinecal calibrate`` for tracker files from several set-ups and 6-DoF
instruments: ``--orientation-format``, ``--station-per-file``, ``--validate-register``
(docs/measurement-kinds.md, docs/cli.md), and what they do to the files read."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.errors import InputError

__all__ = ["TRACKER_OPTIONS", "check_tracker_options", "has_station_column",
           "orientation_format_option",
           "per_file_station", "station_per_file_option", "validate_register_option"]

#: the option names, for "applies to ..." messages
TRACKER_OPTIONS = ("--orientation-format", "--station-per-file", "--validate-register")


def orientation_format_option() -> Any:
    import typer

    return typer.Option(
        None, "--orientation-format", metavar="FORMAT[:deg]",
        help="Orientation columns of tracker files: quaternion (qw,qx,qy,qz; default), rpy "
        "(roll,pitch,yaw), euler-zyx (a,b,c), rotvec (rx,ry,rz) or a named Euler convention "
        "intrinsic-SEQ / extrinsic-SEQ (a,b,c; e.g. intrinsic-xyz:deg for a Leica T-Mac); "
        ":deg for degrees.")


def station_per_file_option() -> Any:
    import typer

    return typer.Option(False, "--station-per-file", help="Each tracker file is its own "
                        "set-up (station, named by the file) with its own base frame "
                        "base@NAME; a station column does this within a file.")


def validate_register_option() -> Any:
    import typer

    return typer.Option(None, "--validate-register", metavar="all|N%", help="Validation "
                        "data from another set-up: refit the base frame and the tool on all "
                        "of its rows, or on N% of them (drawn with --seed) and judge on the "
                        "others.")


def check_tracker_options(orientation: str | None, register: str | None,
                          validate: list[str] | None) -> None:
    """Refuse bad values before any file is read."""
    if orientation is not None:
        from kinecal.io.poses import PoseFormat

        PoseFormat.parse(orientation, option="--orientation-format")
    if register is not None:
        from kinecal.calibration.serial.validation_frame import parse_register

        parse_register(register)
        if not validate:
            raise InputError("applies with --validate only", option="--validate-register")


def per_file_station(data, path: str | Path):
    """`data` (tracker rows) as one station named by its file (`--station-per-file`);
    other kinds and files with a station column are refused."""
    from kinecal.data import Measurements
    from kinecal.io.tracker_columns import station_name

    if not isinstance(data, Measurements):
        raise InputError(f"{Path(path).name}: a {data.kind} file has no base frame of its own",
                         option="--station-per-file")
    if data.station is not None:
        raise InputError(f"{Path(path).name} has a station column: give either the column "
                         "or --station-per-file", option="--station-per-file")
    name = station_name(re.sub(r"[^A-Za-z0-9_+-]", "_", Path(path).stem) or "station")
    return dataclasses.replace(data, station=np.zeros(len(data), dtype=np.intp),
                               station_names=(name,))


def has_station_column(spec: str, option: str) -> bool:
    """True when the CSV `spec` has a ``station`` column (several set-ups: the stacked
    path)."""
    from kinecal.cli._common import resolve_data_path
    from kinecal.io.measurements import csv_header

    return "station" in csv_header(resolve_data_path(spec, option))
