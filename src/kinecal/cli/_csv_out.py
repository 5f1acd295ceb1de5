"""CSV on stdout from columns of numbers: 15 significant digits (``%.15g``), one format
string per row, a block of rows at a time (the ``stewart`` commands' output)."""

from __future__ import annotations

import sys

import numpy as np

__all__ = ["format_rows", "write_columns", "write_csv"]


def write_csv(header: list[str], rows: list[list]) -> None:
    out = [",".join(header)]
    for row in rows:
        out.append(",".join(v if isinstance(v, str) else f"{v:.15g}" for v in row))
    sys.stdout.write("\n".join(out) + "\n")


def write_columns(header: list[str], columns: list) -> None:
    """CSV on stdout from columns (float arrays, or lists of text), 15 significant digits;
    one format string per row, written a block of rows at a time."""
    sys.stdout.write(",".join(header) + "\n")
    n = len(columns[0])
    for s in range(0, n, 16384):
        sys.stdout.write(format_rows([c[s:s + 16384] for c in columns]))


#: rows from which `format_rows` formats in numpy (`kinecal.cli._g15`)
NUMPY_ROWS = 256


def format_rows(columns: list) -> str:
    """The CSV lines of columns (float arrays, or lists of text), 15 significant digits.

    A long block whose text columns each repeat one text is formatted in numpy
    (`kinecal.cli._g15`: the same characters, about twice as fast)."""
    n = len(columns[0]) if columns else 0
    if n >= NUMPY_ROWS and all(not isinstance(c, list) or len(set(c)) == 1 for c in columns):
        from kinecal.cli._g15 import g15_cells, join_rows

        cells = []
        for c in columns:
            if isinstance(c, list):  # one text, every row
                text = np.frombuffer(str(c[0]).encode("utf-8"), dtype=np.uint8)
                cells.append((np.tile(text, (n, 1)), np.ones((n, text.size), dtype=bool)))
            else:
                cells.append(g15_cells(c))
        return join_rows(cells)
    fmt = ",".join("%s" if isinstance(c, list) else "%.15g" for c in columns)
    cells = [c if isinstance(c, list) else np.asarray(c, dtype=float).tolist() for c in columns]
    return "".join([fmt % r + "\n" for r in zip(*cells, strict=True)])
