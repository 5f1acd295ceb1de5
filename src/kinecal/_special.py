"""The chi-square and F distribution functions of `scipy.special`, imported on first use.

``import scipy.special`` costs 0.15-0.3 s (its array-API layer loads parts of numpy that
nothing else needs), more than a one-pose ``kinecal fk`` or a hand-eye calibration from
images takes in all. The tests that use these functions are the diagnostics' and the
outlier judgements'; a command that never reaches one of them no longer pays for the
import. Same names, arguments and results as `scipy.special` (which see).

The chi-square quantile of a whole number of degrees of freedom, the one the outlier
bounds ask for, needs no scipy at all: its survival function is a finite sum (Abramowitz
and Stegun 1964, 26.4.4 and 26.4.5),

    Q(x | 2k)     = exp(-x/2) sum_{i<k} (x/2)^i / i!
    Q(x | 2k + 1) = erfc(sqrt(x/2)) + exp(-x/2) sum_{i=1..k} (x/2)^(i-1/2) / Gamma(i+1/2),

solved for x by Newton's method on its logarithm (on ``1 - Q`` from its power series when
``p > 1/2``); it agrees with scipy's ``chdtri`` to 1e-13 relative (tests/test_special.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["chdtr", "chdtrc", "chdtri", "fdtri"]


def chdtri(v: Any, p: Any) -> Any:
    """Chi-square quantile exceeded with probability `p` (`v` degrees of freedom)."""
    vv, pp = np.broadcast_arrays(np.asarray(v, float), np.asarray(p, float))
    whole = vv.size and np.all((vv == np.round(vv)) & (vv >= 1) & (vv <= 1e5)) \
        and np.all((pp > 0) & (pp < 1))
    if not whole:
        from scipy.special import chdtri as f

        return f(v, p)
    pairs = {(int(a), float(b)) for a, b in zip(vv.ravel(), pp.ravel(), strict=True)}
    x = {key: _chi2_quantile(*key) for key in sorted(pairs)}
    out = np.array([x[int(a), float(b)] for a, b in zip(vv.ravel(), pp.ravel(), strict=True)])
    return out.reshape(vv.shape)[()] if vv.ndim else np.float64(out[0])


def _log_upper(v: int, x: float) -> float:
    """``log Q(x | v)``: the finite sums of the module docstring, summed from their largest
    term (no overflow for large `x` or `v`)."""
    y = 0.5 * x
    if y <= 0.0:
        return 0.0
    if v % 2 == 0:  # y^i / i!, i = 0 .. v/2 - 1
        s = np.arange(v // 2) + 0.0
        head = -np.inf
    else:  # y^s / Gamma(s + 1), s = i - 1/2, i = 1 .. (v - 1)/2
        s = np.arange(1, (v - 1) // 2 + 1) - 0.5
        e = math.erfc(math.sqrt(y))
        head = math.log(e) if e > 0.0 else -np.inf
    logs = s * math.log(y) - np.array([math.lgamma(k + 1.0) for k in s]) - y
    terms = np.append(logs, head)
    top = float(np.max(terms)) if terms.size else -np.inf
    if not np.isfinite(top):
        return -np.inf
    return top + math.log(float(np.sum(np.exp(terms - top))))


def _log_lower(v: int, x: float) -> float:
    """``log (1 - Q(x | v))`` by the series of the regularised lower incomplete gamma
    function, exact where ``Q`` is near 1 (small `x`)."""
    a, y = 0.5 * v, 0.5 * x
    if y <= 0.0:
        return -np.inf
    term, total, n = 1.0, 1.0, 0
    while term > 1e-17 * total and n < 100000:
        n += 1
        term *= y / (a + n)
        total += term
    return a * math.log(y) - y - math.lgamma(a + 1.0) + math.log(total)


def _chi2_quantile(v: int, p: float) -> float:
    """x with ``Q(x | v) = p``: Newton's method on ``log Q`` (``log (1 - Q)`` for p > 1/2),
    kept inside a bracket that halves when a step leaves it."""
    upper = p <= 0.5
    target = math.log(p) if upper else math.log1p(-p)
    f = (lambda x: _log_upper(v, x) - target) if upper else (lambda x: _log_lower(v, x) - target)
    lo, hi = 0.0, float(max(v, 1))
    while (f(hi) > 0) == upper:  # Q falls with x: move hi past the root
        lo, hi = hi, 2.0 * hi
    x = 0.5 * (lo + hi) if lo > 0 else hi * 0.5
    a = 0.5 * v
    for _ in range(200):
        fx = f(x)
        if fx == 0.0:
            return x
        if (fx > 0) == upper:
            lo = x
        else:
            hi = x
        # d log Q / dx = -pdf / Q, d log(1 - Q) / dx = pdf / (1 - Q); log pdf of chi-square
        log_pdf = (a - 1.0) * math.log(x) - 0.5 * x - a * math.log(2.0) - math.lgamma(a)
        log_tail = fx + target
        slope = (-1.0 if upper else 1.0) * math.exp(log_pdf - log_tail)
        step = x - fx / slope if slope != 0.0 else 0.5 * (lo + hi)
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if abs(step - x) <= 4e-16 * x:
            return step
        x = step
    return x


def chdtr(v: Any, x: Any) -> Any:
    """Chi-square cumulative distribution function at `x`."""
    from scipy.special import chdtr as f

    return f(v, x)


def chdtrc(v: Any, x: Any) -> Any:
    """Chi-square survival function at `x` (``1 - chdtr``)."""
    from scipy.special import chdtrc as f

    return f(v, x)


def fdtri(dfn: Any, dfd: Any, p: Any) -> Any:
    """F-distribution quantile: the `x` whose cumulative probability is `p`."""
    from scipy.special import fdtri as f

    return f(dfn, dfd, p)
