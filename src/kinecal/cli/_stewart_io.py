"""The column names of the Stewart commands' CSV files and their readers, free of typer
(`kinecal.cli._stewart_common` re-exports them beside the command group; ``stewart fk``
runs without typer: `kinecal.cli._direct`)."""

from __future__ import annotations

import numpy as np

from kinecal.cli._common import resolve_data_path

__all__ = ["LEG_COLUMNS", "POSE_COLUMNS", "load_geometry_arg", "poses_rad", "read_columns"]

POSE_COLUMNS = ("x", "y", "z", "alpha", "beta", "gamma")
LEG_COLUMNS = tuple(f"l{i}" for i in range(1, 7))


def load_geometry_arg(spec: str):
    """The geometry of a GEOMETRY argument (bundled name or YAML path)."""
    from kinecal.io.geometry import load_geometry

    return load_geometry(spec)


def read_columns(path: str, columns: tuple[str, ...], option: str) -> np.ndarray:
    """The `columns` of a CSV argument as an array ``(N, len(columns))``."""
    from kinecal.io.csvtable import read_table

    p = resolve_data_path(path, option)
    table = read_table(p, columns)
    return np.column_stack([table[c] for c in columns])


def poses_rad(deg: np.ndarray) -> np.ndarray:
    """Poses ``(N, 6)`` with the angles of a poses CSV (degrees) in radians."""
    from kinecal.kinematics.stewart.platform import degrees_to_radians

    return degrees_to_radians(deg)
