"""Box, unit-cube and argument helpers shared by the optimizers (see ``_common``).

Bounds validation, the linear map between a box and the unit hypercube, seed points, option
checks, the rng helper and index sampling. Re-exported by :mod:`kinecal.optimize._common`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal.errors import InputError

__all__ = [
    "RngLike",
    "as_int",
    "as_positive",
    "as_probability",
    "check_bounds",
    "clip_unit",
    "distinct_others",
    "from_unit",
    "make_rng",
    "seed_points",
    "to_unit",
]

RngLike = None | int | np.random.Generator


def make_rng(rng: RngLike = None) -> np.random.Generator:
    """Return a :class:`numpy.random.Generator` (``np.random.default_rng(rng)``).

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        ``None`` draws fresh OS entropy, an int is a seed, a Generator is used as it is.
    """
    if rng is not None and not isinstance(rng, int | np.integer | np.random.Generator):
        raise InputError(
            f"expected None, an int seed or a numpy Generator, got {type(rng).__name__}",
            option="rng",
        )
    return np.random.default_rng(rng)


def check_bounds(bounds: Any) -> tuple[np.ndarray, np.ndarray]:
    """Validate a box and return its lower and upper corners.

    Parameters
    ----------
    bounds : array_like, shape (n, 2)
        One ``(low, high)`` row per variable, in the variable's unit.

    Returns
    -------
    lo, hi : numpy.ndarray, shape (n,)

    Raises
    ------
    kinecal.InputError
        (a ``ValueError``) if the shape is not ``(n, 2)`` with ``n >= 1``, a value is not finite
        or a row has ``low >= high``.
    """
    try:
        b = np.asarray(bounds, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"expected an (n, 2) array of (low, high) rows, got {bounds!r}", option="bounds"
        ) from exc
    if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] < 1:
        raise InputError(
            f"expected an (n, 2) array of (low, high) rows, got shape {b.shape}", option="bounds"
        )
    if not np.all(np.isfinite(b)):
        rows = np.flatnonzero(~np.all(np.isfinite(b), axis=1))
        raise InputError(
            f"expected finite (low, high) values, row(s) {rows.tolist()} are not finite",
            option="bounds",
        )
    bad = np.flatnonzero(b[:, 0] >= b[:, 1])
    if bad.size:
        raise InputError(
            f"expected low < high in every row, row(s) {bad.tolist()} violate it", option="bounds"
        )
    return b[:, 0].copy(), b[:, 1].copy()


def to_unit(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Map points ``(..., n)`` from the box ``[lo, hi]`` to the unit cube (no clipping)."""
    return (np.asarray(x, dtype=float) - lo) / (hi - lo)


def from_unit(u: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Map points ``(..., n)`` from the unit cube to the box ``[lo, hi]``."""
    return lo + u * (hi - lo)


def clip_unit(a: np.ndarray) -> np.ndarray:
    """Clip ``a`` to ``[0, 1]`` in place and return it (two ufunc calls, cheaper than np.clip)."""
    np.maximum(a, 0.0, out=a)
    return np.minimum(a, 1.0, out=a)


def seed_points(x0: Any, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """Validate user seed points and return them in the unit cube, clipped into it.

    Parameters
    ----------
    x0 : None or array_like, shape (n,) or (k, n)
        Points (in the box's unit) to place in the initial population.
    lo, hi : numpy.ndarray, shape (n,)

    Returns
    -------
    numpy.ndarray, shape (k, n), or None
    """
    if x0 is None:
        return None
    n = lo.size
    try:
        x = np.asarray(x0, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected an ({n},) or (k, {n}) array", option="x0") from exc
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != n or x.shape[0] < 1:
        raise InputError(f"expected an ({n},) or (k, {n}) array, got shape {x.shape}", option="x0")
    if not np.all(np.isfinite(x)):
        raise InputError("expected finite values", option="x0")
    return np.clip(to_unit(x, lo, hi), 0.0, 1.0)


def as_int(name: str, value: Any, minimum: int) -> int:
    """Return ``value`` as an int ``>= minimum`` or raise :class:`InputError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InputError(f"expected an integer >= {minimum}, got {value!r}", option=name)
    return int(value)


def as_probability(name: str, value: Any) -> float:
    """Return ``value`` as a float in ``[0, 1]`` or raise :class:`InputError` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected a number in [0, 1], got {value!r}", option=name) from exc
    if not 0.0 <= v <= 1.0:
        raise InputError(f"expected a number in [0, 1], got {value!r}", option=name)
    return v


def as_positive(name: str, value: Any, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite float ``> 0`` (``>= 0`` with ``allow_zero``)."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected a positive number, got {value!r}", option=name) from exc
    if not np.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise InputError(f"expected a positive number, got {value!r}", option=name)
    return v


def distinct_others(
    rng: np.random.Generator, size: int, k: int, rows: np.ndarray | None = None
) -> np.ndarray:
    """Draw ``k`` distinct population indices per row, all different from the row's own index.

    Each row draws ``k`` distinct offsets in ``1 .. size - 1`` (the ``j``-th uniform over the
    ``size - 1 - j`` offsets not yet taken, mapped past the taken ones) and returns
    ``(own + offset) mod size``: uniform over the ordered ``k``-tuples of other indices.
    Vectorized over rows; the loops run over ``k`` only.

    Parameters
    ----------
    rng : numpy.random.Generator
    size : int
        Population size, ``>= k + 1``.
    k : int
        Number of indices per row.
    rows : numpy.ndarray of int, shape (m,), optional
        The index each row must avoid (default ``arange(size)``).

    Returns
    -------
    numpy.ndarray of int, shape (m, k)
    """
    own = np.arange(size) if rows is None else np.asarray(rows, dtype=np.intp)
    highs = (size - np.arange(k))[:, None]  # exclusive upper bounds: 1 .. size - 1 - j
    off = rng.integers(1, highs, size=(k, own.size))
    taken: list[np.ndarray] = []  # offsets drawn so far, sorted per row
    for j in range(k):
        r = off[j]
        for e in taken:
            r += r >= e
        merged, cur = [], r
        for e in taken:  # insert r, keeping every row sorted
            merged.append(np.minimum(e, cur))
            cur = np.maximum(e, cur)
        taken = [*merged, cur]
    return (own[:, None] + off.T) % size
