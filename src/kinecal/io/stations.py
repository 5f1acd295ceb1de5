"""STATIONS.csv of ``kinecal calibrate MODEL STATIONS.csv --images DIR``: one row per image,
``image,q1..qn`` (the image's file name inside DIR and the joint readings when it was taken,
in the model's units: revolute joints in its angle unit, prismatic in its length unit); the
joint columns may carry the model's joint names instead (a URDF's, as a ROS
``joint_states`` export has them; `kinecal.io.measurements.joint_columns`). Other columns
are ignored.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import read_column, read_table
from kinecal.io.handeye import IMAGE_COLUMN, check_image_name
from kinecal.io.measurements import csv_header, joint_columns, joint_names
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["IMAGE_COLUMN", "read_stations"]


def read_stations(path: str | Path, model: SerialModel, *, angle_unit: str | None = None
                  ) -> tuple[list[str], NDArray[np.float64]]:
    """Image names and joint readings of a STATIONS.csv.

    Returns
    -------
    names : list of str
        Image file names, in row order.
    q : ndarray, shape (n, n_joints)
        Joint readings (rad; prismatic: length unit).

    Raises
    ------
    InputError
        No ``image`` column, an empty or repeated image name, joint columns beyond the
        model's joints (its chain ends before the camera or board?), missing joint
        columns, a non-numeric cell (file and 1-based data row named).
    """
    path = Path(path)
    header = csv_header(path)
    if IMAGE_COLUMN not in header:
        raise InputError(f"missing column {IMAGE_COLUMN} (the image file of each row); "
                         f"expected image,q1..q{model.n_joints} (found "
                         f"{', '.join(header) or 'nothing'})", file=path)
    n = model.n_joints
    extra = [c for c in header if c.startswith("q") and c[1:].isdigit() and int(c[1:]) > n]
    if extra:
        names = joint_names(model)
        raise InputError(f"joint column(s) {', '.join(extra)} beyond model {model.name!r}'s "
                         f"{n} joints: the model's chain ends before the joints that move "
                         "the camera or board (a URDF read to another --tip-link?); expected "
                         f"q1..q{n}" + (f" or {', '.join(names)}" if names else ""), file=path)
    joints = joint_columns(header, model, path)
    cells = read_column(path, IMAGE_COLUMN) or []
    seen: dict[str, int] = {}
    for r, name in enumerate(cells, start=1):
        check_image_name(name, seen, path, r)
    cols = read_table(path, joints)
    q = np.column_stack([cols[c] for c in joints]) * model.joint_scale(angle_unit)
    if len(q) != len(cells):  # pragma: no cover - both readers count the same rows
        raise InputError(f"{len(cells)} image names but {len(q)} joint rows", file=path)
    return list(cells), q
