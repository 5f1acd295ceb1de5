"""Serial-arm measurement files: joint readings and measured tool-point positions.

kinecal's format (``docs/file-formats.md``): header ``q1..qn,x,y,z``, optional
``qw,qx,qy,qz`` (measured tool orientation, a unit quaternion, for 6-DoF instruments) and an
optional ``weight`` column; joint values in the model's angle unit, positions in its length unit.
The laser-tracker export of the bundled UR5 dataset (``joint_1..joint_n, x_t, y_t, z_t,
x_dif, y_dif, z_dif``; degrees, mm) is read as well: measured = target + dif.

Optional ``temperature`` (deg C) and ``time`` (seconds or ISO 8601) columns are carried
into the report (`kinecal.io.conditions`).

An optional ``marker`` column says which marker (tool point) each row measured: a name of
the model's ``markers`` or its number 1..M in the model's order. A model without markers
takes the names the file uses (`kinecal.kinematics.serial.markers.model_for_markers` then gives
it one tool point per name).

The joint columns may instead carry the model's joint names (a URDF model's joint names,
as a ROS ``joint_states`` export has them), in the same units as ``q1..qn``: either
``q1..qn`` or every joint name, never a mix (`joint_columns`). Every reader takes an
``angle_unit`` (``deg`` or ``rad``) for joint columns written in another unit than the
model's (``--angle-unit``).

Wide marker tables (``x1,y1,z1,x2,...``: markers 1..k of one pose in one row, the layout of
motion-capture exports such as FIGAROH's) are read into the long form (`kinecal.io.wide`).

Optional column sets of tracker rows (`kinecal.io.tracker_columns`): ``station`` (which
tracker set-up measured the row), the orientation in another format than quaternions
(``--orientation-format``), and per-axis standard deviations ``sx, sy, sz`` and
``srx, sry, srz`` that weight each row.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.io.conditions import read_conditions
from kinecal.io.csvtable import check_separator, read_column, read_table, write_table
from kinecal.io.poses import PoseFormat
from kinecal.io.tracker_columns import QUATERNION, read_orientation, read_sigma, read_stations
from kinecal.io.wide import is_wide, read_wide
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_quaternion, quaternion_from_matrix

# Measurements (kinecal.data) is re-exported here
__all__ = ["Measurements", "csv_header", "joint_columns", "joint_names", "measured_poses",
           "orientation_columns", "read_joints", "read_markers", "read_measurements",
           "resolve_csv", "write_measurements"]

#: columns with a meaning of their own in measurement and program files: a joint of that
#: name can only be given as q1..qn
_RESERVED = frozenset(("x", "y", "z", "qw", "qx", "qy", "qz", "weight", "marker", "pose",
                       "pivot", "pair", "point", "plane", "distance", "sigma",
                       "px", "py", "pz", "nx", "ny", "nz", "station", "sx", "sy", "sz",
                       "srx", "sry", "srz", "temperature", "time"))


def _q_column(name: str) -> bool:
    return name.startswith("q") and name[1:].isdigit()


def joint_names(model: SerialModel) -> tuple[str, ...]:
    """The names of `model`'s moving joints, base to flange, usable as CSV columns.

    A URDF model's joints carry the URDF's names (other models' joints may carry a
    ``name`` too). Empty when a moving joint has no name, names repeat, or a name is
    already a column of its own (``x``, ``weight``, ``q2`` ...): such a model's joints are
    read from ``q1..qn`` only.
    """
    names = tuple(str(e.get("name") or "") for e in model.joints if "frame" not in e)
    if names == tuple(f"q{i}" for i in range(1, model.n_joints + 1)):
        return names
    if (len(names) != model.n_joints or not all(names) or len(set(names)) != len(names)
            or any(n in _RESERVED or _q_column(n) for n in names)):
        return ()
    return names


def joint_columns(header: list[str], model: SerialModel, path: Path | None = None,
                  required: bool = True) -> list[str]:
    """The joint columns of a CSV `header` for `model`, in joint order.

    ``q1..qn``, or the model's joint names (`joint_names`) when the header uses them. A
    header with neither gives ``q1..qn`` when the joints are optional (Cartesian targets
    without seed joints) or the model has no joint names (the table reader then names the
    missing columns); else it is an error naming both choices.

    Raises
    ------
    InputError
        A mix of ``q`` columns and joint names, only some of the joint names, or no joint
        column at all where `required`.
    """
    n = model.n_joints
    qs = [f"q{i}" for i in range(1, n + 1)]
    names = joint_names(model)
    qcols = [c for c in header if _q_column(c)]
    named = [c for c in header if c in names and c not in qs]
    if named and qcols:
        raise InputError(
            f"joint columns {', '.join(qcols + named)} mix q1..q{n} and the model's joint "
            f"names: expected either q1..q{n} or {', '.join(names)}", file=path)
    if named:
        missing = [c for c in names if c not in header]
        if missing:
            raise InputError(
                f"joint column(s) {', '.join(missing)} missing: the file names its joint "
                f"columns by model {model.name!r}'s joint names, expected all of "
                f"{', '.join(names)}", file=path)
        return list(names)
    if required and not qcols and names:
        raise InputError(f"no joint columns: expected q1..q{n} or model {model.name!r}'s "
                         f"joint names {', '.join(names)} (found {', '.join(header)})",
                         file=path)
    return qs


def csv_header(path: Path) -> list[str]:
    """The header cells of a CSV file (InputError naming the file when unreadable)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            header = next(csv.reader(fh), [])
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    check_separator(header, path)
    return [h.strip() for h in header]


