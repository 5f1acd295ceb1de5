"""The chi-square and F distribution functions of `scipy.special`, imported on first use.

``import scipy.special`` costs 0.15-0.3 s (its array-API layer loads parts of numpy that
nothing else needs), more than a one-pose ``kinecal fk`` takes in all. The tests that use
these functions are the diagnostics' and the outlier judgements'; a command that never
reaches one of them no longer pays for the import. Same names, arguments and results as
`scipy.special` (which see).
"""

from __future__ import annotations

from typing import Any

__all__ = ["chdtr", "chdtrc", "chdtri", "fdtri"]


def chdtri(v: Any, p: Any) -> Any:
    """Chi-square quantile exceeded with probability `p` (`v` degrees of freedom)."""
    from scipy.special import chdtri as f

    return f(v, p)


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
