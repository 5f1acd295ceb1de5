"""Known fixtures: points and planes whose position in the base frame is known.

A calibration block's sockets, the faces of a fixture the arm touches, the three planes
of FIGAROH's MATE set at known x, y and z: their geometry need not be solved with the arm.
It is given per ``point`` or ``plane`` id, in the base frame and the model's length unit,
either in the measurement file itself or in a separate fixture file
(docs/measurement-kinds.md, "Known fixtures"):

==========  ==============================  =============================================
kind        columns                         meaning
==========  ==============================  =============================================
``point``   ``px,py,pz``                    the point
``plane``   ``px,py,pz,nx,ny,nz``           a point on the plane and its normal (any
                                            length: normalised)
==========  ==============================  =============================================

In a measurement file the columns may be blank on the rows of ids that are unknown (known
and unknown ids mix in one file); rows of one id that give them must agree. A fixture
file (``--fixture FILE``) holds one row per id: ``point,px,py,pz`` or
``plane,px,py,pz,nx,ny,nz``; its ids name the groups of the point or plane files of the
calibration.

Entry points: `read_known` (the columns of a measurement file), `read_fixture` (a fixture
file), `with_fixture` (measurements with a fixture's known groups).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.data import KNOWN_COLUMNS, GaugeMeasurements
from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, read_column
from kinecal.io.measurements import csv_header, resolve_csv

__all__ = ["Fixture", "read_fixture", "read_known", "with_fixture"]

Array = NDArray[np.float64]

#: two rows of one id agree when their coordinates differ by less than this (relative to
#: the coordinate's size, at least 1 length unit)
AGREE = 1e-9
#: every known column of any kind
ALL_COLUMNS = tuple(dict.fromkeys(c for cols in KNOWN_COLUMNS.values() for c in cols))


@dataclasses.dataclass(frozen=True)
class Fixture:
    """A fixture file: the known geometry of some ids of one kind.

    Attributes
    ----------
    kind : {"point", "plane"}
    values : dict of str to ndarray
        Per id: ``(3,)`` point or ``(6,)`` point and unit normal (base frame, length unit).
    source : str
    """

    kind: str
    values: dict[str, Array]
    source: str = ""


def _number(cell: str, column: str, path: Path, row: int) -> float:
    try:
        v = float(cell)
    except ValueError:
        raise InputError(f"column {column}: {cell!r} is not a number", file=path,
                         row=row) from None
    if not np.isfinite(v) or abs(v) > MAX_CELL:
        raise InputError(f"column {column}: {cell!r}, expected a finite number of at most "
                         f"{MAX_CELL:g} in size", file=path, row=row)
    return v


def _row_values(cells: Sequence[str], columns: Sequence[str], path: Path, row: int
                ) -> Array | None:
    """One row's known values (None when every cell is blank); a plane's normal
    normalised."""
    blank = [c for c, v in zip(columns, cells, strict=True) if not v]
    if len(blank) == len(columns):
        return None
    if blank:
        given = [c for c in columns if c not in blank]
        raise InputError(f"column {', '.join(blank)}: blank where {', '.join(given)} "
                         f"{'is' if len(given) == 1 else 'are'} given: expected all of "
                         f"{','.join(columns)} (a known fixture) or none (unknown)",
                         file=path, row=row)
    v = np.array([_number(x, c, path, row) for x, c in zip(cells, columns, strict=True)])
    if v.size == 6:
        norm = float(np.linalg.norm(v[3:]))
        if not norm > 0:
            raise InputError("columns nx,ny,nz: a zero normal, expected the plane's normal "
                             "direction", file=path, row=row)
        v[3:] /= norm
    return v


def _check_columns(header: Sequence[str], kind: str, path: Path) -> list[str]:
    """The known columns of `kind` in `header` (all of them, or none)."""
    cols = KNOWN_COLUMNS.get(kind, ())
    foreign = [c for c in ALL_COLUMNS if c in header and c not in cols]
    if foreign:
        expected = (f"a {kind} file gives {','.join(cols)}" if cols else
                    f"{kind} files have no known geometry (points and planes do)")
        raise InputError(f"column(s) {', '.join(foreign)}: {expected}", file=path)
    present = [c for c in cols if c in header]
    if present and len(present) != len(cols):
        missing = [c for c in cols if c not in present]
        raise InputError(f"column(s) {', '.join(missing)} missing: a known {kind} gives "
                         f"{','.join(cols)}", file=path)
    return present


def read_known(path: str | Path, kind: str, group: NDArray[np.intp],
               names: Sequence[str]) -> Array | None:
    """The known geometry per group ``(G, 3 or 6)`` (NaN rows: unknown) from the
    ``px,py,pz[,nx,ny,nz]`` columns of a point or plane file, or None without them.

    Raises
    ------
    InputError
        Known columns of another kind, only some of them, a row with some cells blank, a
        cell that is no number, a zero normal, or two rows of one id that disagree.
    """
    path = resolve_csv(path)
    cols = _check_columns(csv_header(path), kind, path)
    if not cols:
        return None
    cells = [read_column(path, c) or [] for c in cols]
    known = np.full((len(names), len(cols)), np.nan)
    first = np.zeros(len(names), dtype=np.intp)
    for r in range(len(group)):
        v = _row_values([c[r] for c in cells], cols, path, r + 1)
        if v is None:
            continue
        g = int(group[r])
        if np.isnan(known[g, 0]):
            known[g], first[g] = v, r + 1
        elif np.abs(v - known[g]).max() > AGREE * max(1.0, float(np.abs(v).max())):
            raise InputError(f"{kind} {names[g]!r}: {','.join(cols)} differ from row "
                             f"{first[g]}'s: expected one known {kind} per id", file=path,
                             row=r + 1)
    return known


def read_fixture(path: str | Path) -> Fixture:
    """A fixture file: ``point,px,py,pz`` or ``plane,px,py,pz,nx,ny,nz`` rows, one per id.

    Raises
    ------
    InputError
        No ``point`` or ``plane`` column (or both), missing or foreign known columns, an
        empty id, a bad cell, a zero normal, an id given twice with other values.
    """
    path = Path(path)
    header = csv_header(path)
    kinds = [k for k in KNOWN_COLUMNS if k in header]
    if len(kinds) != 1:
        raise InputError("a fixture file has one id column, point or plane (with "
                         "px,py,pz or px,py,pz,nx,ny,nz), found "
                         f"{', '.join(header) or 'nothing'}", file=path)
    kind = kinds[0]
    cols = _check_columns(header, kind, path)
    if not cols:
        raise InputError(f"column(s) {', '.join(KNOWN_COLUMNS[kind])} missing: a fixture "
                         f"file gives each {kind}'s known geometry", file=path)
    ids = read_column(path, kind) or []
    if not ids:
        raise InputError(f"no rows: expected one {kind} per row", file=path)
    cells = [read_column(path, c) or [] for c in cols]
    values: dict[str, Array] = {}
    for r, name in enumerate(ids, start=1):
        if not name or any(c in name for c in "\"'\t"):
            raise InputError(f"column {kind}: {name!r}, expected an id (text without quotes, "
                             "e.g. P1)", file=path, row=r)
        v = _row_values([c[r - 1] for c in cells], cols, path, r)
        if v is None:
            raise InputError(f"{kind} {name!r}: no {','.join(cols)}: a fixture file gives "
                             "known geometry only", file=path, row=r)
        if name in values and np.abs(values[name] - v).max() > AGREE * max(1.0, abs(v).max()):
            raise InputError(f"{kind} {name!r} is given twice with other values", file=path,
                             row=r)
        values[name] = v
    return Fixture(kind, values, str(path))


def with_fixture(data: GaugeMeasurements, fixtures: Sequence[Fixture]) -> GaugeMeasurements:
    """`data` with the known groups of `fixtures` of its kind (by id) added to those its
    own columns give.

    Raises
    ------
    InputError
        A fixture and the file (or two fixtures) giving one id different values.
    """
    mine = [f for f in fixtures if f.kind == data.kind]
    if not mine:
        return data
    cols = KNOWN_COLUMNS[data.kind]
    known = (np.full((len(data.group_names), len(cols)), np.nan) if data.known is None
             else np.array(data.known, dtype=float))
    where = ["" if np.isnan(k).all() else data.source for k in known]
    for f in mine:
        for g, name in enumerate(data.group_names):
            v = f.values.get(name)
            if v is None:
                continue
            if not np.isnan(known[g]).all():
                if np.abs(known[g] - v).max() > AGREE * max(1.0, float(np.abs(v).max())):
                    raise InputError(f"{data.kind} {name!r}: the fixture gives other "
                                     f"coordinates than {Path(where[g]).name}", file=f.source)
                continue
            known[g], where[g] = v, f.source
    return dataclasses.replace(data, known=known)
