"""Wide marker tables: ``x1,y1,z1,x2,y2,z2,...`` are markers 1..k measured in one pose.

Motion-capture exports (FIGAROH's mocap sets among them) write one row per arm pose with
the positions of every marker side by side, where kinecal's long form writes one row per
marker with a ``marker`` column. `read_wide` reads the wide form into the long one: each
pose row becomes k rows (pose-major, markers in order), marker ``i`` being the model's
i-th marker when the model declares markers (at least k of them), else a marker named
``i``. A marker whose three cells are blank on a row was not seen in that pose (occluded)
and gives no row; one or two blank cells of a marker are refused. Other columns (a
time stamp, a row number, a noise estimate) are ignored, as in the long form.

Refused, naming the file (and row and column where there is one): a marker with some of
its three columns (``x3,y3`` without ``z3``), markers not numbered 1..k without gaps, both
``x,y,z`` and ``x1,...``, a ``marker`` column or orientation columns beside the wide
markers, cells that are no finite numbers.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, read_columns

__all__ = ["is_wide", "marker_count", "read_wide"]

Array = NDArray[np.float64]

_WIDE = re.compile(r"^([xyz])([1-9][0-9]*)$")


def is_wide(header: Sequence[str]) -> bool:
    """Whether a header has wide marker columns (``x1``, ``y1``, ...)."""
    return any(_WIDE.match(h) for h in header)


def marker_count(header: Sequence[str], path: Path | None = None) -> int:
    """The number k of markers of a wide header (columns ``x1..zk``, none missing).

    Raises
    ------
    InputError
        A marker without all of its three columns, markers not numbered 1..k, or
        ``x,y,z`` / ``marker`` / orientation columns beside them.
    """
    found: dict[int, set[str]] = {}
    for h in header:
        m = _WIDE.match(h)
        if m:
            found.setdefault(int(m.group(2)), set()).add(m.group(1))
    if not found:
        return 0
    both = [c for c in ("x", "y", "z", "marker", "qw", "qx", "qy", "qz") if c in header]
    if both:
        raise InputError(f"column(s) {', '.join(both)} beside wide marker columns "
                         "x1,y1,z1,...: expected one layout, one row per marker (x,y,z and "
                         "a marker column) or one row per pose (x1,y1,z1,x2,... for markers "
                         "1..k; positions only)", file=path)
    k = max(found)
    for i in range(1, k + 1):
        have = found.get(i, set())
        if have != {"x", "y", "z"}:
            missing = [f"{a}{i}" for a in "xyz" if a not in have]
            raise InputError(f"column(s) {', '.join(missing)} missing: a wide marker table "
                             f"gives x{i},y{i},z{i} for every marker 1..{k}", file=path)
    return k


def _values(cells: list[str], column: str, path: Path) -> Array:
    """A column's numbers, NaN for blank cells; anything else that is no finite number of
    at most `MAX_CELL` refused with its row."""
    out = np.empty(len(cells))
    for r, c in enumerate(cells):
        if not c:
            out[r] = np.nan
            continue
        try:
            v = float(c)
        except ValueError:
            raise InputError(f"column {column}: {c!r} is not a number", file=path,
                             row=r + 1) from None
        if not np.isfinite(v) or abs(v) > MAX_CELL:
            raise InputError(f"column {column}: {c!r}, expected a finite number of at most "
                             f"{MAX_CELL:g} in size (blank: marker not seen)", file=path,
                             row=r + 1)
        out[r] = v
    return out


def read_wide(path: Path, header: Sequence[str], names: Sequence[str]
              ) -> tuple[NDArray[np.intp], Array, NDArray[np.intp], tuple[str, ...]]:
    """The long form of a wide marker table.

    Parameters
    ----------
    path : Path
    header : sequence of str
        Its header.
    names : sequence of str
        The model's markers (empty: the markers are named ``1..k``).

    Returns
    -------
    pose_row : ndarray of int, shape (N,)
        The file's data row (0-based) of each long row.
    xyz : ndarray, shape (N, 3)
        Marker positions.
    marker : ndarray of int, shape (N,)
        Index of each row's marker into the returned names.
    marker_names : tuple of str
    """
    k = marker_count(header, path)
    if names and k > len(names):
        raise InputError(f"{k} markers (x1..z{k}), the model declares {len(names)} "
                         f"({', '.join(names)}): wide marker i is the model's i-th marker",
                         file=path)
    cols = [f"{a}{i}" for i in range(1, k + 1) for a in "xyz"]
    text = read_columns(path, cols)
    P = np.stack([np.column_stack([_values(text[f"{a}{i}"], f"{a}{i}", path) for a in "xyz"])
                  for i in range(1, k + 1)], axis=1)  # (rows, k, 3)
    blank = np.isnan(P)
    partial = blank.any(axis=2) & ~blank.all(axis=2)
    if partial.any():
        r, i = (int(v) for v in np.argwhere(partial)[0])
        gone = [f"{a}{i + 1}" for a, b in zip("xyz", blank[r, i], strict=True) if b]
        given = [f"{a}{i + 1}" for a, b in zip("xyz", blank[r, i], strict=True) if not b]
        raise InputError(f"column {', '.join(gone)}: blank where {', '.join(given)} "
                         f"{'is' if len(given) == 1 else 'are'} given: a marker not seen "
                         "leaves all three blank", file=path, row=r + 1)
    seen = ~blank.all(axis=2)  # (rows, k), pose-major below
    rows, markers = np.nonzero(seen)
    if not rows.size:
        raise InputError(f"no marker position on any row: expected x1..z{k} numbers",
                         file=path)
    out_names = tuple(names[:k]) if names else tuple(str(i) for i in range(1, k + 1))
    return rows.astype(np.intp), P[rows, markers], markers.astype(np.intp), out_names
