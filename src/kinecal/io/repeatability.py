"""Repeated-measurement files of ISO 9283 tests (``kinecal iso9283``, docs/iso9283.md).

One row per pose and cycle, header names in any order:

- ``pose`` (a name: ``P1``, ``1``, ...) and ``cycle`` (an integer);
- the measured position ``x, y, z`` and optionally the measured orientation ``qw, qx, qy,
  qz`` (unit quaternion, w first);
- the commanded pose: ``cx, cy, cz`` and optionally ``cqw, cqx, cqy, cqz``, or, with a
  model, the commanded joints ``q1..qn`` (or the model's joint names, in its angle unit),
  whose forward kinematics give the commanded position and orientation.

A pose's commanded cells may be filled on one of its rows only (the others left empty);
where they are repeated they must agree. Every pose must be measured exactly once in every
cycle. Every mistake is an `InputError` with the file and the 1-based data row.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.data import RepeatedPoses
from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, check_separator, read_column, read_table
from kinecal.spatial import matrix_from_quaternion

__all__ = ["read_repeatability"]

_QUAT = ("qw", "qx", "qy", "qz")
_CPOS = ("cx", "cy", "cz")
_CQUAT = ("cqw", "cqx", "cqy", "cqz")


def _header(path: Path) -> list[str]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            for row in csv.reader(fh):
                if row and any(c.strip() for c in row):
                    check_separator(row, path)
                    return [h.strip() for h in row]
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    raise InputError("empty file; expected a header with pose, cycle, x, y, z", file=path)


def _group(header: list[str], names: tuple[str, ...], what: str, path: Path) -> bool:
    """True when every column of `names` is in `header`, False when none is."""
    present = [c for c in names if c in header]
    if present and len(present) != len(names):
        raise InputError(f"{what} columns {', '.join(present)} without the others: expected "
                         f"all of {', '.join(names)} or none", file=path)
    return bool(present)


def _unit_quaternions(q: NDArray[np.float64], rows: NDArray[np.intp], names: tuple[str, ...],
                      path: Path) -> NDArray[np.float64]:
    norm = np.linalg.norm(q, axis=-1).ravel()
    bad = np.abs(norm - 1.0) > 1e-3
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(f"{', '.join(names)}: norm {norm[k]:.6f}, expected a unit quaternion",
                         file=path, row=int(np.ravel(rows)[k]) + 1)
    return matrix_from_quaternion(q)


def _per_pose(cells: dict[str, list[str]], names: tuple[str, ...] | list[str],
              pose_rows: list[list[int]], labels: list[str], path: Path) -> NDArray[np.float64]:
    """One value per pose and column ``(P, len(names))`` from text cells that may be empty on
    some of a pose's rows; the filled ones must agree."""
    out = np.empty((len(pose_rows), len(names)))
    for i, rows in enumerate(pose_rows):
        value, first = None, -1
        for r in rows:
            row = [cells[n][r] for n in names]
            if not any(row):
                continue
            empty = [n for n, c in zip(names, row, strict=True) if not c]
            if empty:
                raise InputError(f"column(s) {', '.join(empty)} empty: expected all of "
                                 f"{', '.join(names)} or none on a row", file=path, row=r + 1)
            v = np.empty(len(names))
            for k, (n, c) in enumerate(zip(names, row, strict=True)):
                try:
                    v[k] = float(c)
                except ValueError:
                    v[k] = np.nan
                if not abs(v[k]) <= MAX_CELL:
                    raise InputError(f"column {n}: {c!r}, expected a finite number of at most "
                                     f"{MAX_CELL:g} in size", file=path, row=r + 1)
            if value is None:
                value, first = v, r
            elif np.any(np.abs(v - value) > 1e-9 * np.maximum(1.0, np.abs(value))):
                raise InputError(
                    f"pose {labels[i]!r}: commanded {', '.join(names)} differ from row "
                    f"{first + 1}: expected the same commanded pose in every cycle",
                    file=path, row=r + 1)
        if value is None:
            raise InputError(f"pose {labels[i]!r} has no commanded values: expected "
                             f"{', '.join(names)} on at least one of its rows", file=path,
                             row=rows[0] + 1)
        out[i] = value
    return out


