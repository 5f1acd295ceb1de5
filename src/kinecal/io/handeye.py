"""Hand-eye pose pairs: CSV and OpenCV FileStorage YAML readers and writers.

CSV (DESIGN sec. 4): one row per station, columns ``flange_x, flange_y, flange_z,
flange_qw, flange_qx, flange_qy, flange_qz`` (``flange2base``) and the same seven with
prefix ``target_`` (``target2cam``); quaternions (w, x, y, z), lengths in one unit. The
rotation columns may instead be any format of `kinecal.io.poses` (4x4 matrices, rotation
vectors, ZYX Euler A, B, C, roll-pitch-yaw; degrees or radians), and a CSV without a header
holds two row-major 4x4 matrices (32 numbers) per row.

YAML: OpenCV FileStorage as written by ``cv::FileStorage`` (``%YAML:1.0``, matrices as
``!!opencv-matrix`` with ``rows, cols, dt, data``) holding ``frameCount`` and 4x4
matrices ``T1_i`` (``flange2base``) and ``T2_i`` (``target2cam``), i = 0 .. frameCount-1,
the layout of the handeye_calib_camodocal recordings (see docs/handeye.md for how the
frame conventions of that recording were established); or two lists of 4x4 matrices named
by their direction (``base2gripper`` is inverted to ``gripper2base``, see
`read_handeye_pairs`). Robot and target poses may also come in two files
(`read_handeye_files`), and either may be stored inverted (`PoseFormat.invert`).

Every pose read is rebuilt from its translation and unit quaternion, so the same
recording in any of these formats gives bit-identical results. Every write is atomic; every
bad input raises `InputError` naming the file and the row (CSV: 1-based data row; YAML: the
key of the matrix, ``T1_i`` or ``base2gripper[i]``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import write_text_atomic
from kinecal.errors import InputError
from kinecal.io.csvtable import check_separator, write_table
from kinecal.io.matrices import (
    load_filestorage,
    matrix_entry,
    matrix_yaml,
    read_matrix_lists,
)
from kinecal.io.poses import (
    PoseFormat,
    finish,
    first_csv_row,
    keyed_format,
    numeric_row,
    read_csv_poses,
    read_poses,
)
from kinecal.spatial import pq_from_transform

Array = NDArray[np.float64]

__all__ = [
    "FLANGE_COLUMNS",
    "IMAGE_COLUMN",
    "TARGET_COLUMNS",
    "check_image_name",
    "pose_columns",
    "read_handeye_csv",
    "read_handeye_files",
    "read_handeye_pairs",
    "read_handeye_yaml",
    "read_matrix_lists",
    "read_robot_poses",
    "write_handeye_csv",
    "write_handeye_yaml",
]

_PQ = ("x", "y", "z", "qw", "qx", "qy", "qz")


def check_image_name(name: str, seen: dict[str, int], path: Path, row: int) -> None:
    """Refuse an empty image name or one listed before (`seen`: name -> its row, updated)."""
    if not name:
        raise InputError("empty image name", file=path, row=row)
    if name in seen:
        raise InputError(f"image {name!r} listed twice (also row {seen[name]})", file=path,
                         row=row)
    seen[name] = row

def pose_columns(prefix: str) -> list[str]:
    """Column names ``prefix_x .. prefix_qz`` of a pose (x, y, z, qw, qx, qy, qz)."""
    return [f"{prefix}_{c}" for c in _PQ]


FLANGE_COLUMNS = pose_columns("flange")
TARGET_COLUMNS = pose_columns("target")


def read_handeye_pairs(path: str | Path, robot: PoseFormat = PoseFormat(),
                       target: PoseFormat = PoseFormat()) -> tuple[Array, Array]:
    """Read pose pairs from ``.csv`` or ``.yml``/``.yaml`` (OpenCV FileStorage).

    Parameters
    ----------
    path : str or Path
        CSV with ``flange_*`` and ``target_*`` pose columns in any format of
        `kinecal.io.poses` (or 32 numbers per row without a header: two row-major 4x4
        matrices), or FileStorage YAML with ``T1_i``/``T2_i`` matrices or two lists of 4x4
        matrices (``flange2base``/``gripper2base``/``base2flange``/``base2gripper`` and
        ``target2cam``/``cam2target``; ``base2*`` and ``cam2target`` are inverted).
    robot, target : PoseFormat
        Rotation format, angle unit and direction of the robot and target poses.

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
        Rebuilt from translation and unit quaternion (`kinecal.io.poses`).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return read_handeye_csv(path, robot, target)
    if suffix in (".yml", ".yaml"):
        return read_handeye_yaml(path, robot, target)
    raise InputError(f"unknown file type {suffix or '(none)'!r}; expected .csv, .yml or .yaml",
                     file=path)


