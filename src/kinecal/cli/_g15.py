"""``%.15g`` text of float arrays, computed in numpy: the same characters as Python's
``"%.15g" % v`` for every value, several times faster for long columns.

Python formats a float in about 0.3 us, which made the formatting of ``kinecal stewart
fk`` as costly as a third of its solve. Here, per value ``v`` (``|v|`` in ``[1e-200,
1e15)``; others are formatted by Python): the decimal exponent ``X`` from ``log10``
(corrected when the digits say it was one off), the 15 significant digits
``n = round(|v| 10^(14 - X))`` rounded half to even on the exact binary value as
Python's correctly rounded conversion does: the product is taken exactly as the sum of two
doubles (Dekker's product, with ``10^k`` exact for ``k <= 22``, else as a pair of doubles
with an error below 1e-16 of the digit; a value whose product lies within 1e-12 of a
tie is formatted by Python). Then the ``%g`` layout: fixed
notation for ``-4 <= X < 15`` (trailing zeros and a bare point dropped), otherwise
``d.ddde+XX``. tests/cli/test_g15.py checks it against Python on many random and
edge-case values.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WIDTH", "g15_cells", "join_rows"]

#: characters of one value's cells: sign, "0.000", 15 digits and a point, "e+XXX"
WIDTH = 27
_MAXK = 216
_P10_HI = np.array([float(10**k) for k in range(_MAXK + 1)])
_P10_LO = np.array([float(10**k - int(h)) for k, h in enumerate(_P10_HI.tolist())])
_SPLIT = 134217729.0  # 2^27 + 1
_SLOTS = np.arange(16, dtype=np.int8)
#: Python's format, for the values not taken here
_G15 = "%.15g"


def _split(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = _SPLIT * v
    hi = t - (t - v)
    return hi, v - hi


def _round15(a: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``round(a 10^(14 - X))`` half to even on the exact value, and whether the answer
    is sure (False: within 1e-12 of a tie whose side the pair of doubles cannot tell)."""
    k = 14 - X  # in [0, _MAXK]: X clipped to the plain values' range
    p, plo = _P10_HI[k], _P10_LO[k]
    s = a * p
    ah, al = _split(a)
    ph, pl = _split(p)
    e = ((ah * ph - s) + ah * pl + al * ph) + al * pl + a * plo  # s + e = a 10^k (to 1e-30)
    n = np.rint(s)
    t = s - n  # exact, |t| <= 0.5
    exact = plo == 0.0  # 10^k a double: s + e is the product itself
    # exact: only a tie of s needs e, whose sign is exact; otherwise |t + e| stays below
    # 1/2 (t is a multiple of ulp(s), |e| at most half of it)
    away = (np.abs(t) == 0.5) & (np.sign(e) == np.sign(t))
    # 10^k a pair of doubles: e holds up to an ulp, t + e may pass 1/2 (sure when not
    # within 1e-12 of it: the pair's error is below 1e-16)
    r = t + e
    move = np.where(exact, np.where(away, np.sign(t), 0.0),
                    np.where(r > 0.5, 1.0, np.where(r < -0.5, -1.0, 0.0)))
    sure = exact | (np.abs(np.abs(r) - 0.5) > 1e-12)
    n = n + move
    return n, sure