def _cycles(path: Path, labels: list[str], cycle: NDArray[np.float64]
            ) -> tuple[list[str], list[int], list[list[int]]]:
    """Pose names (order of appearance), sorted cycle numbers, and the row of every pose in
    every cycle ``rows[pose][cycle]``; refuses duplicates, gaps and fewer than 2 cycles."""
    order: dict[str, int] = {}
    found: list[dict[int, int]] = []
    for r, (label, c) in enumerate(zip(labels, cycle, strict=True)):
        if not label:
            raise InputError("column pose: empty, expected a pose name", file=path, row=r + 1)
        if c != np.round(c):
            raise InputError(f"column cycle: {c!r}, expected a whole number", file=path,
                             row=r + 1)
        i = order.setdefault(label, len(order))
        if i == len(found):
            found.append({})
        c = int(c)
        if c in found[i]:
            raise InputError(f"duplicate cycle number: pose {label!r} has cycle {c} on rows "
                             f"{found[i][c] + 1} and {r + 1}; expected each pose once per "
                             "cycle", file=path, row=r + 1)
        found[i][c] = r
    names = list(order)
    cycles = sorted(set().union(*found))
    for c in cycles:
        missing = [names[i] for i, rows in enumerate(found) if c not in rows]
        if missing:
            raise InputError(
                f"cycles of different lengths: cycle {c} has {len(names) - len(missing)} of "
                f"the {len(names)} poses (missing: {', '.join(missing[:5])}"
                f"{', ...' if len(missing) > 5 else ''}); expected every pose once in every "
                "cycle", file=path)
    if len(cycles) < 2:
        raise InputError(f"{len(cycles)} cycle (cycle {cycles[0]}): expected at least 2 cycles "
                         "of every pose for the repeatabilities (ISO 9283 prescribes 30)",
                         file=path)
    return names, cycles, [[rows[c] for c in cycles] for rows in found]


def _commanded_source(header: list[str], model: Any, path: Path) -> list[str] | None:
    """The joint columns when the commanded poses come from `model` (None: ``cx..``)."""
    has_c = _group(header, _CPOS, "commanded position", path)
    has_q = any(h.startswith("q") and h[1:].isdigit() for h in header)
    if model is None:
        if has_c:
            return None
        if has_q:
            raise InputError("joint columns without a model: give --model to compute the "
                             "commanded poses from the joints, or columns cx, cy, cz",
                             file=path)
        raise InputError("no commanded pose: expected columns cx, cy, cz (and optionally "
                         "cqw, cqx, cqy, cqz) or joint columns q1..qn with --model", file=path)
    if has_c:
        raise InputError("both commanded columns cx, cy, cz and --model: expected one "
                         "source of the commanded pose (drop --model or the c columns)",
                         file=path)
    from kinecal.io.measurements import joint_columns

    joints = joint_columns(header, model, path)
    missing = [c for c in joints if c not in header]
    if missing:
        raise InputError(f"missing joint column(s) {', '.join(missing)}: with --model the "
                         f"commanded pose is the forward kinematics of {', '.join(joints)}",
                         file=path)
    return joints


def read_repeatability(path: str | Path, model: Any = None,
                       length_unit: str | None = None, *,
                       angle_unit: str | None = None) -> RepeatedPoses:
    """Read an ISO 9283 repeated-measurement CSV (module docstring).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    model : SerialModel, optional
        With joint columns: the commanded poses are its forward kinematics (its tool
        frame), in its length unit.
    length_unit : str, optional
        Unit label of a file without model (default ``mm``).
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns (default the model's).

    Returns
    -------
    RepeatedPoses
        Poses in order of first appearance, cycles sorted.

    Raises
    ------
    InputError
        Missing or partial column groups, a bad cell, a duplicate (pose, cycle), a pose
        missing from a cycle, fewer than 2 cycles, a pose without commanded values,
        commanded values that differ between cycles, a quaternion that is not unit.
    """
    path = Path(path)
    header = _header(path)
    missing = [c for c in ("pose", "cycle", "x", "y", "z") if c not in header]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; expected pose, cycle, x, "
                         f"y, z (found {', '.join(header)})", file=path)
    has_q = _group(header, _QUAT, "measured orientation", path)
    has_cq = _group(header, _CQUAT, "commanded orientation", path)
    joints = _commanded_source(header, model, path)
    if has_cq and (joints is not None or not has_q):
        why = "with --model the orientation is the model's" if joints is not None else \
            "without measured qw, qx, qy, qz there is nothing to compare"
        raise InputError(f"commanded orientation columns cqw..cqz: {why}", file=path)
    cols = read_table(path, ["cycle", "x", "y", "z", *(_QUAT if has_q else ())])
    text = read_column(path, "pose") or []
    names, cycles, rows = _cycles(path, text, cols["cycle"])
    index = np.asarray(rows, dtype=np.intp)  # (P, n) data rows
    xyz = np.column_stack([cols[c] for c in "xyz"])
    measured_rot = None
    if has_q:
        q = np.column_stack([cols[c] for c in _QUAT])[index]
        measured_rot = _unit_quaternions(q, index, _QUAT, path)
    wanted = list(joints) if joints is not None else [*_CPOS, *(_CQUAT if has_cq else ())]
    cells = {c: read_column(path, c) or [] for c in wanted}
    values = _per_pose(cells, wanted, rows, names, path)
    q_cmd = commanded_rot = None
    if joints is not None:
        q_cmd = values * model.joint_scale(angle_unit)
        T = model.fk(q_cmd)
        commanded, commanded_rot = T[:, :3, 3], T[:, :3, :3]
        unit = model.length_unit
    else:
        commanded = values[:, :3]
        if has_cq:
            commanded_rot = _unit_quaternions(values[:, 3:], index[:, 0], _CQUAT, path)
        unit = length_unit or "mm"
    return RepeatedPoses(tuple(names), np.asarray(cycles, dtype=np.int64), xyz[index],
                         commanded, measured_rot, commanded_rot, q_cmd, unit, str(path))