def read_handeye_files(robot_path: str | Path, target_path: str | Path,
                       robot: PoseFormat = PoseFormat(), target: PoseFormat = PoseFormat()
                       ) -> tuple[Array, Array]:
    """Pose pairs from two files, robot poses and target poses, one pose per row or
    matrix (`kinecal.io.poses.read_poses`); both must hold the same number of stations.

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
    """
    F = read_poses(robot_path, robot, option="--robot-format")
    C = read_poses(target_path, target, option="--target-format")
    if len(F) != len(C):
        raise InputError(f"{len(F)} robot poses ({Path(robot_path).name}) but {len(C)} target "
                         f"poses ({Path(target_path).name}): expected one of each per station")
    _enough(len(F), Path(robot_path))
    return F, C


def _enough(n: int, path: Path) -> None:
    if n < 3:
        raise InputError(f"{n} stations, expected at least 3", file=path)


def read_handeye_csv(path: str | Path, robot: PoseFormat = PoseFormat(),
                     target: PoseFormat = PoseFormat()) -> tuple[Array, Array]:
    """Read the hand-eye CSV (``flange_*`` and ``target_*`` pose columns, e.g.
    `FLANGE_COLUMNS` and `TARGET_COLUMNS`; or 32 numbers per row without a header).

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
        Lengths in the file's unit.
    """
    path = Path(path)
    if numeric_row(first_csv_row(path)):
        F, C = read_csv_poses(path, {"flange_": robot, "target_": target})
    else:
        F = read_csv_poses(path, {"flange_": robot}, option="--robot-format")[0]
        C = read_csv_poses(path, {"target_": target}, option="--target-format")[0]
    _enough(len(F), path)
    return F, C


def write_handeye_csv(path: str | Path, flange2base: Array, target2cam: Array) -> None:
    """Write pose pairs ``(n, 4, 4)`` as the hand-eye CSV (atomic)."""
    cols = {}
    for prefix, T in (("flange", flange2base), ("target", target2cam)):
        pq = pq_from_transform(np.asarray(T, dtype=float))
        cols.update({name: pq[:, k] for k, name in enumerate(pose_columns(prefix))})
    write_table(path, cols)


_ROBOT_LISTS = ("flange2base", "gripper2base", "base2flange", "base2gripper")
_TARGET_LISTS = ("target2cam", "cam2target")