def _as_model(model: SerialModel | str | Path) -> SerialModel:
    """`model`, or the model a bundled name or a model file path names."""
    if isinstance(model, SerialModel):
        return model
    if isinstance(model, str | Path):
        from kinecal.io.models import load_model

        return load_model(model)
    raise TypeError(f"model: expected a SerialModel, a bundled model name or a model file "
                    f"path, got {type(model).__name__}")


def resolve_csv(path: str | Path) -> Path:
    """A file path, or the file of a bundled ``NAME:PART``."""
    spec = str(path)
    path = Path(path)
    if not path.exists() and ":" in spec and not path.suffix:
        from kinecal.datasets import bundled_csv

        path = bundled_csv(spec)
    return path


def read_markers(path: str | Path, model: SerialModel
                 ) -> tuple[NDArray[np.intp] | None, tuple[str, ...]]:
    """The ``marker`` column: per-row indices ``(N,)`` and the names they index.

    With a model that has markers, a cell is one of its marker names or a number 1..M (in
    the model's order) and the names are the model's; without, the names are those in the
    file, in order of first appearance. No column: ``(None, ())`` (and a warning when the
    model has several markers: every row is then taken as the first).
    """
    path = resolve_csv(path)
    cells = read_column(path, "marker")
    known = model.marker_names
    if cells is None:
        if len(known) > 1:
            diagnostics.warn("no-marker-column",
                             f"{path.name}: model {model.name!r} has markers "
                             f"{', '.join(known)} but the file has no marker column: every "
                             f"row is taken as marker {known[0]}")
        return None, ()
    names = list(known)
    lookup = {n: i for i, n in enumerate(names)}
    idx = np.empty(len(cells), dtype=np.intp)
    for r, cell in enumerate(cells, start=1):
        if cell in lookup:
            idx[r - 1] = lookup[cell]
        elif known and cell.isdigit() and 1 <= int(cell) <= len(known):
            idx[r - 1] = int(cell) - 1
        elif known or not cell or any(c in cell for c in " \t\"'"):
            expected = (f"one of the model's markers {', '.join(known)} or a number "
                        f"1..{len(known)}" if known else "a marker name (no spaces or quotes)")
            raise InputError(f"column marker: {cell!r}, expected {expected}", file=path,
                             row=r)
        else:
            lookup[cell] = len(names)
            names.append(cell)
            idx[r - 1] = lookup[cell]
    return idx, tuple(names)


def read_joints(path: str | Path, model: SerialModel, *, angle_unit: str | None = None
                ) -> NDArray[np.float64]:
    """Joint values ``(N, n_joints)`` (rad; prismatic: length unit) from a CSV with
    ``q1..qn`` or the model's joint names (in `angle_unit`, default the model's; other
    columns ignored) or a laser-tracker export (``joint_1..``, degrees)."""
    model = _as_model(model)
    path = resolve_csv(path)
    header = csv_header(path)
    if _tracker_export(header):
        return read_measurements(path, model, angle_unit=angle_unit).q
    names = joint_columns(header, model, path)
    cols = read_table(path, names)
    q = np.column_stack([cols[n] for n in names])
    q *= model.joint_scale(angle_unit)
    return q


