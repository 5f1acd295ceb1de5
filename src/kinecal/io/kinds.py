"""Measurement files of every kind, the kind read from the columns (docs/measurement-kinds.md).

============  ======================================  ====================================
kind          columns (besides the joints)            one row is
============  ======================================  ====================================
``tracker``   ``x,y,z`` (``qw..qz``, ``weight``)      a measured tool point (pose)
``ballbar``   ``pivot,distance``                      the distance from an unknown pivot
``pair``      ``pair,distance``                       one end of a known distance
``point``     ``point``                               a touch of an unknown fixed point
``plane``     ``plane``                               a touch of an unknown plane
============  ======================================  ====================================

Joints are ``q1..qn`` or the model's joint names, in the model's units, as for tracker
files (`kinecal.io.measurements.joint_columns`); ``pivot``, ``pair``, ``point`` and
``plane`` hold ids (any text without commas: ``P1``, ``3``); ``distance`` is in the
model's length unit; an optional ``sigma`` column states each row's 1-sigma noise (length
unit); an optional ``marker`` column says which tool point touched (several markers);
point and plane files may give known fixtures (``px,py,pz[,nx,ny,nz]``,
`kinecal.io.fixtures`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinecal.data import (
    DISTANCE_KINDS,
    GAUGE_KINDS,
    KNOWN_COLUMNS,
    GaugeMeasurements,
    Measurements,
)
from kinecal.errors import InputError
from kinecal.io.csvtable import read_column, read_table, write_table
from kinecal.io.fixtures import read_known
from kinecal.io.measurements import (
    csv_header,
    joint_columns,
    joint_names,
    read_markers,
    read_measurements,
    resolve_csv,
)
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["KINDS", "gauge_columns", "gauge_values", "kind_of_columns", "read_gauge",
           "read_kind", "write_gauge"]

#: every kind -> the columns that name it
KINDS: dict[str, tuple[str, ...]] = {
    "tracker": ("x", "y", "z"),
    **{k: (c, "distance") if k in DISTANCE_KINDS else (c,) for k, c in GAUGE_KINDS.items()},
}


def kind_of_columns(header: list[str], path: Path | None = None) -> str:
    """The measurement kind of a CSV header (module docstring).

    Raises
    ------
    InputError
        Columns of two kinds, a ``pivot`` or ``pair`` column without ``distance`` (or the
        other way round). A header without any gauge column is a tracker file's (its
        reader then names the missing ``x, y, z``).
    """
    if "x_t" in header and "joint_1" in header:
        return "tracker"
    xyz = all(c in header for c in "xyz")
    gauges = [k for k, c in GAUGE_KINDS.items() if c in header]
    found = (["tracker"] if xyz else []) + gauges
    if len(found) > 1:
        cols = ", ".join(",".join(KINDS[k][:1] if k != "tracker" else KINDS[k]) for k in found)
        raise InputError(f"columns of {len(found)} measurement kinds ({cols}; kinds "
                         f"{', '.join(found)}): expected one kind per file", file=path)
    if gauges:
        kind = gauges[0]
        if kind in DISTANCE_KINDS and "distance" not in header:
            raise InputError(f"column {GAUGE_KINDS[kind]} without a distance column: a "
                             f"{kind} file has {','.join(KINDS[kind])}", file=path)
        if kind not in DISTANCE_KINDS and "distance" in header:
            raise InputError(f"a distance column in a {kind} file: distances go with pivot "
                             "(ballbar) or pair ids", file=path)
        return kind
    if "distance" in header:
        raise InputError("a distance column without pivot or pair ids: expected "
                         "pivot,distance (ballbar) or pair,distance (pair)", file=path)
    # no gauge column: a tracker file, whose reader names what is missing (x, y, z)
    return "tracker"


def read_kind(path: str | Path, model: SerialModel, orientation=None, *,
              angle_unit: str | None = None) -> Measurements | GaugeMeasurements:
    """Read a measurement file of any kind for `model` (the kind from its columns; joint
    columns in `angle_unit`, default the model's); `orientation`: the orientation format
    of a tracker file (`read_measurements`)."""
    path = resolve_csv(path)
    kind = kind_of_columns(csv_header(path), path)
    if kind == "tracker":
        return read_measurements(path, model, orientation, angle_unit=angle_unit)
    return read_gauge(path, model, kind, angle_unit=angle_unit)


def _ids(path: Path, column: str, n: int) -> tuple[np.ndarray, tuple[str, ...]]:
    cells = read_column(path, column) or []
    if len(cells) != n:  # pragma: no cover - read_table counted the same rows
        raise InputError(f"column {column}: {len(cells)} cells for {n} rows", file=path)
    lookup: dict[str, int] = {}
    idx = np.empty(n, dtype=np.intp)
    for r, cell in enumerate(cells, start=1):
        if not cell or any(c in cell for c in "\"'\t"):
            raise InputError(f"column {column}: {cell!r}, expected an id (text without "
                             "quotes, e.g. P1)", file=path, row=r)
        idx[r - 1] = lookup.setdefault(cell, len(lookup))
    return idx, tuple(lookup)


def read_gauge(path: str | Path, model: SerialModel, kind: str | None = None, *,
               angle_unit: str | None = None) -> GaugeMeasurements:
    """Read a ballbar, pair, point or plane file for `model` (joint columns in
    `angle_unit`, default the model's).

    Raises
    ------
    InputError
        Missing or extra joint columns, bad cells (with the row), a non-positive distance
        or sigma, an empty id.
    """
    path = resolve_csv(path)
    header = csv_header(path)
    kind = kind_of_columns(header, path) if kind is None else kind
    if kind not in GAUGE_KINDS:
        raise InputError(f"expected a ballbar, pair, point or plane file, got {kind} columns",
                         file=path)
    joints = joint_columns(header, model, path)
    n = model.n_joints
    qcols = [c for c in header if c.startswith("q") and c[1:].isdigit()]
    if qcols and len(qcols) != n:
        names = joint_names(model)
        raise InputError(f"{len(qcols)} joint columns ({', '.join(qcols)}), model "
                         f"{model.name!r} has {n} joints: expected q1..q{n}"
                         + (f" or {', '.join(names)}" if names else ""), file=path)
    cols = read_table(path, joints + gauge_columns(kind), optional=["sigma"])
    q = np.column_stack([cols[c] for c in joints]) * model.joint_scale(angle_unit)
    group, names, distance, sigma = gauge_values(path, kind, cols, len(q),
                                                  model.length_unit)
    known = read_known(path, kind, group, names)
    marker, markers = read_markers(path, model)
    return GaugeMeasurements(kind, q, group, names, distance, sigma, str(path), marker,
                             markers, known)


def gauge_columns(kind: str) -> list[str]:
    """The numeric columns a gauge kind's file must have besides the joints."""
    return ["distance"] if kind in DISTANCE_KINDS else []


def gauge_values(path: Path, kind: str, cols: dict, n: int, length_unit: str
                 ) -> tuple[np.ndarray, tuple[str, ...], np.ndarray | None, np.ndarray | None]:
    """Group index per row and group names, distances and sigmas of a gauge file, from the
    columns `read_table` read (``distance``, ``sigma``) and its id column; `InputError`
    for a non-positive distance or sigma or a bad id."""
    for name in ("distance", "sigma"):
        v = cols.get(name)
        if v is not None and not (v > 0).all():
            row = int(np.argmax(~(v > 0))) + 1
            raise InputError(f"column {name}: {v[row - 1]:g}, expected a positive length "
                             f"({length_unit})", file=path, row=row)
    group, names = _ids(path, GAUGE_KINDS[kind], n)
    return group, names, cols.get("distance"), cols.get("sigma")


def write_gauge(path: str | Path, data: GaugeMeasurements, model: SerialModel, *,
                angle_unit: str | None = None) -> None:
    """Write gauge measurements in their kind's CSV format (joints in the model's units, or
    revolute ones in `angle_unit`)."""
    q = np.asarray(data.q) / model.joint_scale(angle_unit)
    columns: dict[str, np.ndarray] = {f"q{i + 1}": q[:, i] for i in range(q.shape[1])}
    columns[GAUGE_KINDS[data.kind]] = np.asarray(data.group_names, dtype=str)[data.group]
    if data.distance is not None:
        columns["distance"] = np.asarray(data.distance)
    if data.sigma is not None:
        columns["sigma"] = np.asarray(data.sigma)
    if data.marker is not None:
        columns["marker"] = np.asarray(data.marker_names, dtype=str)[np.asarray(data.marker)]
    if data.known is not None:  # known fixtures: their rows carry them, unknown ones blank
        known = np.asarray(data.known, dtype=float)[np.asarray(data.group)]
        for k, c in enumerate(KNOWN_COLUMNS[data.kind]):
            columns[c] = np.array(["" if np.isnan(v) else repr(float(v)) for v in known[:, k]],
                                  dtype=object)
    write_table(path, columns)
