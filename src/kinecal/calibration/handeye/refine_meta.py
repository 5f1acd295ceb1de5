"""Paper 001's metaheuristic refinement of a hand-eye solution (``papers/001``, sec. 4).

The unknown is the 7-vector ``x = (q_w, q_x, q_y, q_z, t_x, t_y, t_z)`` (unit quaternion
and translation of X, sec. 4.1); the search box is centred on the analytic solution and
the analytic solution itself is seeded into the initial pack (sec. 4.1: "replace part of
the initial wolves by the analytic solution"). The fitness (sec. 4, the equation before
4.1; the formula itself is not in our copy of the text) is read as the mean squared
Frobenius norm of the ``A X - X B`` mismatch over the motion pairs,

    f(x) = 1/m sum_k || A_k X(x) - X(x) B_k ||_F^2,

with the quaternion normalised inside ``X(x)`` and lengths divided by a reference length
``length`` (default: the rms camera-target distance). The Frobenius norm adds unit-free
rotation entries to lengths, so in raw millimetres the translation rows would swamp the
rotation rows and the refined rotation would be worse than the analytic one (measured:
about 3x in `benchmarks/bench_handeye.py`); the paper does not state its unit, and the
scaling makes the fitness independent of it. The optimizers are
`kinecal.optimize.minimize` with ``method="igwo"`` (Nadimi-Shahraki et al. 2021) or
``"dlh-gwo-de"`` (paper 001, sec. 4.2-4.6); nothing of the search is re-implemented here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye._motions import motion_pairs
from kinecal.spatial import matrix_from_quaternion, quaternion_from_matrix, transform_from

Array = NDArray[np.float64]

__all__ = ["MetaRefinement", "axxb_fitness", "fitness_matrix", "metaheuristic"]


@dataclass
class MetaRefinement:
    """Result of `metaheuristic`: refined ``X`` ``(4, 4)``, best fitness, history per
    iteration (``history[0]`` the seeded pack's best), evaluations, iterations, seconds."""

    X: Array
    fun: float
    history: list[float] = field(default_factory=list)
    nfev: int = 0
    nit: int = 0
    elapsed: float = 0.0


def axxb_fitness(A: Array, B: Array, length: float = 1.0) -> Callable[[Array], Array]:
    """Population fitness ``(P, 7) -> (P,)`` of paper 001 (sec. 4), see the module docstring.

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L).
    length : float
        Reference length (L) dividing every translation.

    Returns
    -------
    callable
        ``f(x)`` with ``x`` ``(P, 7)`` = (q_w, q_x, q_y, q_z, t (L)); ``f`` unit-free.
    """
    Q = fitness_matrix(A, B, length)

    def fun(x: Array) -> Array:
        x = np.atleast_2d(x)
        q = x[:, :4]
        norm = np.linalg.norm(q, axis=1)
        R = matrix_from_quaternion(np.where(norm[:, None] > 0, q, [1.0, 0.0, 0.0, 0.0]))
        z = np.concatenate([R.reshape(-1, 9), x[:, 4:] / length, np.ones((len(x), 1))], axis=1)
        return np.einsum("pi,ij,pj->p", z, Q, z)

    return fun


def fitness_matrix(A: Array, B: Array, length: float = 1.0) -> Array:
    """The fitness as a quadratic form ``f = z^T Q z``, ``z = (vec R (row-major), t / length, 1)``.

    Per pair, ``A X - X B`` is linear in z: rotation block
    ``(R_A (x) I - I (x) R_B^T) vec R`` (9 rows) and translation block
    ``(R_A - I) t - (I (x) t_B^T) vec R + t_A`` (3 rows); summing their Gram matrices once
    makes each evaluation of the whole pack one small quadratic form instead of m matrix
    products per wolf.

    Returns
    -------
    ndarray, shape (13, 13)
        Symmetric positive semi-definite, divided by the number of pairs m.
    """
    m = len(A)
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    tA, tB = A[:, :3, 3] / length, B[:, :3, 3] / length
    I3 = np.eye(3)
    M = np.zeros((m, 12, 13))
    M[:, :9, :9] = (np.einsum("kij,ab->kiajb", RA, I3)
                    - np.einsum("ij,kba->kiajb", I3, RB)).reshape(m, 9, 9)
    M[:, 9:, :9] = -np.einsum("ij,kb->kijb", I3, tB).reshape(m, 3, 9)
    M[:, 9:, 9:12] = RA - I3
    M[:, 9:, 12] = tA
    return np.einsum("kai,kaj->ij", M, M) / m


def metaheuristic(
    G: Array,
    C: Array,
    X0: Array,
    method: str,
    *,
    rng: int | np.random.Generator | None = None,
    pairs: str = "all",
    maxiter: int = 200,
    popsize: int = 30,
    rotation_box: float = 0.01,
    translation_box: float | None = None,
    maxfev: int | None = None,
    length: float | None = None,
    method_options: dict[str, Any] | None = None,
    callback: Callable[..., Any] | None = None,
) -> MetaRefinement:
    """Refine ``X0`` with IGWO or DLH-GWO-DE over the 7-vector (paper 001, sec. 4).

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand), length L.
    C : ndarray, shape (n, 4, 4)
        ``target2cam``, length L.
    X0 : ndarray, shape (4, 4)
        Analytic solution: centre of the search box and seed of the pack.
    method : {"igwo", "dlh-gwo-de"}
        Optimizer of `kinecal.optimize.minimize`.
    rng : int or Generator, optional
        Seed; the same seed gives the same result.
    pairs : {"all", "consecutive"}
        Motion pairs of the fitness (the paper: consecutive stations, eq. (2)).
    maxiter : int
        Iterations.
    popsize : int
        Pack size.
    rotation_box : float
        Half-width of the box of each quaternion component around ``q(X0)`` (0.01 is about
        +-1.1 deg per component).
    translation_box : float, optional
        Half-width (L) of the box of each translation component; default 5 % of the rms
        camera-target distance.
    maxfev : int, optional
        Evaluation budget.
    length : float, optional
        Reference length of the fitness (L); default the rms camera-target distance.
    method_options : dict, optional
        Further options of the optimizer (e.g. ``F``, ``CR`` of DLH-GWO-DE).
    callback : callable, optional
        Passed to `minimize`.

    Returns
    -------
    MetaRefinement
    """
    from kinecal.optimize import minimize

    A, B = motion_pairs(G, C, pairs)
    dist = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    fun = axxb_fitness(A, B, length if length is not None else dist)
    if translation_box is None:
        translation_box = 0.05 * dist
    x0 = np.concatenate([quaternion_from_matrix(X0[:3, :3]), X0[:3, 3]])
    half = np.r_[[rotation_box] * 4, [translation_box] * 3]
    bounds = np.stack([x0 - half, x0 + half], axis=1)
    opts = {"popsize": int(popsize), **(method_options or {})}
    res = minimize(fun, bounds, method=method, x0=x0, rng=rng, maxiter=maxiter, maxfev=maxfev,
                   callback=callback, options=opts)
    x = np.asarray(res.x, dtype=float)
    X = transform_from(matrix_from_quaternion(x[:4]), x[4:])
    return MetaRefinement(X, float(res.fun), [float(h) for h in res.history], int(res.nfev),
                          int(res.nit), float(res.elapsed))
