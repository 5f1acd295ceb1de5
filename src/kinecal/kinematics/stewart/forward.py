"""Newton forward kinematics of the Stewart-platform CMM (papers/004 sec. 2.2).

* :func:`newton_batch`: damped Newton-Raphson on the leg-length equations (papers/004
  eq. 4-5) with the analytic Jacobian, vectorized over any number of leg sets (a stream
  of machine readings); the orientation is updated multiplicatively (``R <- exp(w) R``), so
  there is no Euler-angle singularity inside the iteration.
* :func:`forward_newton`: neutral start, then multi-start retries for rows that fail.

The paper's own solver, particle swarm optimisation of eq. 6, is in
`kinecal.kinematics.stewart.pso`; both return a :class:`ForwardResult`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.spatial import matrix_from_rpy, rpy_from_matrix

__all__ = [
    "ForwardResult",
    "StewartGeometry",
    "default_tol",
    "expmap",
    "forward_newton",
    "newton_batch",
    "random_starts",
]

Array = NDArray[np.float64]


class StewartGeometry(Protocol):
    """What the solvers here (and in `pso`, `modes`) read of a geometry:
    `kinecal.kinematics.stewart.platform.StewartPlatform` is one. A protocol, so that these
    modules sit below the class that calls them (no import circle)."""

    base_joints: Array
    platform_joints: Array
    leg_offsets: Array
    leg_range: tuple[float, float]
    probe_offset: float

    @property
    def tip_joints(self) -> Array: ...

    @property
    def probe_vector(self) -> Array: ...

    def inverse(self, poses: ArrayLike) -> Array: ...

    def neutral_pose(self) -> Array: ...

    def check_legs(self, legs: ArrayLike, *, file: str | None = None,
                   row_offset: int = 1) -> Array: ...


#: rows per Newton block in `forward_newton` (cache-sized temporaries)
CHUNK = 4096

@dataclass(repr=False)
class ForwardResult:
    """Result of a batch forward-kinematics solve.

    Attributes
    ----------
    poses : ndarray, shape (N, 6)
        Probe poses (x, y, z in the length unit; alpha, beta, gamma in rad).
    converged : ndarray of bool, shape (N,)
        Row solved to the tolerance (newton) or target (pso).
    residual : ndarray, shape (N,)
        Max abs leg-length error ``|l_i - l'_i|`` of each row (length unit).
    iterations : ndarray of int, shape (N,)
        Newton iterations or PSO generations per row.
    elapsed : float
        Wall time of the whole solve (s).
    method : str
        ``"newton"`` or ``"pso"``.
    nfev : ndarray of int, shape (N,)
        Leg-length evaluations per row (pso: particles times generations).
    history : list of ndarray, optional
        pso: best value of eq. 6 after each generation, one array per row.
    """

    poses: Array
    converged: NDArray[np.bool_]
    residual: Array
    iterations: NDArray[np.int64]
    elapsed: float
    method: str
    nfev: NDArray[np.int64]
    history: list[Array] | None = None

    def __repr__(self) -> str:
        return (f"<ForwardResult {self.method}: {len(self.converged)} rows, "
                f"{int(np.count_nonzero(self.converged))} converged, {self.elapsed:.3g} s>")


def expmap(w: Array) -> Array:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``w`` ``(..., 3)`` (Rodrigues)."""
    th2 = np.sum(w * w, axis=-1)
    th = np.sqrt(th2)
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    E = b[..., None, None] * (w[..., :, None] * w[..., None, :])
    diag = 1.0 - b * th2
    E[..., 0, 0] += diag
    E[..., 1, 1] += diag
    E[..., 2, 2] += diag
    E[..., 0, 1] -= a * z
    E[..., 1, 0] += a * z
    E[..., 0, 2] += a * y
    E[..., 2, 0] -= a * y
    E[..., 1, 2] -= a * x
    E[..., 2, 1] += a * x
    return E


def _jacobian(rq: Array, n: Array) -> Array:
    """Rows ``[n_i, (R q_i) x n_i]`` ``(N, 6, 6)`` from ``R q_i`` and unit legs ``(N, 6, 3)``."""
    J = np.empty((*n.shape[:-1], 6))
    J[..., :3] = n
    J[..., 3] = rq[..., 1] * n[..., 2] - rq[..., 2] * n[..., 1]
    J[..., 4] = rq[..., 2] * n[..., 0] - rq[..., 0] * n[..., 2]
    J[..., 5] = rq[..., 0] * n[..., 1] - rq[..., 1] * n[..., 0]
    return J