def _tracker_export(header: list[str]) -> bool:
    """The bundled UR5 laser-tracker export's columns (``joint_1..``, ``x_t``, ``x_dif``)."""
    return "x_t" in header and "joint_1" in header


def _read_tracker_export(path: Path, header: list[str], model: SerialModel,
                         angle_unit: str | None) -> Measurements:
    """measured = target + dif; joints in degrees (the export's own unit)."""
    n = model.n_joints
    if angle_unit not in (None, "deg"):
        raise InputError("a laser-tracker export (joint_1.., x_t, x_dif) has its joints in "
                         "degrees: --angle-unit does not apply", file=path)
    joints = [f"joint_{i}" for i in range(1, n + 1)]
    if f"joint_{n + 1}" in header:
        raise InputError(f"more joint columns than the model's {n} joints", file=path)
    cols = read_table(path, joints + ["x_t", "y_t", "z_t", "x_dif", "y_dif", "z_dif"])
    q = np.column_stack([cols[c] for c in joints])
    q *= model.joint_scale("deg")
    xyz = np.column_stack([cols[f"{a}_t"] + cols[f"{a}_dif"] for a in "xyz"])
    return Measurements(q, xyz, None, str(path))


def _checked_joint_columns(header: list[str], model: SerialModel, path: Path) -> list[str]:
    """`joint_columns`, with a ``q`` column count other than the model's refused."""
    n = model.n_joints
    joints = joint_columns(header, model, path)
    qcols = [c for c in header if _q_column(c)]
    if qcols and len(qcols) != n:
        names = joint_names(model)
        raise InputError(
            f"{len(qcols)} joint columns ({', '.join(qcols)}), model {model.name!r} has {n} "
            f"joints: expected q1..q{n}" + (f" or {', '.join(names)}" if names else ""),
            file=path)
    return joints


def _orientation_columns(header: list[str], path: Path) -> list[str]:
    """``qw, qx, qy, qz`` when the header has them (all four or none)."""
    present = [c for c in QUATERNION if c in header]
    if present and len(present) != 4:
        raise InputError(
            f"orientation columns {', '.join(present)} without the others: expected all of "
            "qw, qx, qy, qz (tool orientation as a unit quaternion) or none",
            file=path,
        )
    return present


def orientation_columns(header: list[str], path: Path) -> list[str]:
    """``qw, qx, qy, qz`` when the header has them, none when it has none; `InputError`
    for some of them only (the readers of a robot system's files, `kinecal.io.system_data`)."""
    return _orientation_columns(header, path)


def measured_poses(path: Path, cols: dict) -> tuple[NDArray[np.float64], NDArray | None,
                                                    NDArray | None]:
    """Measured points ``(N, 3)``, weights ``(N,)`` and rotations ``(N, 3, 3)`` (None when
    absent) from the columns `read_table` read (``x, y, z`` and the optional ``weight``,
    ``qw .. qz``); `InputError` for a non-positive weight or a quaternion off unit norm."""
    xyz = np.column_stack([cols[c] for c in "xyz"])
    quat = [c for c in QUATERNION if c in cols]
    return xyz, _weights(cols, path), _rotations(cols, quat, path)


def _weights(cols: dict[str, NDArray[np.float64]], path: Path) -> NDArray[np.float64] | None:
    weights = cols.get("weight")
    if weights is not None and not (weights > 0).all():
        row = int(np.argmax(~(weights > 0))) + 1
        raise InputError("column weight: expected a positive number", file=path, row=row)
    return weights


def _rotations(cols: dict[str, NDArray[np.float64]], quat: list[str], path: Path
               ) -> NDArray[np.float64] | None:
    if not quat:
        return None
    qv = np.column_stack([cols[c] for c in quat])
    norm = np.linalg.norm(qv, axis=1)
    bad = np.abs(norm - 1.0) > 1e-3
    if bad.any():
        row = int(np.argmax(bad)) + 1
        raise InputError(f"qw, qx, qy, qz: norm {norm[row - 1]:.6f}, expected a unit "
                         "quaternion", file=path, row=row)
    return matrix_from_quaternion(qv)


