"""Measurement files of a robot system: every kind, each row naming its chain.

A system's files are those of one arm (docs/measurement-kinds.md: ``x,y,z[,qw..qz]``,
``pivot,distance``, ``pair,distance``, ``point``, ``plane``) with three differences:

* joint columns carry the system's joint names (``torso_1_joint``, ``arm.q3``), in the
  system's units; a row gives the joints of its chain, and the cells of joints off its
  chain are blank (a filled one is refused: it would be silently ignored);
* a ``tip`` column names the chain of each row (a tip link, or a part of a system file);
  a file without one is all of one tip (`tip`, the command line's ``--tip``), which a
  system of one tip needs not say;
* ``point`` rows may carry a ``carrier`` column: the link that holds the touched point
  (a workpiece on a positioner's table, probed by an arm): the row then also gives the
  joints that move that link. Blank: the point is fixed in the measurement frame.

Rows of different tips share the kind's unknowns: a ``pair`` id on two tips is a bar
between the two hands, a ``point`` id touched by two tips one point, and tracker rows of
every chain are in one tracker frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.data import GAUGE_KINDS, GaugeMeasurements, Measurements
from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, read_columns, read_table, write_table
from kinecal.io.fixtures import read_known
from kinecal.io.kinds import gauge_columns, gauge_values, kind_of_columns
from kinecal.io.measurements import (
    csv_header,
    measured_poses,
    orientation_columns,
    resolve_csv,
)
from kinecal.kinematics.tree.system import SystemModel
from kinecal.spatial import quaternion_from_matrix

__all__ = ["read_system_data", "system_readings", "write_system_data",
           "write_system_joints"]

Array = NDArray[np.float64]


def _number(cell: str, path: Path, row: int, column: str) -> float:
    try:
        v = float(cell)
    except ValueError:
        v = np.nan
    if not (np.isfinite(v) and abs(v) <= MAX_CELL):
        raise InputError(f"column {column}: {cell!r}, expected a finite number (or a blank "
                         "cell for a joint off the row's chain)", file=path, row=row)
    return v


def _tips(path: Path, cells: list[str] | None, tip: str | None, system: SystemModel,
          n: int) -> NDArray[np.intp]:
    names = system.tips
    if tip is not None:
        system.tip_number(tip)  # a known tip, whatever the file
    if cells is not None and tip is not None:
        raise InputError("applies to files without a tip column (this one has one)",
                         option="--tip")
    if cells is None:
        if tip is None and len(names) > 1:
            raise InputError(f"no tip column: expected a tip column naming each row's chain "
                             f"(one of {', '.join(names)}) or --tip for the whole file",
                             file=path)
        return np.full(n, system.tip_number(tip) if tip is not None else 0, dtype=np.intp)
    lookup = {t: k for k, t in enumerate(names)}
    out = np.empty(n, dtype=np.intp)
    for r, cell in enumerate(cells, start=1):
        if cell not in lookup:
            raise InputError(f"column tip: {cell!r}, expected one of the system's tips "
                             f"{', '.join(names)}", file=path, row=r)
        out[r - 1] = lookup[cell]
    return out


def _carriers(path: Path, cells: list[str] | None, system: SystemModel
              ) -> tuple[NDArray[np.intp] | None, tuple[str, ...]]:
    if cells is None:
        return None, ()
    links = set(system.links)
    names: list[str] = []
    out = np.full(len(cells), -1, dtype=np.intp)
    for r, cell in enumerate(cells, start=1):
        if not cell:
            continue
        if cell not in links or cell == system.root:
            raise InputError(f"column carrier: {cell!r}, expected a link of the system that "
                             f"moves (e.g. {', '.join(sorted(links - {system.root})[:6])}) or "
                             "a blank cell (the point is fixed)", file=path, row=r)
        if cell not in names:
            names.append(cell)
        out[r - 1] = names.index(cell)
    return out, tuple(names)


def system_readings(path: Path, header: list[str], system: SystemModel, tip: str | None,
                    carrier_ok: bool = False, angle_unit: str | None = None
                    ) -> tuple[Array, NDArray[np.intp],
                                                       NDArray[np.intp] | None,
                                                       tuple[str, ...]]:
    """Joint readings ``(N, n_joints)`` (API units; joints off a row's chain set inside
    their limits), tip per row, carrier per row (or None) and the carrier names of a
    system file (module docstring); revolute readings in `angle_unit` (default the
    system's).

    Raises
    ------
    InputError
        ``q1..qn`` columns, a row's chain joint blank, a joint off its chain filled, bad
        cells, unknown tips or links (with the file and row).
    """
    joints = list(system.joint_names)
    qcols = [c for c in header if c.startswith("q") and c[1:].isdigit()]
    if qcols and not any(c in joints for c in qcols):
        raise InputError(f"joint columns {', '.join(qcols)}: a system's joint columns are its "
                         f"joint names ({', '.join(joints)})", file=path)
    present = [j for j in joints if j in header]
    if not present:
        raise InputError(f"no joint columns: expected the system's joint names "
                         f"({', '.join(joints)})", file=path)
    cells = read_columns(path, [*present, "tip", "carrier"])
    n = len(cells[present[0]])
    if "carrier" in cells and not carrier_ok:
        raise InputError("a carrier column applies to point files only", file=path)
    tips = _tips(path, cells.get("tip"), tip, system, n)
    carrier, carriers = _carriers(path, cells.get("carrier"), system)
    raw = np.full((n, len(joints)), np.nan)
    for j, name in enumerate(joints):
        for r, cell in enumerate(cells.get(name, ()), start=1):
            if cell:
                raw[r - 1, j] = _number(cell, path, r, name)
    need = np.zeros((len(system.tips), len(joints)), dtype=bool)
    for t, name in enumerate(system.tips):
        need[t, system.chain_joints(name)] = True
    want = need[tips]
    if carrier is not None:
        for c, link in enumerate(carriers):
            want[np.ix_(carrier == c, system.link_joints(link))] = True
    _check_cells(path, raw, want, joints, system.tips, tips)
    lo, hi = system.joint_limits[:, 0], system.joint_limits[:, 1]
    q = np.where(want, raw * system.joint_scale(angle_unit), np.clip(0.0, lo, hi))
    return q, tips, carrier, carriers


def _check_cells(path, raw, want, joints, tip_names, tips) -> None:
    filled = ~np.isnan(raw)
    for bad, words in ((want & ~filled, "is blank: the row's chain (tip {tip}) reads it"),
                       (filled & ~want, "is not on the row's chain (tip {tip}): leave it "
                        "blank")):
        if bad.any():
            r, j = np.argwhere(bad)[0]
            raise InputError(f"joint {joints[j]} " + words.format(tip=tip_names[tips[r]]),
                             file=path, row=int(r) + 1)


def read_system_data(path: str | Path, system: SystemModel, tip: str | None = None,
                     angle_unit: str | None = None) -> Measurements | GaugeMeasurements:
    """Read a measurement file of any kind for `system` (module docstring); `tip`: the
    chain of a file without a ``tip`` column; `angle_unit`: of its revolute joint columns
    (default the system's)."""
    path = resolve_csv(path)
    header = csv_header(path)
    kind = kind_of_columns(header, path)
    if "marker" in header:
        raise InputError("a marker column: a system's rows name their chain in a tip "
                         "column (markers on a system's tips are not supported)", file=path)
    if kind == "tracker" and "x_t" in header:
        raise InputError("a laser-tracker export of one arm, not a system's file", file=path)
    q, tips, carrier, carriers = system_readings(path, header, system, tip,
                                                 carrier_ok=kind == "point",
                                                 angle_unit=angle_unit)
    if kind == "tracker":
        cols = read_table(path, ["x", "y", "z"],
                          optional=["weight", *orientation_columns(header, path)])
        xyz, weights, rotations = measured_poses(path, cols)
        return Measurements(q, xyz, weights, str(path), rotations, tips, system.tips)
    numeric = gauge_columns(kind)
    cols = read_table(path, numeric, optional=["sigma"]) if numeric or "sigma" in header \
        else {}
    group, names, distance, sigma = gauge_values(path, kind, cols, len(q), system.length_unit)
    known = read_known(path, kind, group, names)  # in the measurement frame (or the carrier's)
    return GaugeMeasurements(kind, q, group, names, distance, sigma, str(path), tips,
                             system.tips, known=known, carrier=carrier,
                             carrier_names=carriers)


def _joint_columns(q: Array, tips: NDArray[np.intp], carrier, carrier_names,
                   system: SystemModel) -> dict[str, np.ndarray]:
    """The joint columns of rows (system units; blank off each row's chain and carrier)."""
    n = len(q)
    want = np.zeros((n, system.n_joints), dtype=bool)
    for t, name in enumerate(system.tips):
        want[np.ix_(tips == t, system.chain_joints(name))] = True
    if carrier is not None:
        for c, link in enumerate(carrier_names):
            want[np.ix_(carrier == c, system.link_joints(link))] = True
    q = np.asarray(q) / system.joint_scale()
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(system.joint_names):
        cells = np.array([repr(float(v)) for v in q[:, j]], dtype=object)
        cells[~want[:, j]] = ""
        columns[name] = cells
    columns["tip"] = np.asarray(system.tips, dtype=object)[tips]
    return columns


def write_system_joints(path: str | Path, q: Array, tips: NDArray[np.intp],
                        system: SystemModel) -> None:
    """Write rows of joints and tips alone (a plan: ``kinecal select-poses`` of a system)."""
    write_table(path, _joint_columns(q, np.asarray(tips), None, (), system))


def write_system_data(path: str | Path, data: Measurements | GaugeMeasurements,
                      system: SystemModel) -> None:
    """Write `data` of `system` (joints by name in the system's units, blank off each
    row's chain; a ``tip`` column; ``carrier`` for carried points)."""
    n = len(data)
    tips = np.zeros(n, dtype=np.intp) if data.marker is None else np.asarray(data.marker)
    carrier = getattr(data, "carrier", None)
    columns = _joint_columns(data.q, tips, carrier, getattr(data, "carrier_names", ()),
                             system)
    if isinstance(data, Measurements):
        columns.update({c: np.asarray(data.xyz)[:, k] for k, c in enumerate("xyz")})
        if data.rotations is not None:
            qv = quaternion_from_matrix(np.asarray(data.rotations))
            columns.update({c: qv[:, k] for k, c in enumerate(("qw", "qx", "qy", "qz"))})
        if data.weights is not None:
            columns["weight"] = np.asarray(data.weights)
    else:
        columns[GAUGE_KINDS[data.kind]] = np.asarray(data.group_names, dtype=object)[data.group]
        if data.distance is not None:
            columns["distance"] = np.asarray(data.distance)
        if data.sigma is not None:
            columns["sigma"] = np.asarray(data.sigma)
        if carrier is not None:
            names = np.asarray([*data.carrier_names, ""], dtype=object)
            columns["carrier"] = names[np.where(carrier < 0, len(data.carrier_names), carrier)]
    write_table(path, columns)