def newton_batch(
    q: Array,
    b: Array,
    lengths: Array,
    R: Array,
    t: Array,
    *,
    tol: float = 1e-12,
    max_iter: int = 50,
    max_step: float = 0.25,
    max_turn: float = 0.5,
) -> tuple[Array, Array, Array, NDArray[np.int64]]:
    """Damped Newton-Raphson on ``|R q_i + t - b_i| = L_i``, vectorized over rows.

    Parameters
    ----------
    q : ndarray, shape (6, 3)
        Platform joints relative to the probe tip (platform frame).
    b : ndarray, shape (6, 3)
        Base joints (base frame).
    lengths : ndarray, shape (N, 6)
        Physical leg lengths ``L_i`` (length unit).
    R : ndarray, shape (N, 3, 3)
        Start orientations.
    t : ndarray, shape (N, 3)
        Start tip positions (length unit).
    tol : float
        A row stops when ``max_i | |l_i| - L_i | < tol`` (length unit).
    max_iter : int
        Iteration limit.
    max_step, max_turn : float
        Step limits per iteration: translation (length unit) and rotation (rad).

    Returns
    -------
    R : ndarray, shape (N, 3, 3)
    t : ndarray, shape (N, 3)
    residual : ndarray, shape (N,)
        Final max abs leg error (length unit); ``inf`` for rows that diverged.
    iterations : ndarray of int, shape (N,)
    """
    R = np.array(R, dtype=float)
    t = np.array(t, dtype=float)
    L = np.asarray(lengths, dtype=float)
    n_rows = L.shape[0]
    residual = np.full(n_rows, np.inf)
    iters = np.zeros(n_rows, dtype=np.int64)
    active = np.arange(n_rows)
    far = 10.0 * (np.abs(b).max() + np.abs(q).max() + L.max(initial=1.0))
    qt = np.ascontiguousarray(q.T)
    for k in range(max_iter + 1):
        Ra, ta = (R, t) if active.size == n_rows else (R[active], t[active])
        rq = np.swapaxes(Ra @ qt, -1, -2)  # (n, 6, 3): R q_i
        lv = rq + ta[:, None, :] - b
        norm = np.sqrt(np.einsum("nij,nij->ni", lv, lv))
        r = norm - (L if active.size == n_rows else L[active])
        rmax = np.abs(r).max(axis=1)
        ok = np.isfinite(rmax) & (np.abs(ta).max(axis=1) < far)
        residual[active] = np.where(ok, rmax, np.inf)
        go = ok & (rmax >= tol)
        if k == max_iter or not go.any():
            break
        if not go.all():
            active, rq, lv, norm, r, Ra, ta = (a[go] for a in (active, rq, lv, norm, r, Ra, ta))
        J = _jacobian(rq, lv / norm[..., None])
        try:
            d = np.linalg.solve(J, -r[..., None])[..., 0]
        except np.linalg.LinAlgError:
            d = -(np.linalg.pinv(J) @ r[..., None])[..., 0]
        dt, dw = d[:, :3], d[:, 3:]
        nt = np.sqrt(np.einsum("ni,ni->n", dt, dt))
        nw = np.sqrt(np.einsum("ni,ni->n", dw, dw))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.minimum(1.0, np.minimum(max_step / nt, max_turn / nw))
        scale = np.where(np.isfinite(scale), scale, 0.0)[:, None]
        t[active] = ta + scale * dt
        R[active] = expmap(scale * dw) @ Ra
        iters[active] += 1
    return R, t, residual, iters


def default_tol(lengths: Array) -> float:
    """Default Newton tolerance: ``1e-13`` times the longest leg (length unit)."""
    return 1e-13 * max(float(np.abs(lengths).max(initial=0.0)), 1e-300)


