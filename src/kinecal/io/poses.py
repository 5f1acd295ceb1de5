"""Pose tables as robots and cameras write them: quaternions, 4x4 matrices, rotation
vectors, ZYX Euler angles, roll-pitch-yaw; either direction; degrees or radians.

A pose file holds one rigid transform per row (CSV) or a list of 4x4 matrices (OpenCV
FileStorage YAML, as ``cv::FileStorage`` writes a ``std::vector<cv::Mat>``). Columns,
optionally behind a prefix such as ``flange_`` (header matched case-insensitively):

==============  ====================================  ===================================
rotation        columns                               rotation matrix
==============  ====================================  ===================================
``quaternion``  ``x, y, z, qw, qx, qy, qz``           unit quaternion (w, x, y, z)
``matrix``      ``m00 .. m33`` (row-major), or 16      the upper-left 3x3 (last row must
                numbers per row without a header      be 0 0 0 1)
``rotvec``      ``x, y, z, rx, ry, rz``               rotation vector, axis * angle (UR)
``euler-zyx``   ``x, y, z, a, b, c``                  ``Rz(a) Ry(b) Rx(c)`` (KUKA A, B, C)
``rpy``         ``x, y, z, roll, pitch, yaw``         ``Rz(yaw) Ry(pitch) Rx(roll)`` (ROS)
==============  ====================================  ===================================

A named Euler convention ``intrinsic-SEQ`` or ``extrinsic-SEQ`` (`kinecal.io.orientation`,
e.g. ``intrinsic-xyz`` for ``Rx(a) Ry(b) Rz(c)``) reads the columns ``x, y, z, a, b, c``.

`PoseFormat` says which (``auto`` detects it from the columns; ``rx, ry, rz`` are not
guessed: UR writes a rotation vector there, others fixed-axis angles; a named Euler
convention is never guessed), the unit of the angles and whether the file stores the
inverse transform (a robot recording of ``base2gripper`` instead of ``gripper2base``).

Every pose is rebuilt from its translation and unit quaternion
(``transform_from_pq(pq_from_transform(T))``), whatever format it came in: a recording
stored as quaternions and the same recording stored as 4x4 matrices give bit-identical
inputs, hence bit-identical results, and slightly non-orthonormal matrices become
rotations.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import check_separator, read_table
from kinecal.io.matrices import check_matrices, read_matrix_lists
from kinecal.io.orientation import EULER_COLUMNS, EULER_FORMATS, euler_matrix
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    pq_from_transform,
    transform_from,
    transform_from_pq,
)

__all__ = ["DIRECTED_KEYS", "ROTATIONS", "PoseFormat", "canonical_poses", "check_matrices",
           "finish", "first_csv_row", "keyed_format", "numeric_row", "pose_columns",
           "poses_from_table", "read_csv_poses", "read_poses"]

Array = NDArray[np.float64]

#: rotation formats and their columns after ``x, y, z``
ROTATIONS: dict[str, tuple[str, ...]] = {
    "quaternion": ("qw", "qx", "qy", "qz"),
    "matrix": tuple(f"m{i}{j}" for i in range(4) for j in range(4)),
    "rotvec": ("rx", "ry", "rz"),
    "euler-zyx": ("a", "b", "c"),
    "rpy": ("roll", "pitch", "yaw"),
}
_XYZ = ("x", "y", "z")


@dataclass(frozen=True)
class PoseFormat:
    """How a pose file stores its transforms.

    Attributes
    ----------
    rotation : {"auto", "quaternion", "matrix", "rotvec", "euler-zyx", "rpy"}
        Rotation columns (module docstring); ``auto`` detects them from the header.
    angle_unit : {"rad", "deg"}
        Unit of rotation vectors and Euler / roll-pitch-yaw angles.
    invert : bool
        The file stores the inverse of the wanted transform (``base2gripper`` for
        ``gripper2base``): invert each pose after reading.
    """

    rotation: str = "auto"
    angle_unit: str = "rad"
    invert: bool = False

    def __post_init__(self) -> None:
        if self.rotation != "auto" and self.rotation not in ROTATIONS and \
                self.rotation not in EULER_FORMATS:
            raise InputError(f"rotation format {self.rotation!r}: expected auto, "
                             f"{', '.join(ROTATIONS)} or a named Euler convention "
                             "intrinsic-SEQ / extrinsic-SEQ (e.g. intrinsic-xyz)")
        if self.angle_unit not in ("rad", "deg"):
            raise InputError(f"angle unit {self.angle_unit!r}: expected rad or deg")

    @classmethod
    def parse(cls, spec: str, invert: bool = False, option: str | None = None) -> PoseFormat:
        """From ``FORMAT[:deg|rad]`` (e.g. ``euler-zyx:deg``, ``rotvec``, ``auto``)."""
        rotation, _, unit = spec.strip().lower().partition(":")
        try:
            return cls(rotation or "auto", unit or "rad", invert)
        except InputError as exc:
            raise InputError(f"{exc.message} (FORMAT[:deg|rad], e.g. euler-zyx:deg)",
                             option=option) from None


def pose_columns(rotation: str, prefix: str = "") -> list[str]:
    """Columns of a pose in `rotation` format: ``prefix + x, y, z, ...`` (matrix: only
    the 16 ``m`` entries)."""
    rot = EULER_COLUMNS if rotation in EULER_FORMATS else ROTATIONS[rotation]
    cols = rot if rotation == "matrix" else _XYZ + rot
    return [prefix + c for c in cols]


def canonical_poses(T: Array) -> Array:
    """Transforms ``(n, 4, 4)`` rebuilt from translation and unit quaternion (``w >= 0``)."""
    return transform_from_pq(pq_from_transform(T))


def _detect(header: list[str], prefix: str, path: Path, option: str | None) -> str:
    have = set(header)
    found = [r for r, cols in ROTATIONS.items() if prefix + cols[0] in have]
    if prefix + "rx" in have and "rotvec" in found:
        raise InputError(
            f"columns {prefix}rx, {prefix}ry, {prefix}rz: a rotation vector (UR) or "
            "fixed-axis angles? say which: rotvec, or rename them roll, pitch, yaw",
            file=path, option=option)
    if len(found) > 1:
        raise InputError(f"columns for several rotation formats ({', '.join(found)}): say "
                         "which", file=path, option=option)
    return found[0] if found else "quaternion"


def poses_from_table(cols: dict[str, Array], rotation: str, angle_unit: str, prefix: str,
                     path: Path) -> Array:
    """Transforms ``(n, 4, 4)`` from the named columns of a table (not yet inverted or
    canonicalised); quaternions must have unit norm, matrices be rigid (row in errors)."""
    if rotation == "matrix":
        M = np.stack([cols[c] for c in pose_columns("matrix", prefix)], axis=1).reshape(-1, 4, 4)
        check_matrices(M, f"{prefix}m00..m33".lstrip("_"), path)
        return M
    t = np.column_stack([cols[prefix + c] for c in _XYZ])
    r = np.column_stack([cols[c] for c in pose_columns(rotation, prefix)[3:]])
    if rotation == "quaternion":
        norm = np.linalg.norm(r, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
        if bad.size:
            k = int(bad[0])
            raise InputError(f"{prefix.rstrip('_') or 'pose'} quaternion has norm "
                             f"{norm[k]:.6f}, expected a unit quaternion (qw, qx, qy, qz)",
                             file=path, row=k + 1)
        return transform_from_pq(np.column_stack([t, r]))
    _check_angle_unit(r, rotation, angle_unit, prefix, path)
    r = r * (np.pi / 180.0 if angle_unit == "deg" else 1.0)
    if rotation in EULER_FORMATS:
        R = euler_matrix(r, *EULER_FORMATS[rotation])
    elif rotation == "rotvec":
        R = matrix_from_axis_angle(r)
    elif rotation == "euler-zyx":  # Rz(a) Ry(b) Rx(c)
        R = matrix_from_rpy(r[:, ::-1])
    else:  # roll, pitch, yaw
        R = matrix_from_rpy(r)
    return transform_from(R, t)


def _check_angle_unit(r: Array, rotation: str, angle_unit: str, prefix: str,
                      path: Path) -> None:
    """Angles in the other unit than the format says: radians beyond 2 pi (an Euler angle
    or a rotation vector never needs more) are degrees, an error naming ``:deg``; degrees
    that all stay within 2 pi (no station turned by more than 6 deg: no hand-eye motion)
    look like radians, a warning (``angle-units``)."""
    from kinecal.diagnostics import warn

    cols = ", ".join(pose_columns(rotation, prefix)[3:])
    size = np.linalg.norm(r, axis=1) if rotation == "rotvec" else np.max(np.abs(r), axis=1)
    limit = 2.0 * np.pi * (1.0 + 1e-6)
    if angle_unit == "rad":
        bad = np.flatnonzero(size > limit)
        if bad.size:
            k = int(bad[0])
            what = "rotation angle" if rotation == "rotvec" else "angle"
            raise InputError(f"columns {cols}: {what} {size[k]:.6g} is beyond 2 pi for "
                             f"radians; degrees? give the format as {rotation}:deg",
                             file=path, row=k + 1)
    elif len(r) > 1 and 0.0 < float(size.max()) <= limit:
        warn("angle-units",
             f"{path.name}: columns {cols} read in degrees stay within "
             f"{float(size.max()):.3g} deg of zero in every row, too little turning for any "
             f"calibration: they look like radians; give the format as {rotation} (radians) "
             "if so")


def numeric_row(row: list[str]) -> bool:
    """True when `row` is not empty and every cell reads as a number: the first row of a
    CSV without a header (non-finite values are then refused with their row)."""
    try:
        [float(c) for c in row]
    except ValueError:
        return False
    return bool(row)


def first_csv_row(path: Path) -> list[str]:
    """The first row of a CSV file, cells stripped (``[]`` for an empty file)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            first = next(csv.reader(fh), [])
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    check_separator(first, path)
    return [c.strip() for c in first]


