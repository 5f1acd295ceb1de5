"""CSV tables: the C-speed reader gives the values and the error messages (file, row,
column) of a cell-by-cell reader, in small files and across the blocks of big ones; the
bulk writer round-trips every float exactly."""

import csv

import numpy as np
import pytest

import kinecal.io.csvtable as csvtable
from kinecal.errors import InputError
from kinecal.io.csvtable import MAX_CELL, read_table, write_table


def reference_read(path, required, optional=(), min_rows=1):
    """The cell-by-cell reader kinecal had before the C-speed one (same contract)."""
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.reader(fh))
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise InputError(f"empty file; expected a header with {', '.join(required)}", file=path)
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)}; expected {', '.join(required)} "
            f"(found {', '.join(header) or 'nothing'})", file=path)
    wanted = list(required) + [c for c in optional if c in header]
    cols = [header.index(c) for c in wanted]
    data = np.empty((len(rows) - 1, len(wanted)))
    for r, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields, expected {len(header)} as in the header",
                             file=path, row=r)
        for k, c in enumerate(cols):
            cell = row[c].strip()
            try:
                value = float(cell)
            except ValueError:
                raise InputError(f"column {wanted[k]}: {cell!r} is not a number", file=path,
                                 row=r) from None
            if not np.isfinite(value):
                raise InputError(f"column {wanted[k]}: {cell!r}, expected a finite number",
                                 file=path, row=r)
            if abs(value) > MAX_CELL:
                raise InputError(f"column {wanted[k]}: {cell!r}, expected a number of at most "
                                 f"{MAX_CELL:g} in size (no length, angle or weight is that "
                                 "large; check the exponent)", file=path, row=r)
            data[r - 1, k] = value
    if data.shape[0] < min_rows:
        raise InputError(f"{data.shape[0]} data rows, expected at least {min_rows}", file=path)
    return {name: data[:, k] for k, name in enumerate(wanted)}


def _outcome(fn, path, *args):
    try:
        return "ok", {k: v.tolist() for k, v in fn(path, *args).items()}
    except InputError as exc:
        return "error", exc.one_line()


HEADER = "a,b,c,w"
MUTATIONS = {
    "clean": lambda lines: lines,
    "text cell": lambda lines: _set(lines, 37, 1, "x1"),
    "empty cell": lambda lines: _set(lines, 80, 0, ""),
    "nan": lambda lines: _set(lines, 12, 2, "NaN"),
    "inf": lambda lines: _set(lines, 99, 1, "-inf"),
    "overflow": lambda lines: _set(lines, 64, 0, "1e999"),
    "huge": lambda lines: _set(lines, 70, 1, "1e308"),  # finite, beyond any length
    "too many fields": lambda lines: lines[:50] + [lines[50] + ",7"] + lines[51:],
    "too few fields": lambda lines: lines[:70] + ["1,2"] + lines[71:],
    "blank lines": lambda lines: lines[:5] + ["", "   ", " , , , "] + lines[5:],
    "python-only float": lambda lines: _set(lines, 3, 1, "1_000"),
    "quoted and spaced": lambda lines: _set(_set(lines, 4, 0, '"2.5"'), 9, 2, " 7.25 "),
    "unwanted text column": lambda lines: _set(lines, 20, 3, "note"),
    "nan in unwanted column": lambda lines: _set(lines, 21, 3, "nan"),
    "two errors": lambda lines: _set(_set(lines, 90, 1, "y"), 30, 2, "inf"),
    "crlf": lambda lines: [ln + "\r" for ln in lines],
}


