"""Optional column sets of tracker measurement files: the station, the measured orientation,
the per-axis standard deviations (docs/file-formats.md).

========================  =======================================================  =========
columns                   meaning                                                  unit
========================  =======================================================  =========
``station``               which tracker set-up measured the row (a name, e.g. A):  text
                          each station has its own base frame ``base@NAME``
``qw, qx, qy, qz``        tool orientation, a unit quaternion (default)            -
``a, b, c`` (or another   tool orientation in the format ``--orientation-format``  deg / rad
format's columns)         names (`kinecal.io.poses.PoseFormat`: ``rpy``,
                          ``rotvec``, ``intrinsic-xyz:deg`` ...)
``sx, sy, sz``            standard deviation of x, y, z                            length
``srx, sry, srz``         standard deviation of the three orientation values (of   deg
                          the Euler angles, or of the rotation about x, y, z)
========================  =======================================================  =========

Each function reads one set and returns what `kinecal.data.Measurements` holds; a set is
all of its columns or none, and every cell is checked (file and row in the message).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import read_column, read_table
from kinecal.io.orientation import rotation_sigma
from kinecal.io.poses import ROTATIONS, PoseFormat, pose_columns, poses_from_table

__all__ = ["POSITION_SIGMA", "QUATERNION", "ROTATION_SIGMA", "STATION_COLUMN", "read_orientation",
           "read_sigma", "read_stations", "station_name"]

Array = NDArray[np.float64]

STATION_COLUMN = "station"
POSITION_SIGMA = ("sx", "sy", "sz")
ROTATION_SIGMA = ("srx", "sry", "srz")
QUATERNION = ("qw", "qx", "qy", "qz")


def station_name(name: object, what: str = "station") -> str:
    """A station name: it goes into parameter names ``base@NAME.x`` and onto the command
    line, so no dots, ``@``, commas, quotes, spaces or control characters."""
    text = str(name)
    if not text or any(c in text for c in ".@,\"' \t") or any(
            ord(c) < 32 or c == "\x7f" for c in text):
        raise InputError(f"{what} {text!r}: expected a name without dots, @, commas, quotes "
                         "or spaces (e.g. A, tracker2)")
    return text


def read_stations(path: Path) -> tuple[NDArray[np.intp] | None, tuple[str, ...]]:
    """The ``station`` column: per-row indices ``(N,)`` into the names, which are in order
    of first appearance; ``(None, ())`` without the column."""
    cells = read_column(path, STATION_COLUMN)
    if cells is None:
        return None, ()
    lookup: dict[str, int] = {}
    idx = np.empty(len(cells), dtype=np.intp)
    for r, cell in enumerate(cells, start=1):
        if cell not in lookup:
            try:
                station_name(cell, "column station:")
            except InputError as exc:
                raise InputError(exc.message, file=path, row=r) from None
            lookup[cell] = len(lookup)
        idx[r - 1] = lookup[cell]
    return idx, tuple(lookup)


def _format_columns(header: list[str], fmt: PoseFormat) -> tuple[str, list[str]] | None:
    """The rotation format and its columns in `header` (None: no orientation)."""
    if fmt.rotation != "auto":
        return fmt.rotation, pose_columns(fmt.rotation)[3:]
    present = [c for c in QUATERNION if c in header]
    if present:
        return "quaternion", list(QUATERNION)
    for name in ("rpy", "euler-zyx", "rotvec"):  # a whole set of another format's columns
        cols = list(ROTATIONS[name])
        if all(c in header for c in cols):
            raise InputError(f"columns {', '.join(cols)}: an orientation? say its format with "
                             f"--orientation-format ({name}[:deg], or an Euler convention "
                             "such as intrinsic-xyz:deg)")
    return None


def read_orientation(path: Path, header: list[str], fmt: PoseFormat | None = None
                     ) -> tuple[Array | None, str, Array | None]:
    """The measured tool orientations ``(N, 3, 3)`` (None without orientation columns),
    the rotation format read and the file's angle values in rad ``(N, 3)`` (Euler and
    roll-pitch-yaw formats; for `read_sigma`).

    Without a format (``auto``): ``qw, qx, qy, qz`` when present; all four are needed and
    each row must be a unit quaternion (to 1e-3).
    """
    fmt = PoseFormat() if fmt is None else fmt
    found = _format_columns(header, fmt)
    if found is None:
        return None, "", None
    rotation, cols = found
    if rotation == "quaternion":
        present = [c for c in cols if c in header]
        if len(present) != 4:
            raise InputError(
                f"orientation columns {', '.join(present) or 'none'} without the others: "
                "expected all of qw, qx, qy, qz (tool orientation as a unit quaternion)",
                file=path)
    missing = [c for c in cols if c not in header]
    if missing:
        raise InputError(f"orientation format {rotation}: missing column(s) "
                         f"{', '.join(missing)} (expected {', '.join(cols)})", file=path)
    table = read_table(path, [*cols, "x", "y", "z"])
    T = poses_from_table(table, rotation, fmt.angle_unit, "", path)
    angles = None
    if rotation not in ("quaternion", "matrix", "rotvec"):
        angles = np.column_stack([table[c] for c in cols])
        angles *= np.pi / 180.0 if fmt.angle_unit == "deg" else 1.0
    return T[:, :3, :3], rotation, angles


def read_sigma(path: Path, header: list[str], rotation: str, angles: Array | None,
               oriented: bool) -> Array | None:
    """Per-row standard deviations ``(N, 3)`` or ``(N, 6)`` (x, y, z in the length unit;
    then the rotation about the measurement frame's x, y, z axes in rad, propagated from
    the file's ``srx, sry, srz`` in degrees by `kinecal.io.orientation.rotation_sigma`);
    None without ``sx, sy, sz``. Every value must be positive."""
    sets = {"position": POSITION_SIGMA, "rotation": ROTATION_SIGMA}
    for what, cols in sets.items():
        present = [c for c in cols if c in header]
        if present and len(present) != 3:
            raise InputError(f"{what} standard deviations {', '.join(present)} without the "
                             f"others: expected all of {', '.join(cols)} or none", file=path)
    has_pos, has_rot = POSITION_SIGMA[0] in header, ROTATION_SIGMA[0] in header
    if has_rot and not oriented:
        raise InputError("columns srx, sry, srz without a measured orientation: they are the "
                         "standard deviations of the orientation columns", file=path)
    if has_rot and not has_pos:
        raise InputError("columns srx, sry, srz without sx, sy, sz: give the position's "
                         "standard deviations too", file=path)
    if not has_pos:
        return None
    cols = list(POSITION_SIGMA) + (list(ROTATION_SIGMA) if has_rot else [])
    table = read_table(path, cols)
    s = np.column_stack([table[c] for c in cols])
    bad = ~(s > 0)
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(f"column {cols[c]}: {s[r, c]:g}, expected a positive standard "
                         "deviation", file=path, row=r + 1)
    if not has_rot:
        if oriented:  # orientations without their deviations: weighted as the positions
            raise InputError("columns sx, sy, sz with a measured orientation but without "
                             "srx, sry, srz: give both or neither", file=path)
        return s
    rot = rotation_sigma(rotation, angles, np.radians(s[:, 3:]))
    return np.column_stack([s[:, :3], rot])
