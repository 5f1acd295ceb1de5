"""STATIONS.csv of a camera rig: ``image,camera[,board],<joints>``, one row per image.

- ``image``: the file name inside the image folder;
- ``camera``: the name of the ``--camera`` that took it (the column may be left out when
  the rig has one camera);
- ``board``: the ``--board`` the image shows (optional; left out, or a blank cell, the
  image is searched for every board: ChArUco boards of disjoint marker ids are told apart
  in one image);
- the joint readings when it was taken: ``q1..qn`` or the model's joint names (a system's
  joint names; a system's cells of joints that move neither the image's camera nor its
  boards may be blank), in the model's units (revolute joints in its angle unit,
  prismatic in its length unit).

Other columns are ignored.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, read_columns, read_table
from kinecal.io.handeye import IMAGE_COLUMN, check_image_name
from kinecal.io.measurements import csv_header, joint_columns
from kinecal.kinematics.tree.system import is_system

__all__ = ["RigStations", "read_rig_stations", "write_rig_stations"]

Array = NDArray[np.float64]


@dataclass
class RigStations:
    """The rows of a rig's STATIONS.csv.

    Attributes
    ----------
    names : list of str
        Image file names.
    camera : ndarray of int, shape (n,)
        Camera of each image (index into the camera names given to the reader).
    board : list of str or None
        The board each image shows (None: every board).
    q : ndarray, shape (n, n_joints)
        Joint readings (rad; prismatic: length unit); NaN for a system's blank cells.
    """

    names: list[str]
    camera: NDArray[np.intp]
    board: list[str | None]
    q: Array


def _lookup(path: Path, cells: list[str], names: Sequence[str], column: str, option: str,
            blank_ok: bool) -> list[int | None]:
    out: list[int | None] = []
    for r, cell in enumerate(cells, start=1):
        if not cell and blank_ok:
            out.append(None)
            continue
        if cell not in names:
            raise InputError(f"column {column}: {cell!r}, expected one of the {option} names "
                             f"{', '.join(names)}", file=path, row=r)
        out.append(list(names).index(cell))
    return out


def _system_joints(path: Path, header: list[str], model, n: int, angle_unit) -> Array:
    joints = list(model.joint_names)
    missing = [j for j in joints if j not in header]
    if missing:
        raise InputError(f"joint column(s) {', '.join(missing)} missing: a system's stations "
                         f"name every joint ({', '.join(joints)}; blank cells for the joints "
                         "an image does not need)", file=path)
    cells = read_columns(path, joints)
    q = np.full((n, len(joints)), np.nan)
    for j, name in enumerate(joints):
        for r, cell in enumerate(cells[name], start=1):
            if not cell:
                continue
            try:
                v = float(cell)
            except ValueError:
                v = np.nan
            if not (np.isfinite(v) and abs(v) <= MAX_CELL):
                raise InputError(f"column {name}: {cell!r}, expected a finite number or a "
                                 "blank cell", file=path, row=r)
            q[r - 1, j] = v
    return q * model.joint_scale(angle_unit)


def read_rig_stations(path: str | Path, model, cameras: Sequence[str],
                      boards: Sequence[str], *, angle_unit: str | None = None) -> RigStations:
    """Read a rig's STATIONS.csv (module docstring).

    Raises
    ------
    InputError
        No ``image`` column; no ``camera`` column with several cameras; unknown camera or
        board names; empty or repeated image names; missing or bad joint cells (file and
        1-based data row named).
    """
    path = Path(path)
    header = csv_header(path)
    if IMAGE_COLUMN not in header:
        raise InputError(f"missing column {IMAGE_COLUMN} (the image file of each row); "
                         "expected image,camera[,board],<joints> (found "
                         f"{', '.join(header) or 'nothing'})", file=path)
    text = read_columns(path, [IMAGE_COLUMN, "camera", "board"])
    names = text[IMAGE_COLUMN]
    seen: dict[str, int] = {}
    for r, name in enumerate(names, start=1):
        check_image_name(name, seen, path, r)
    n = len(names)
    if "camera" in text:
        cam = _lookup(path, text["camera"], cameras, "camera", "--camera", False)
    elif len(cameras) == 1:
        cam = [0] * n
    else:
        raise InputError(f"no camera column: with {len(cameras)} cameras each row names the "
                         f"camera of its image ({', '.join(cameras)})", file=path)
    board: list[str | None] = [None] * n
    if "board" in text:
        idx = _lookup(path, text["board"], boards, "board", "--board", True)
        board = [None if i is None else boards[i] for i in idx]
    if is_system(model):
        q = _system_joints(path, header, model, n, angle_unit)
    else:
        cols = joint_columns(header, model, path)
        table = read_table(path, cols)
        q = np.column_stack([table[c] for c in cols]) * model.joint_scale(angle_unit)
    if len(q) != n:  # pragma: no cover - both readers count the same rows
        raise InputError(f"{n} image names but {len(q)} joint rows", file=path)
    return RigStations(list(names), np.asarray(cam, dtype=np.intp), board, q)


def write_rig_stations(path: str | Path, model, names: Sequence[str], cameras: Sequence[str],
                       q: Array, boards: Sequence[str | None] | None = None) -> None:
    """Write a rig's STATIONS.csv: ``image,camera[,board],<joints>`` (the joints in the
    model's units: ``q1..qn`` for an arm, the joint names for a system); the board column
    only when `boards` is given (None cells blank)."""
    from kinecal._files import write_text_atomic

    cols = list(model.joint_names) if is_system(model) else \
        [f"q{i + 1}" for i in range(model.n_joints)]
    head = ["image", "camera"] + (["board"] if boards is not None else []) + cols
    values = np.asarray(q, float) / model.joint_scale()
    lines = [",".join(head)]
    for i, (name, cam) in enumerate(zip(names, cameras, strict=True)):
        cells = [name, cam] + ([boards[i] or ""] if boards is not None else [])
        lines.append(",".join(cells + [repr(float(v)) for v in values[i]]))
    write_text_atomic(path, "\n".join(lines) + "\n")