def _set(lines, row, col, text):
    out = list(lines)
    cells = out[row].split(",")
    cells[col] = text
    out[row] = ",".join(cells)
    return out


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of 16 lines in the checked pass: errors fall in the middle of a file."""
    monkeypatch.setattr(csvtable, "BLOCK_LINES", 16)


@pytest.mark.parametrize("mutation", list(MUTATIONS))
@pytest.mark.parametrize("blocks", ["default", "small"])
def test_same_values_and_messages_as_cell_by_cell_reading(mutation, blocks, tmp_path,
                                                          monkeypatch):
    if blocks == "small":
        monkeypatch.setattr(csvtable, "BLOCK_LINES", 16)
    rng = np.random.default_rng(0)
    lines = [",".join(repr(v) for v in row) for row in rng.normal(0, 100, (120, 4)).tolist()]
    path = tmp_path / "t.csv"
    text = "\ufeff" + HEADER + "\n" + "\n".join(MUTATIONS[mutation](lines)) + "\n"
    path.write_text(text, encoding="utf-8")
    for args in ((["c", "a"], ["w", "z"]), (["a", "b", "c"],)):
        got = _outcome(read_table, path, *args)
        assert got == _outcome(reference_read, path, *args)
    if mutation == "clean":
        assert got[0] == "ok"
    elif mutation in ("text cell", "nan", "too few fields", "two errors"):
        assert got[0] == "error" and "row " in got[1]


def test_big_file_reports_the_row_of_a_bad_cell_far_down(tmp_path):
    """Across several blocks of the checked pass: the row counts every data row before."""
    n = 3 * csvtable.BLOCK_LINES + 100
    rng = np.random.default_rng(1)
    data = rng.uniform(-1000, 1000, (n, 3))
    path = tmp_path / "big.csv"
    write_table(path, {"x": data[:, 0], "y": data[:, 1], "z": data[:, 2]})
    back = read_table(path, ["x", "y", "z"])
    np.testing.assert_array_equal(np.column_stack([back[c] for c in "xyz"]), data)
    lines = path.read_text().splitlines()
    bad = n - 7  # data row (1-based) of the bad cell
    lines[bad] = lines[bad].split(",")[0] + ",oops," + lines[bad].split(",")[2]
    lines.insert(10, "")  # a blank line is not a data row
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_table(path, ["x", "y", "z"])
    assert err.value.one_line() == InputError(
        "column y: 'oops' is not a number", file=path, row=bad).one_line()
    assert f"row {bad}" in err.value.one_line()


def test_header_only_and_empty_files(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text("\n\nx,y\n\n")
    assert _outcome(read_table, path, ["x"], (), 0) == ("ok", {"x": []})
    assert _outcome(read_table, path, ["x"]) == _outcome(reference_read, path, ["x"])
    path.write_text("  \n")
    assert _outcome(read_table, path, ["x"]) == _outcome(reference_read, path, ["x"])
    with pytest.raises(InputError, match="file not found"):
        read_table(tmp_path / "none.csv", ["x"])


def test_writer_round_trips_every_float(tmp_path):
    v = np.array([0.1, 1 / 3, -0.0, 5e-324, 1e-300, 1.7976931348623157e308, 123456789.123,
                  -2.5e-7, 1e16, 2.0 ** 53 + 2])
    rng = np.random.default_rng(2)
    cols = {"v": np.resize(v, 5000), "r": rng.normal(0, 1e3, 5000)}
    path = tmp_path / "w.csv"
    write_table(path, cols)
    back = read_table(path, ["v", "r"], max_abs=np.inf)
    for k in cols:
        np.testing.assert_array_equal(back[k], cols[k])
        assert np.array_equal(np.signbit(back[k]), np.signbit(cols[k]))
    with pytest.raises(InputError, match=r"row 6: column v: '1.7976931348623157e\+308', "
                       "expected a number of at most 1e\\+12"):
        read_table(path, ["v", "r"])  # the default refuses what no calibration file holds
    first = path.read_text().splitlines()[1]
    assert first == ",".join([repr(0.1), repr(float(cols["r"][0]))])
    write_table(path, {"only": np.arange(3.0)})
    assert path.read_text() == "only\n0.0\n1.0\n2.0\n"