def _digits(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exponent ``X``, 15 digits (as int64) of the plain values of `x` and the mask of
    the plain values (the others are formatted by Python)."""
    a = np.abs(x)
    plain = np.isfinite(a) & (a >= 1e-200) & (a < 1e15)
    a = np.where(plain, a, 1.0)
    X = np.clip(np.floor(np.log10(a)), -201, 14).astype(np.int64)  # 1e-200 <= a < 1e15
    n = np.zeros(a.shape)
    todo = np.ones(a.shape, dtype=bool)
    for _ in range(3):  # log10 may be one off near a power of ten
        idx = np.flatnonzero(todo)
        if idx.size == 0:
            break
        ni, sure = _round15(a[idx], X[idx])
        plain[idx[~sure]] = False
        low, high = ni < 1e14, ni > 1e15
        carry = ni == 1e15  # rounded up to the next power of ten
        ni = np.where(carry, 1e14, ni)
        X[idx] = np.clip(X[idx] + np.where(low, -1, 0) + np.where(high, 1, 0), -201, 14) \
            + carry
        n[idx] = ni
        todo[:] = False
        todo[idx[low | high]] = True
    plain &= ~todo
    return X, n.astype(np.int64), plain, a


def g15_cells(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Characters ``(N, WIDTH)`` (uint8) and the mask of those kept, whose kept
    characters of row ``i`` are ``"%.15g" % x[i]``."""
    x = np.asarray(x, dtype=float).ravel()
    N = x.size
    X, n, plain, _ = _digits(x)
    d = np.empty((N, 15), dtype=np.uint8)
    for j in range(14, -1, -1):  # a scalar divisor: numpy's fast integer division
        q = n // 10
        d[:, j] = n - q * 10
        n = q
    m = (15 - np.argmax(d[:, ::-1] != 0, axis=1)).astype(np.int8)  # no trailing zeros
    d += ord("0")
    fixed = (X >= -4) & (X < 15)
    X8 = X.astype(np.int16)
    # digits written: the integer part at least (fixed, X >= 0)
    nd = np.where(fixed & (X8 >= 0), np.maximum(m, X8 + 1), m).astype(np.int8)
    p = np.where(fixed, np.where(X8 >= 0, X8 + 1, 16), 1).astype(np.int8)  # point's slot
    chars = np.empty((N, WIDTH), dtype=np.uint8)
    keep = np.empty((N, WIDTH), dtype=bool)
    chars[:, 0] = ord("-")
    keep[:, 0] = np.signbit(x)
    chars[:, 1:6] = np.frombuffer(b"0.000", dtype=np.uint8)
    lead = np.where(fixed & (X8 < 0), 1 - X8, 0).astype(np.int8)  # "0." and zeros
    np.less(_SLOTS[:5], lead[:, None], out=keep[:, 1:6])
    body, kb = chars[:, 6:22], keep[:, 6:22]
    after = _SLOTS > p[:, None]  # body slot s holds digit s before the point, s - 1 after
    body[:, :15] = d
    body[:, 15] = ord("0")
    np.copyto(body[:, 1:], d, where=after[:, 1:])
    # kept: digit s - after < nd; at the point (s = p) that reads p < nd, i.e. a digit
    # follows the point
    np.less(_SLOTS - after, nd[:, None], out=kb)
    rows = np.flatnonzero(p < 16)
    body[rows, p[rows]] = ord(".")
    ex = ~fixed
    ax = np.abs(X8)
    chars[:, 22] = ord("e")
    chars[:, 23] = np.where(X < 0, ord("-"), ord("+"))
    chars[:, 24] = ax // 100 % 10 + ord("0")
    chars[:, 25] = ax // 10 % 10 + ord("0")
    chars[:, 26] = ax % 10 + ord("0")
    keep[:, 22:24] = ex[:, None]
    keep[:, 24] = ex & (ax >= 100)
    keep[:, 25:27] = ex[:, None]
    for i in np.flatnonzero(~plain).tolist():  # zeros, inf, nan, huge, tiny, near ties
        text = np.frombuffer((_G15 % x[i]).encode("ascii"), dtype=np.uint8)
        chars[i, :] = 0
        chars[i, :text.size] = text
        keep[i, :] = False
        keep[i, :text.size] = True
    return chars, keep


def join_rows(cells: list[tuple[np.ndarray, np.ndarray]]) -> str:
    """CSV lines from the cells of each column (``g15_cells``, or a constant text as
    ``(N, len)`` characters all kept): columns joined by commas, rows ended by newlines."""
    N = cells[0][0].shape[0]
    comma = (np.full((N, 1), ord(","), dtype=np.uint8), np.ones((N, 1), dtype=bool))
    newline = (np.full((N, 1), ord("\n"), dtype=np.uint8), np.ones((N, 1), dtype=bool))
    parts = []
    for k, c in enumerate(cells):
        parts.extend([comma, c] if k else [c])
    parts.append(newline)
    chars = np.concatenate([c for c, _ in parts], axis=1)
    keep = np.concatenate([k for _, k in parts], axis=1)
    return chars[keep].tobytes().decode("utf-8")