def random_starts(
    geom: StewartGeometry, n: int, rng: np.random.Generator, *, below: bool = True
) -> tuple[Array, Array]:
    """Random start poses for multi-start Newton.

    Orientations are uniform on SO(3) (random unit quaternions); tip positions uniform in
    a box around the base: ``|x|, |y| <= R_b``, ``z`` in ``[-z_max, z_max]`` (or
    ``[0, z_max]`` when `below` is false) with ``z_max = l_max + |ls|``.

    Returns
    -------
    R : ndarray, shape (n, 3, 3)
    t : ndarray, shape (n, 3)
    """
    from kinecal.spatial import matrix_from_quaternion

    quat = rng.standard_normal((n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    R = matrix_from_quaternion(quat)
    rb = float(np.abs(geom.base_joints[:, :2]).max())
    hi = geom.leg_range[1] if np.isfinite(geom.leg_range[1]) else 2.0 * rb
    zmax = hi + abs(geom.probe_offset)
    u = rng.random((n, 3))
    t = np.empty((n, 3))
    t[:, :2] = (2.0 * u[:, :2] - 1.0) * rb
    t[:, 2] = (2.0 * u[:, 2] - 1.0) * zmax if below else u[:, 2] * zmax
    return R, t


def _start_poses(geom: StewartGeometry, x0: ArrayLike | None, n: int) -> tuple[Array, Array]:
    x = geom.neutral_pose() if x0 is None else np.asarray(x0, dtype=float)
    if x.shape not in ((6,), (n, 6)) or not np.isfinite(x).all():
        raise InputError(f"x0 must be one finite pose (6,) or ({n}, 6), got {x.shape}", option="x0")
    x = np.broadcast_to(x, (n, 6))
    return np.array(matrix_from_rpy(x[:, 3:])), np.array(x[:, :3])


def forward_newton(
    geom: StewartGeometry,
    legs: Array,
    *,
    x0: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    tol: float | None = None,
    max_iter: int = 50,
    restarts: int = 64,
) -> ForwardResult:
    """Batch Newton forward kinematics; failed rows retried from `restarts` random starts.

    Parameters
    ----------
    geom : StewartGeometry
    legs : ndarray, shape (N, 6)
        Leg readings (length unit), already range-checked.
    x0 : array_like, shape (6,) or (N, 6), optional
        Start poses (length unit, rad); default the neutral pose.
    rng : Generator or int, optional
        For the retries' random starts (default seed 0: deterministic).
    tol : float, optional
        Convergence tolerance on the max abs leg error (length unit); default
        ``1e-13 * max(L)``, a few rounding errors of the leg lengths.
    max_iter : int
        Newton iteration limit.
    restarts : int
        Random starts per failed row; among the converged ones the solution nearest the
        neutral pose is kept.

    Returns
    -------
    ForwardResult
    """
    t0 = time.perf_counter()
    L = np.asarray(legs, dtype=float) + geom.leg_offsets
    n = L.shape[0]
    tol = default_tol(L) if tol is None else float(tol)
    R, t = _start_poses(geom, x0, n)
    q, b = geom.tip_joints, geom.base_joints
    res = np.empty(n)
    its = np.empty(n, dtype=np.int64)
    for s in range(0, n, CHUNK):  # blocks keep the temporaries in cache (2x faster)
        blk = slice(s, s + CHUNK)
        R[blk], t[blk], res[blk], its[blk] = newton_batch(
            q, b, L[blk], R[blk], t[blk], tol=tol, max_iter=max_iter
        )
    failed = np.flatnonzero(~(res < tol))
    if failed.size and restarts > 0:
        gen = np.random.default_rng(0 if rng is None else rng)
        Rs, ts = random_starts(geom, failed.size * restarts, gen, below=False)
        Lr = np.repeat(L[failed], restarts, axis=0)
        Rs, ts, rs, itr = newton_batch(q, b, Lr, Rs, ts, tol=tol, max_iter=max_iter)
        neutral = geom.neutral_pose()
        dist = np.linalg.norm(ts - neutral[:3], axis=1) + np.linalg.norm(
            Rs - np.eye(3), axis=(1, 2)
        )
        dist = np.where(rs < tol, dist, np.inf).reshape(failed.size, restarts)
        pick = np.argmin(dist, axis=1)
        good = np.isfinite(dist[np.arange(failed.size), pick])
        idx = np.arange(failed.size) * restarts + pick
        rows = failed[good]
        R[rows], t[rows], res[rows] = Rs[idx[good]], ts[idx[good]], rs[idx[good]]
        its[failed] += itr.reshape(failed.size, restarts).sum(axis=1)
    poses = np.concatenate([t, rpy_from_matrix(R)], axis=1)
    return ForwardResult(
        poses, res < tol, res, its, time.perf_counter() - t0, "newton", 6 * (its + 1)
    )