def read_csv_poses(path: Path, formats: dict[str, PoseFormat],
                   option: str | None = None) -> list[Array]:
    """One pose stack ``(n, 4, 4)`` per prefix (`formats`: prefix -> format) from a CSV,
    inverted as each format says and canonicalised (`finish`). A CSV without a header
    holds 16 numbers per pose and row."""
    prefixes = tuple(formats)
    first = first_csv_row(path)
    if numeric_row(first):  # rows of 16 numbers per pose, row-major
        bad = [f.rotation for f in formats.values() if f.rotation not in ("auto", "matrix")]
        if bad:
            raise InputError(f"no header: expected 4x4 matrices (16 numbers per pose), not "
                             f"{bad[0]}", file=path, option=option)
        if len(first) != 16 * len(prefixes):
            raise InputError(f"{len(first)} numbers per row without a header: expected "
                             f"{16 * len(prefixes)} (a row-major 4x4 matrix per pose)",
                             file=path)
        data = _headerless(path, first)
        out = []
        for k, fmt in enumerate(formats.values()):
            M = data[:, 16 * k:16 * (k + 1)].reshape(-1, 4, 4)
            check_matrices(M, "4x4 matrix", path)
            out.append(finish(M, fmt))
        return out
    lower = [h.lower() for h in first]
    actual = dict(zip(lower, first, strict=True))
    out = []
    for prefix, fmt in formats.items():
        rotation = (_detect(lower, prefix, path, option) if fmt.rotation == "auto"
                    else fmt.rotation)
        wanted = pose_columns(rotation, prefix)
        cols = read_table(path, [actual.get(c, c) for c in wanted], min_rows=1)
        cols = {c: cols[actual.get(c, c)] for c in wanted}
        T = poses_from_table(cols, rotation, fmt.angle_unit, prefix, path)
        out.append(finish(T, fmt, quaternion=rotation == "quaternion"))
    return out