def read_handeye_yaml(path: str | Path, robot: PoseFormat = PoseFormat(),
                      target: PoseFormat = PoseFormat()) -> tuple[Array, Array]:
    """Read an OpenCV FileStorage YAML: ``frameCount``, ``T1_i`` and ``T2_i``, or two lists
    of 4x4 matrices (see `read_handeye_pairs`).

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
        Rebuilt from translation and unit quaternion (lengths in the file's unit).
    """
    path = Path(path)
    doc = load_filestorage(path)
    if "frameCount" in doc or "T1_0" in doc:
        try:
            n = int(doc["frameCount"])
        except (KeyError, TypeError, ValueError):
            n = sum(1 for k in doc if str(k).startswith("T1_"))
        _enough(n, path)
        F = np.stack([matrix_entry(doc, f"T1_{i}", path) for i in range(n)])
        C = np.stack([matrix_entry(doc, f"T2_{i}", path) for i in range(n)])
        return finish(F, robot), finish(C, target)
    lists = read_matrix_lists(path)
    found = {k.lower(): k for k in lists}
    keys = [[found[k] for k in names if k in found] for names in (_ROBOT_LISTS, _TARGET_LISTS)]
    if any(len(k) != 1 for k in keys):
        raise InputError(
            f"lists {', '.join(lists) or 'none'}: expected T1_i/T2_i matrices, or one robot "
            f"list ({', '.join(_ROBOT_LISTS)}) and one target list ({', '.join(_TARGET_LISTS)})",
            file=path)
    F, C = lists[keys[0][0]], lists[keys[1][0]]
    if len(F) != len(C):
        raise InputError(f"{len(F)} robot poses but {len(C)} target poses: expected one of "
                         "each per station", file=path)
    _enough(len(F), path)
    robot = keyed_format(robot, keys[0][0], path, "--invert-robot")
    target = keyed_format(target, keys[1][0], path, "--invert-target")
    return finish(F, robot), finish(C, target)


def write_handeye_yaml(path: str | Path, flange2base: Array, target2cam: Array) -> None:
    """Write pose pairs ``(n, 4, 4)`` as OpenCV FileStorage YAML (``T1_i``, ``T2_i``), atomic."""
    F = np.asarray(flange2base, dtype=float)
    C = np.asarray(target2cam, dtype=float)
    parts = ["%YAML:1.0\n", f"frameCount: {len(F)}\n"]
    for i in range(len(F)):
        parts.append(matrix_yaml(f"T1_{i}", F[i]))
        parts.append(matrix_yaml(f"T2_{i}", C[i]))
    write_text_atomic(path, "".join(parts))


#: the image-name column of the robot-pose CSV of ``kinecal handeye-images``
IMAGE_COLUMN = "image"


def read_robot_poses(path: str | Path,
                     robot: PoseFormat = PoseFormat()) -> tuple[list[str], Array]:
    """Read the robot-pose CSV of ``kinecal handeye-images``.

    Columns ``image`` (file name inside the image folder) and the flange pose
    (``flange2base``, lengths in the board's unit): `FLANGE_COLUMNS` (``flange_x ..
    flange_qz``, unit quaternion w, x, y, z) or any other rotation format of
    `kinecal.io.poses` behind the ``flange_`` prefix, one row per image; other columns are
    ignored.

    Returns
    -------
    names : list of str
        Image file names, in row order.
    flange2base : ndarray, shape (n, 4, 4)

    Raises
    ------
    InputError
        Missing columns, an empty image name, a repeated image, a non-numeric or
        non-finite cell, a non-unit quaternion (file and 1-based data row named).
    """
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    wanted = [IMAGE_COLUMN, *FLANGE_COLUMNS]
    if not rows:
        raise InputError(f"empty file; expected a header with {', '.join(wanted)}", file=path)
    check_separator(rows[0], path)
    header = [h.strip().lower() for h in rows[0]]
    if IMAGE_COLUMN not in header:
        raise InputError(f"missing column {IMAGE_COLUMN} (the image file name of each row); "
                         f"expected {', '.join(wanted)} (found {', '.join(header) or 'nothing'})",
                         file=path)
    col = header.index(IMAGE_COLUMN)
    names: list[str] = []
    seen: dict[str, int] = {}
    for r, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields, expected {len(header)} as in the header",
                             file=path, row=r)
        name = row[col].strip()
        check_image_name(name, seen, path, r)
        names.append(name)
    if not names:
        raise InputError("no data rows", file=path)
    if not any(h.startswith("flange_") for h in header):
        raise InputError(f"missing columns {', '.join(FLANGE_COLUMNS)} (the flange2base pose "
                         f"of each image; found {', '.join(header)})", file=path)
    F = read_csv_poses(path, {"flange_": robot})[0]
    return names, F
