"""Strict numeric CSV tables: named columns, every cell a finite number, row numbers in errors."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import atomic_open
from kinecal.errors import InputError

__all__ = ["read_column", "read_table", "write_table"]


def read_table(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    min_rows: int = 1,
) -> dict[str, NDArray[np.float64]]:
    """Read the named numeric columns of a CSV file with a header line.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    required : sequence of str
        Columns that must be present.
    optional : sequence of str
        Columns read when present.
    min_rows : int
        Fewest data rows accepted.

    Returns
    -------
    dict of str to ndarray, shape (N,)
        One array per column found (other columns are ignored).

    Raises
    ------
    InputError
        Unreadable file, missing columns, a non-numeric / NaN / infinite cell (with its
        1-based data row and column), or fewer than `min_rows` rows.
    """
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise InputError(f"empty file; expected a header with {', '.join(required)}", file=path)
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)}; expected {', '.join(required)} "
            f"(found {', '.join(header) or 'nothing'})",
            file=path,
        )
    wanted = list(required) + [c for c in optional if c in header]
    cols = [header.index(c) for c in wanted]
    data = np.empty((len(rows) - 1, len(wanted)))
    for r, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise InputError(
                f"{len(row)} fields, expected {len(header)} as in the header", file=path, row=r
            )
        for k, c in enumerate(cols):
            cell = row[c].strip()
            try:
                value = float(cell)
            except ValueError:
                raise InputError(
                    f"column {wanted[k]}: {cell!r} is not a number", file=path, row=r
                ) from None
            if not np.isfinite(value):
                raise InputError(
                    f"column {wanted[k]}: {cell!r}, expected a finite number", file=path, row=r
                )
            data[r - 1, k] = value
    if data.shape[0] < min_rows:
        raise InputError(f"{data.shape[0]} data rows, expected at least {min_rows}", file=path)
    return {name: data[:, k] for k, name in enumerate(wanted)}


def read_column(path: str | Path, name: str) -> list[str] | None:
    """The cells of text column `name` (stripped, one per non-blank data row, as
    `read_table` counts rows), or None when the header has no such column."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    header = [h.strip() for h in rows[0]] if rows else []
    if name not in header:
        return None
    k = header.index(name)
    out = []
    for r, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields, expected {len(header)} as in the header",
                             file=path, row=r)
        out.append(row[k].strip())
    return out


def write_table(path: str | Path, columns: dict[str, NDArray]) -> None:
    """Write equal-length columns as CSV with a header, atomically: numbers with full float
    precision, text columns (names without commas or quotes) as they are."""
    names = list(columns)
    cols = []
    for n in names:
        c = np.asarray(columns[n])
        cols.append([str(v) for v in c] if c.dtype.kind in "USO"
                    else [repr(float(v)) for v in c.astype(float)])
    with atomic_open(path, "w") as fh:
        fh.write(",".join(names) + "\n")
        for row in zip(*cols, strict=True):
            fh.write(",".join(row) + "\n")