def _headerless(path: Path, first: list[str]) -> Array:
    """All rows of a CSV of numbers without a header (finite, equal length; row in errors)."""
    rows = []
    with open(path, newline="", encoding="utf-8-sig") as fh:
        for r, row in enumerate(csv.reader(fh), start=1):
            if not row or not any(c.strip() for c in row):
                continue
            if len(row) != len(first):
                raise InputError(f"{len(row)} numbers, expected {len(first)} as in row 1",
                                 file=path, row=r)
            try:
                values = [float(c) for c in row]
            except ValueError:
                raise InputError("expected numbers only", file=path, row=r) from None
            if not np.isfinite(values).all():
                raise InputError("expected finite numbers", file=path, row=r)
            rows.append(values)
    return np.asarray(rows, dtype=float)


def finish(T: Array, fmt: PoseFormat, quaternion: bool = False) -> Array:
    """Invert (if the format says so) and canonicalise a pose stack as read.

    `quaternion`: `T` was built from stored quaternions, so it is canonical already (the
    same bits as `canonical_poses` of any matrix with that quaternion) unless inverted.
    """
    if fmt.invert:
        return canonical_poses(invert_transform(T))
    return T if quaternion else canonical_poses(T)


def read_poses(path: str | Path, fmt: PoseFormat = PoseFormat(), *,
               option: str | None = None) -> Array:
    """One pose per row of a CSV, or the list of 4x4 matrices of an OpenCV FileStorage
    YAML (`kinecal.io.matrices.read_matrix_lists`), as canonical transforms ``(n, 4, 4)``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return read_csv_poses(path, {"": fmt}, option=option)[0]
    if suffix in (".yml", ".yaml"):
        lists = read_matrix_lists(path)
        if len(lists) != 1:
            raise InputError(f"{len(lists)} lists of 4x4 matrices ({', '.join(lists) or 'none'})"
                             ": expected one", file=path)
        (key, M), = lists.items()
        return finish(M, keyed_format(fmt, key, path, option))
    raise InputError(f"unknown file type {suffix or '(none)'!r}; expected .csv, .yml or .yaml",
                     file=path)


#: FileStorage list names that say their direction: True when they store the inverse of
#: the transform kinecal wants (flange2base for the robot, target2cam for the camera)
DIRECTED_KEYS = {"flange2base": False, "gripper2base": False, "base2flange": True,
                 "base2gripper": True, "target2cam": False, "cam2target": True}


def keyed_format(fmt: PoseFormat, key: str, path: Path, option: str | None) -> PoseFormat:
    """`fmt` with the inversion a direction-naming key asks for."""
    inverse = DIRECTED_KEYS.get(key.lower())
    if inverse is None:
        return fmt
    if fmt.invert:
        raise InputError(f"list {key} already names its direction: drop the inversion option",
                         file=path, option=option)
    return PoseFormat(fmt.rotation, fmt.angle_unit, inverse)