def _read_wide(path: Path, header: list[str], model: SerialModel, joints: list[str],
               scale: NDArray[np.float64]) -> Measurements:
    """A wide marker table (`kinecal.io.wide`): one row per pose, markers side by side."""
    rows, xyz, marker, names = read_wide(path, header, model.marker_names)
    cols = read_table(path, joints, optional=["weight"])
    q = np.column_stack([cols[c] for c in joints])[rows] * scale
    weights = _weights(cols, path)
    return Measurements(q, xyz, None if weights is None else weights[rows], str(path), None,
                        marker, names)


def read_measurements(path: str | Path, model: SerialModel,
                      orientation: PoseFormat | str | None = None, *,
                      angle_unit: str | None = None) -> Measurements:
    """Read a measurement CSV for `model` (a path or a bundled ``NAME:PART``).

    `model` may also be a bundled name or a model file path (loaded). Joint columns are in
    `angle_unit` (``deg`` or ``rad``; default the model's). The positions are ``x,y,z``
    (one row per measured point, an optional ``marker`` column) or a wide marker table
    ``x1,y1,z1,x2,...`` (one row per pose, `kinecal.io.wide`). `orientation`: the format
    of the orientation columns (`kinecal.io.poses.PoseFormat` or its text, e.g.
    ``intrinsic-xyz:deg``); default quaternions ``qw, qx, qy, qz`` when present.

    Raises
    ------
    InputError
        Missing columns, wrong joint count, NaN or non-numeric cells (with the row), bad
        station names, incomplete or non-unit orientations, standard deviations that are
        not positive.
    """
    model = _as_model(model)
    path = resolve_csv(path)
    header = csv_header(path)
    if _tracker_export(header):  # laser-tracker export (degrees)
        return _read_tracker_export(path, header, model, angle_unit)
    # per joint column: revolute in the angle unit, prismatic length
    scale = model.joint_scale(angle_unit)
    joints = _checked_joint_columns(header, model, path)
    if is_wide(header):
        return _read_wide(path, header, model, joints, scale)
    fmt = PoseFormat.parse(orientation, option="--orientation-format") if isinstance(
        orientation, str) else orientation
    cols = read_table(path, joints + ["x", "y", "z"], optional=["weight"])
    q = np.column_stack([cols[c] for c in joints])
    q *= scale
    xyz = np.column_stack([cols[c] for c in "xyz"])
    weights = _weights(cols, path)
    rotations, rotation, angles = read_orientation(path, header, fmt)
    sigma = read_sigma(path, header, rotation, angles, rotations is not None)
    marker, names = read_markers(path, model)
    station, stations = read_stations(path)
    return Measurements(q, xyz, weights, str(path), rotations, marker, names, station,
                        stations, sigma, **read_conditions(path))


def write_measurements(path: str | Path, data: Measurements, model: SerialModel) -> None:
    """Write `data` in kinecal's CSV format (revolute joint values in the model's angle
    unit, prismatic ones in its length unit; orientations as quaternions, their standard
    deviations about the measurement axes in degrees)."""
    q = np.asarray(data.q) / model.joint_scale()
    columns = {f"q{i + 1}": q[:, i] for i in range(q.shape[1])}
    columns.update({c: np.asarray(data.xyz)[:, k] for k, c in enumerate("xyz")})
    if data.rotations is not None:
        qv = quaternion_from_matrix(np.asarray(data.rotations))
        columns.update({c: qv[:, k] for k, c in enumerate(("qw", "qx", "qy", "qz"))})
    if data.weights is not None:
        columns["weight"] = np.asarray(data.weights)
    if data.marker is not None:
        columns["marker"] = np.asarray(data.marker_names, dtype=str)[np.asarray(data.marker)]
    if data.station is not None:
        columns["station"] = np.asarray(data.station_names, dtype=str)[np.asarray(data.station)]
    if data.sigma is not None:  # rotations about the measurement axes, as quaternions have
        s = np.asarray(data.sigma)
        columns.update({c: s[:, k] for k, c in enumerate(("sx", "sy", "sz"))})
        columns.update({c: np.degrees(s[:, 3 + k]) for k, c in
                        enumerate(("srx", "sry", "srz")) if s.shape[1] == 6})
    for name in ("temperature", "time"):
        if getattr(data, name) is not None:
            columns[name] = np.asarray(getattr(data, name), dtype=float)
    write_table(path, columns)
