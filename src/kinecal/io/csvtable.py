"""Strict numeric CSV tables: named columns, every cell a finite number, row numbers in errors.

Every cell read must be a finite number of at most `MAX_CELL` in size, and every column
read must appear once in the header.

Reading runs at C speed: numpy's `loadtxt` parser reads the whole file in one call and the
checks (field count, finite values) are vectorised; a 200 MB table of 2.5 million rows
reads in a few seconds and about twice its binary size in memory. Only when that fast
pass fails (a bad cell, a wrong field count, NaN, or a cell that Python's ``float``
accepts but numpy's parser does not, such as ``1_000`` or a blank line of spaces) is the
file read again in blocks of lines: each block first by the C parser, and a block that
fails cell by cell, which finds the first bad cell and reports its file, data row and
column exactly as a cell-by-cell reader would.

A table may hold text columns beside the numeric ones (a marker name per row):
`read_table` ignores them unless asked for, and `read_column` returns one of them.

Writing formats the floats in bulk (shortest round-trip representation, like ``repr``)
a block of rows at a time.
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Iterable, Iterator, Sequence
from itertools import islice
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import atomic_open
from kinecal.errors import InputError

__all__ = ["MAX_CELL", "check_separator", "read_blocks", "read_column", "read_columns",
           "read_table", "write_table"]

#: lines per block of the checked (second) reading pass
BLOCK_LINES = 65536
#: rows per block of the writer
WRITE_ROWS = 16384
#: largest magnitude of a cell: beyond any length (1000 km in mm), angle or weight a
#: calibration file holds; ``1e308`` in one cell overflowed the fit's squares (SVD failure)
MAX_CELL = 1e12


def _resolve_columns(path: Path, required: Sequence[str], optional: Sequence[str]
                     ) -> tuple[list[str], int, list[str], list[int]]:
    """The header, the lines before the data, the columns read (required, then the optional
    ones present) and their indices; missing or repeated columns refused."""
    header, skip = _header(path, required)
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)}; expected {', '.join(required)} "
            f"(found {', '.join(header) or 'nothing'})", file=path)
    wanted = list(required) + [c for c in optional if c in header]
    twice = next((c for c in wanted if header.count(c) > 1), None)
    if twice is not None:
        where = [k + 1 for k, h in enumerate(header) if h == twice]
        raise InputError(f"column {twice} appears {len(where)} times (columns "
                         f"{', '.join(map(str, where))}): expected each column once",
                         file=path)
    return header, skip, wanted, [header.index(c) for c in wanted]


def read_table(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    min_rows: int = 1,
    max_abs: float = MAX_CELL,
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
    max_abs : float
        Largest magnitude of a cell (default `MAX_CELL`).

    Returns
    -------
    dict of str to ndarray, shape (N,)
        One array per column found (other columns are ignored).

    Raises
    ------
    InputError
        Unreadable file, missing or repeated columns, a non-numeric / NaN / infinite /
        too large cell (with its 1-based data row and column), or fewer than `min_rows`
        rows.
    """
    path = Path(path)
    header, skip, wanted, cols = _resolve_columns(path, required, optional)
    data = _read_fast(path, skip, len(header), cols, max_abs)
    if data is None:
        data = _read_checked(path, skip, header, wanted, cols, max_abs)
    if data.shape[0] < min_rows:
        raise InputError(f"{data.shape[0]} data rows, expected at least {min_rows}", file=path)
    return {name: data[:, k] for k, name in enumerate(wanted)}


