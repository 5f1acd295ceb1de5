"""The numpy ``%.15g`` formatter (`kinecal.cli._g15`) gives Python's characters for every
value: random values over the whole range, values at and near ties of the 15th digit,
powers of ten and their neighbours, subnormals, zeros, inf and nan."""

import numpy as np

from kinecal.cli._csv_out import format_rows
from kinecal.cli._g15 import g15_cells, join_rows

G15 = "%.15g"
ROW = G15 + ",true," + G15 + "," + G15 + "\n"


def _python(x):
    return [G15 % v for v in x.tolist()]


def _mine(x):
    chars, keep = g15_cells(x)
    return [row[k].tobytes().decode() for row, k in zip(chars, keep, strict=True)]


def _check(x):
    x = np.asarray(x, dtype=float)
    mine, theirs = _mine(x), _python(x)
    bad = [(v, a, b) for v, a, b in zip(x.tolist(), mine, theirs, strict=True) if a != b]
    assert not bad, bad[:5]


def test_random_values_over_the_range():
    rng = np.random.default_rng(0)
    _check(rng.standard_normal(20000) * 10.0 ** rng.integers(-20, 20, 20000))
    _check(rng.uniform(-1000, 1000, 20000))
    bits = rng.integers(0, 2**63, 20000, dtype=np.uint64) | (rng.integers(0, 2, 20000).astype(
        np.uint64) << np.uint64(63))
    _check(bits.view(np.float64))  # any double, nan and inf included


def test_ties_and_near_ties_of_the_fifteenth_digit():
    rng = np.random.default_rng(1)
    # decimal numbers of 16 significant digits ending in 5: the exact ties are the few
    # that are doubles; the others lie within an ulp of a tie
    mant = rng.integers(10**14, 10**15, 20000) * 10 + 5
    exps = rng.integers(-30, 30, 20000)
    vals = np.array([float(f"{m}e{e}") for m, e in zip(mant.tolist(), exps.tolist(),
                                                        strict=True)])
    _check(vals)
    _check(np.nextafter(vals, np.inf))
    _check(np.nextafter(vals, -np.inf))
    exact = [0.5, 1.5, 2.5, 0.125, 1e15 - 0.5, 2**-20, 2**49 + 0.5, 123456789012345.5,
             12345678901234.25, 1.00000000000000050, 0.3, 0.1, 2 / 3]
    _check(exact + [-v for v in exact])


def test_powers_of_ten_and_their_neighbours():
    p = np.array([10.0**k for k in range(-310, 309)])
    p = p[np.isfinite(p)]
    with np.errstate(over="ignore"):
        near = [p * 9.999999999999999, p * 0.99999999999999994, p * 1.0000000000000002]
    for v in (p, np.nextafter(p, 0), np.nextafter(p, np.inf), *near):
        _check(v)
        _check(-v)


def test_special_values():
    _check([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 2.2250738585072014e-308,
            1.7976931348623157e308, 1e-200, 9.99999999999e-201, 1e15, 999999999999999.9,
            1e-5, 1e-4, 0.0001, 0.00009999999999999999, 1e14, 123456789012345.0])


def test_rows_are_format_rows():
    """Long blocks go through the numpy path of `format_rows`; both give the same text."""
    rng = np.random.default_rng(5)
    cols = [rng.standard_normal(3000) * 10.0 ** rng.integers(-8, 8, 3000) for _ in range(3)]
    cols[1][::7] = 0.0
    fast = format_rows([cols[0], ["true"] * 3000, cols[1], cols[2]])
    slow = "".join(ROW % r for r in zip(*[c.tolist() for c in cols], strict=True))
    assert fast == slow
    mixed = [cols[0][:5], ["a", "b", "c", "d", "e"]]  # text that varies: Python's path
    assert format_rows(mixed) == "".join(G15 % v + f",{t}\n" for v, t in zip(
        cols[0][:5].tolist(), mixed[1], strict=True))


def test_cells_join_like_python():
    rng = np.random.default_rng(2)
    cols = [rng.standard_normal(500) * 300, rng.standard_normal(500) * 1e-12]
    text = np.frombuffer(b"true", dtype=np.uint8)
    cells = [g15_cells(cols[0]), (np.tile(text, (500, 1)), np.ones((500, 4), dtype=bool)),
             g15_cells(cols[1])]
    assert join_rows(cells) == format_rows([cols[0], ["true"] * 500, cols[1]])