def _open(path: Path):
    try:
        return open(path, newline="", encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None


def _header(path: Path, required: Sequence[str]) -> tuple[list[str], int]:
    """The header cells and the number of lines up to and including the header line."""
    with _open(path) as fh:
        try:
            for n, line in enumerate(fh, start=1):
                row = next(csv.reader([line]), [])
                if row and any(c.strip() for c in row):
                    check_separator(row, path)
                    return [h.strip() for h in row], n
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise InputError(f"cannot read CSV: {exc}", file=path) from None
    raise InputError(f"empty file; expected a header with {', '.join(required)}", file=path)


#: separators of CSV exports that are not commas (spreadsheets in locales with decimal
#: commas write ";"), by the name a message gives them
_SEPARATORS = {";": "semicolons (;)", "\t": "tabs", "|": "vertical bars (|)"}


def check_separator(header: Sequence[str], path: str | Path | None = None) -> None:
    """Refuse a header that did not split at commas because another separator was used.

    A one-cell header holding ``;``, tabs or ``|`` between names (``q1;q2;...;z``, what a
    spreadsheet in a locale with decimal commas exports) would otherwise be reported as
    missing every column. Raises `InputError` naming the separator seen.
    """
    cells = [c for c in header if c.strip()]
    if len(cells) != 1:
        return
    for sep, name in _SEPARATORS.items():
        if sep in cells[0] and len([p for p in cells[0].split(sep) if p.strip()]) > 1:
            raise InputError(f"the header is one column separated by {name}, not commas: "
                             "kinecal reads comma-separated CSV with decimal points; save the "
                             "file comma-separated", file=path)


def _parse(lines, skip: int = 0, usecols: list[int] | None = None) -> NDArray[np.float64]:
    """numpy's C parser on a file or a list of lines; ValueError (or another exception)
    on anything it does not read."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "input contained no data"
        return np.loadtxt(lines, dtype=float, delimiter=",", comments=None, quotechar='"',
                          skiprows=skip, ndmin=2, encoding="utf-8", usecols=usecols)


def _sane(a: NDArray[np.float64], limit: float) -> bool:
    """Every value finite and within `limit` in size."""
    return bool(np.isfinite(a).all() and (np.abs(a) <= limit).all())


def _accept(a: NDArray[np.float64], n_fields: int, cols: list[int], limit: float) -> bool:
    """Every row has the header's field count and finite values within `limit` in the
    wanted columns."""
    if a.shape[0] == 0:
        return True
    if a.shape[1] != n_fields:
        return False
    if len(set(cols)) == n_fields:
        return _sane(a, limit)
    return all(_sane(a[:, c], limit) for c in cols)


def _columns(a: NDArray[np.float64], cols: list[int]) -> NDArray[np.float64]:
    """The wanted columns of a parsed block (no copy when they are all, in order)."""
    if a.shape[0] == 0:
        return np.empty((0, len(cols)))
    return a if cols == list(range(a.shape[1])) else a[:, cols]


def _read_fast(path: Path, skip: int, n_fields: int, cols: list[int], limit: float
               ) -> NDArray[np.float64] | None:
    """The wanted columns ``(N, k)`` by one C-parser pass over the file, or None when the
    file needs the checked pass (any doubt at all)."""
    try:
        a = _parse(path, skip)
    except Exception:  # any failure: the checked pass explains it
        return None
    return _columns(a, cols) if _accept(a, n_fields, cols, limit) else None


def _read_checked(path: Path, skip: int, header: list[str], wanted: list[str],
                  cols: list[int], limit: float) -> NDArray[np.float64]:
    """The wanted columns ``(N, k)``, block by block; a block the C parser does not
    accept is read cell by cell, which raises `InputError` at the first bad cell."""
    blocks = [b for _, _, b in _numeric_blocks(path, skip, header, wanted, cols, limit,
                                               BLOCK_LINES)]
    return np.concatenate(blocks) if blocks else np.empty((0, len(wanted)))


def _numeric_blocks(path: Path, skip: int, header: list[str], wanted: list[str],
                    cols: list[int], limit: float, rows: int
                    ) -> Iterator[tuple[int, list[str], NDArray[np.float64]]]:
    """``(first, lines, values)`` per block of `rows` lines after the header: the data
    rows before the block, its lines and its wanted columns ``(n, k)`` (by the C parser,
    or cell by cell where it refuses the block, raising `InputError` at the first bad
    cell)."""
    row = 0
    with _open(path) as fh:
        try:
            for _ in range(skip):
                next(fh)
            while lines := list(islice(fh, rows)):
                b = _block(lines, len(header), cols, limit)
                if b is None:  # cell by cell: raises at the first bad cell
                    b = _cells(lines, row, header, wanted, cols, path, limit)
                yield row, lines, b
                row += b.shape[0]
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise InputError(f"cannot read CSV: {exc}", file=path) from None


def _block(lines: list[str], n_fields: int, cols: list[int], limit: float
           ) -> NDArray[np.float64] | None:
    """The wanted columns of a block of lines by the C parser, or None.

    All columns first (the parser then checks every row's field count); when that fails
    and the header has columns that are not wanted (text, say), only the wanted ones,
    after counting every line's fields (no quotes, whose commas would not separate).
    """
    try:
        a = _parse(lines)
        if _accept(a, n_fields, cols, limit):
            return _columns(a, cols)
    except Exception:  # try the wanted columns alone, or the cell-by-cell reading
        pass
    if len(set(cols)) == n_fields or any('"' in line for line in lines):
        return None
    if any(line.count(",") != n_fields - 1 for line in lines if line.strip()):
        return None
    try:
        a = _parse(lines, usecols=cols)
    except Exception:  # the cell-by-cell reading explains it
        return None
    return a if a.shape[0] and _sane(a, limit) else None


def _cells(lines: Iterable[str], row: int, header: list[str], wanted: list[str],
           cols: list[int], path: Path, limit: float) -> NDArray[np.float64]:
    """Cell-by-cell reading of a block: blank rows skipped, Python's ``float`` per cell."""
    out = []
    for fields in csv.reader(lines):
        if not fields or not any(c.strip() for c in fields):
            continue
        row += 1
        if len(fields) != len(header):
            raise InputError(
                f"{len(fields)} fields, expected {len(header)} as in the header", file=path,
                row=row)
        values = []
        for name, c in zip(wanted, cols, strict=True):
            cell = fields[c].strip()
            try:
                value = float(cell)
            except ValueError:
                raise InputError(f"column {name}: {cell!r} is not a number", file=path,
                                 row=row) from None
            if not np.isfinite(value):
                raise InputError(f"column {name}: {cell!r}, expected a finite number",
                                 file=path, row=row)
            if abs(value) > limit:
                raise InputError(f"column {name}: {cell!r}, expected a number of at most "
                                 f"{limit:g} in size (no length, angle or weight is "
                                 "that large; check the exponent)", file=path, row=row)
            values.append(value)
        out.append(values)
    return np.array(out, dtype=float).reshape(-1, len(wanted))


def read_blocks(path: str | Path, required: Sequence[str], optional: Sequence[str] = (),
                rows: int = BLOCK_LINES, max_abs: float = MAX_CELL
                ) -> Iterator[tuple[int, list[list[str]], dict[str, NDArray[np.float64]]]]:
    """`read_table` a block of rows at a time, with the rows' cells as text.

    For files too long to hold as Python strings (a program of a million lines): memory
    stays that of one block. Checks and error messages are `read_table`'s (rows numbered
    in the whole file).

    Parameters
    ----------
    path : str or Path
    required, optional : sequence of str
        As in `read_table`.
    rows : int
        Lines per block (blank lines count, but are not returned).
    max_abs : float
        Largest magnitude of a cell (default `MAX_CELL`).

    Yields
    ------
    first : int
        Data rows before the block (0-based index of its first row).
    cells : list of list of str
        The block's non-blank rows, every cell stripped.
    columns : dict of str to ndarray, shape (n,)
        The block's numeric columns.
    """
    path = Path(path)
    header, skip, wanted, cols = _resolve_columns(path, required, optional)
    for row, lines, b in _numeric_blocks(path, skip, header, wanted, cols, max_abs, rows):
        try:
            cells = [[c.strip() for c in r] for r in csv.reader(lines)
                     if r and any(c.strip() for c in r)]
        except csv.Error as exc:
            raise InputError(f"cannot read CSV: {exc}", file=path) from None
        yield row, cells, {name: b[:, k] for k, name in enumerate(wanted)}


def read_column(path: str | Path, name: str) -> list[str] | None:
    """The cells of text column `name` (stripped, one per non-blank data row, as
    `read_table` counts rows), or None when the header has no such column."""
    return read_columns(path, [name]).get(name)


def read_columns(path: str | Path, names: Sequence[str]) -> dict[str, list[str]]:
    """The cells of the text columns `names` the header has (stripped, one per non-blank
    data row, as `read_table` counts rows), in one pass over the file; columns the header
    lacks are left out."""
    path = Path(path)
    try:
        header, skip = _header(path, list(names))
    except InputError as exc:
        if exc.message.startswith("empty file"):
            return {}
        raise
    found = [n for n in names if n in header]
    if not found:
        return {}
    ks = [header.index(n) for n in found]
    out: dict[str, list[str]] = {n: [] for n in found}
    cols = list(out.values())
    with _open(path) as fh:
        try:
            for _ in range(skip):
                next(fh)
            for r, row in enumerate((f for f in csv.reader(fh)
                                     if f and any(c.strip() for c in f)), start=1):
                if len(row) != len(header):
                    raise InputError(f"{len(row)} fields, expected {len(header)} as in the "
                                     "header", file=path, row=r)
                for col, k in zip(cols, ks, strict=True):
                    col.append(row[k].strip())
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise InputError(f"cannot read CSV: {exc}", file=path) from None
    return out


def _quoted(cell: str) -> str:
    """A text cell as CSV writes it: in double quotes (inner ones doubled) when it holds a
    space, a comma or a quote (a URDF joint named ``joint 1``), else as it is."""
    if any(c in cell for c in ' ,"'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


def write_table(path: str | Path, columns: dict[str, NDArray]) -> None:
    """Write equal-length columns as CSV with a header, atomically: numbers with full float
    precision, text (header names, text columns) quoted where it holds a space, a comma
    or a quote.

    Each number is written in its shortest form that reads back to the same float (as
    ``repr``), formatted in bulk a block of rows at a time.
    """
    names = list(columns)
    arrays = [np.asarray(columns[n]) for n in names]
    text = [a.dtype.kind in "USO" for a in arrays]
    with atomic_open(path, "w") as fh:
        fh.write(",".join(map(_quoted, names)) + "\n")
        if not any(text):
            data = np.column_stack([a.astype(float) for a in arrays])
            for s in range(0, data.shape[0], WRITE_ROWS):
                block = data[s:s + WRITE_ROWS].tolist()
                # the list's repr formats every float like repr() in C, in one call
                fh.write(str(block)[2:-2].replace("], [", "\n").replace(", ", ",") + "\n")
            return
        cells = [[_quoted(str(v)) for v in a] if t else [repr(float(v)) for v in a.astype(float)]
                 for a, t in zip(arrays, text, strict=True)]
        for row in zip(*cells, strict=True):
            fh.write(",".join(row) + "\n")
