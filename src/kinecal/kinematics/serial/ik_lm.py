"""The Levenberg-Marquardt iterations behind `kinecal.kinematics.serial.ik.solve_ik`.

Batch layout: every array has the targets first; an iteration works on the targets still
active (index array), with a damping factor, a step acceptance and a stopping decision
per target. Only the model's public kinematics is used (`sweep`, or `fk` and
`joint_jacobian`; `joint_limits`, `is_prismatic`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.spatial import axis_angle_from_matrix

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["CONVERGED", "Problem", "condition_numbers", "gram_condition", "pose_error", "run"]

Array = NDArray[np.float64]

#: statuses of converged targets
CONVERGED = ("converged", "near-singular")

_MU0 = 1e-2       # initial damping factor (lam = mu |e| L)
_MU_MIN = 1e-12   # smallest damping factor
_MU_MAX = 1e12    # beyond: no acceptable step left (stationary)
_STALL = 6        # iterations without a relative cost decrease of _FTOL -> stationary
_FTOL = 1e-6
#: targets per sweep of the chain (bounds the memory of the recorded frames)
CHUNK = 4096


def pose_error(target: Array, positions: Array, rotations: Array | None = None
               ) -> tuple[Array, Array | None]:
    """Error of tool frames to `target` ``(N, 3)`` points or ``(N, 4, 4)`` frames.

    Parameters
    ----------
    target : ndarray, shape (N, 3) or (N, 4, 4)
    positions : ndarray, shape (N, 3) or (N, 4, 4)
        Tool points, or tool frames (then `rotations` is taken from them).
    rotations : ndarray, shape (N, 3, 3), optional
        Tool-frame orientations (needed for frame targets when `positions` are points).

    Returns
    -------
    dp : ndarray, shape (N, 3)
        ``p_target - p`` (length unit).
    dr : ndarray, shape (N, 3) or None
        ``log(R_target R^T)``, the rotation vector (rad, measurement frame) that turns the
        tool frame onto the target; None for position targets.
    """
    if positions.ndim == 3:
        positions, rotations = positions[:, :3, 3], positions[:, :3, :3]
    if target.ndim == 2:
        return target - positions, None
    dp = target[:, :3, 3] - positions
    return dp, _rotation_log(target[:, :3, :3] @ np.swapaxes(rotations, 1, 2))


def _rotation_log(M: Array) -> Array:
    """Rotation vectors ``(N, 3)`` of rotations `M` ``(N, 3, 3)``.

    ``theta = atan2(|s|, c)`` from the antisymmetric part ``s`` and ``c = (tr - 1) / 2``:
    exact to round-off at small angles (where IK ends); rotations near pi, where the axis
    of the antisymmetric part loses digits, go through the quaternion.
    """
    s = 0.5 * np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0],
                        M[:, 1, 0] - M[:, 0, 1]], axis=1)
    c = 0.5 * (M[:, 0, 0] + M[:, 1, 1] + M[:, 2, 2] - 1.0)
    sn = np.sqrt(np.einsum("ij,ij->i", s, s))
    theta = np.arctan2(sn, c)
    pos = sn > 0.0
    out = s * np.where(pos, theta / np.where(pos, sn, 1.0), 1.0)[:, None]
    near_pi = (c < 0.0) & (sn < 0.5)
    if near_pi.any():
        out[near_pi] = axis_angle_from_matrix(M[near_pi])
    return out


def joint_bounds(model: SerialModel) -> tuple[Array, Array, NDArray[np.bool_],
                                              NDArray[np.bool_]]:
    """Lower and upper joint limits, prismatic joints and the revolute joints whose range
    spans a full turn (``q`` and ``q +- 2 pi`` are the same joint position, so a step across
    a limit wraps into the range instead of stopping); kept with the model after the first
    call (every `solve_ik` of one target asks)."""
    got = getattr(model, "_ik_bounds", None)
    if got is None:
        lim = np.asarray(model.joint_limits, dtype=float)
        prismatic = np.asarray(model.is_prismatic(), dtype=bool)
        wrap = ~prismatic & (lim[:, 1] - lim[:, 0] >= 2.0 * np.pi - 1e-9)
        got = (lim[:, 0].copy(), lim[:, 1].copy(), prismatic, wrap)
        if isinstance(getattr(model, "__dict__", None), dict):
            model.__dict__["_ik_bounds"] = got
    return got


class Problem:
    """The scaled least-squares problem of one `solve_ik` call (shared by its restarts)."""

    def __init__(self, model: SerialModel, params: Array | None, targets: Array,
                 rotation_weight: float, length: float) -> None:
        self.model = model
        self.params = params
        self.targets = targets
        self.pose = targets.ndim == 3
        self.rows = 6 if self.pose else 3
        self.w = rotation_weight
        self.length = length
        self.lo, self.hi, prismatic, self.wrap = joint_bounds(model)
        # scaled joints: a prismatic joint in units of the arm's length, so that every
        # column of the scaled Jacobian is a length per (dimensionless) joint step
        self.col = np.where(prismatic, length, 1.0)
        self.scaled = bool(prismatic.any())

    def project(self, q: Array) -> Array:
        """Joints `q` ``(M, n)`` brought into the limits: full-turn revolute joints wrapped
        by the fewest turns that bring them back (a joint of range +-360 deg at 370 deg
        goes to 10 deg, not to -350), the others clipped."""
        if self.wrap.any():
            turn = 2.0 * np.pi
            above = self.wrap & (q > self.hi)
            below = self.wrap & (q < self.lo)
            if above.any() or below.any():
                q = np.where(above, q - turn * np.ceil((q - self.hi) / turn), q)
                q = np.where(below, q + turn * np.ceil((self.lo - q) / turn), q)
        return np.clip(q, self.lo, self.hi)

    def evaluate(self, q: Array, idx: NDArray[np.intp]
                 ) -> tuple[Array, Array, Array, Array]:
        """Forward kinematics and joint Jacobian at `q` ``(M, n)`` (targets `idx`).

        Returns the weighted error vectors ``(M, rows)``, the position and rotation errors
        ``(M,)`` and the scaled, weighted joint Jacobian ``(M, rows, n)``. A `SerialModel`
        computes both from one sweep of its chain (`SerialModel.sweep`, in chunks of
        `CHUNK` poses); any other model through its `fk` and `joint_jacobian`.
        """
        outputs = "pose" if self.pose else "position"
        sweep = getattr(self.model, "sweep", None)
        # a problem of one target (not one row of a batch: a target's answer must not
        # depend on the other targets) evaluates the folded chain, no per-call set-up
        single = getattr(self.model, "single_pose", None) if len(self.targets) == 1 else None
        one = single(q[0], self.params, outputs) if single and q.shape[0] == 1 else None
        if one is not None:
            T, J = one[0][None], one[1][None].copy()
            P, R = T[:, :3, 3], T[:, :3, :3]
        elif sweep is None:
            T = self.model.fk(q, self.params)
            P, R = T[:, :3, 3], T[:, :3, :3]
            J = self.model.joint_jacobian(q, self.params, outputs)
        else:
            M = q.shape[0]
            P = np.empty((M, 3))
            R = np.empty((M, 3, 3)) if self.pose else None
            J = np.empty((M, self.rows, q.shape[1]))
            for start in range(0, M, CHUNK):
                sl = slice(start, min(start + CHUNK, M))
                s = sweep(q[sl], self.params)
                P[sl] = s.positions
                if self.pose:
                    R[sl] = s.rotations
                J[sl] = s.joint_jacobian_t(outputs).transpose(2, 1, 0)
        if self.pose:
            J[:, 3:] *= self.w
        if self.scaled:
            J *= self.col
        dp, dr = pose_error(self.targets[idx], P, R)
        pos = np.sqrt(np.einsum("ij,ij->i", dp, dp))
        if dr is None:
            return dp, pos, np.zeros_like(pos), J
        rot = np.sqrt(np.einsum("ij,ij->i", dr, dr))
        return np.concatenate([dp, self.w * dr], axis=1), pos, rot, J


def _solve(A: Array, b: Array) -> Array:
    """Batched ``A x = b``; a (numerically) singular system falls back to least squares."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.stack([np.linalg.lstsq(Ai, bi, rcond=None)[0] for Ai, bi in zip(A, b,
                                                                                 strict=True)])


def _step(J: Array, e: Array, lam: Array, primal: bool = False) -> Array:
    """Damped least-squares steps ``(M, n)``: ``J^T (J J^T + lam I)^-1 e`` (minimum norm)
    when rows <= joints, else (or if `primal`) ``(J^T J + lam I)^-1 J^T e``."""
    _, r, n = J.shape
    Jt = np.swapaxes(J, 1, 2)
    if r <= n and not primal:
        A = J @ Jt
        k = np.arange(r)
        # floor: keeps the system numerically regular (relative damping >= 1e-14)
        A[:, k, k] += np.maximum(lam, 1e-14 * np.trace(A, axis1=1, axis2=2))[:, None]
        return (Jt @ _solve(A, e[:, :, None]))[:, :, 0]
    A = Jt @ J
    k = np.arange(n)
    A[:, k, k] += np.maximum(lam, 1e-14 * np.trace(A, axis1=1, axis2=2))[:, None]
    return _solve(A, Jt @ e[:, :, None])[:, :, 0]


def _bounded_step(prob: Problem, J: Array, e: Array, lam: Array, q: Array) -> Array:
    """`_step`, then again without the joints that sit at a limit and would leave it
    (their columns frozen: the other joints take over the motion)."""
    ds = _step(J, e, lam)
    out = ds * prob.col
    blocked = (((q <= prob.lo) & (out < 0)) | ((q >= prob.hi) & (out > 0))) & ~prob.wrap
    rows = np.flatnonzero(blocked.any(axis=1))
    if rows.size:
        Jb = J[rows] * (~blocked[rows])[:, None, :]
        ds[rows] = _step(Jb, e[rows], lam[rows], primal=True)
    return ds


def _trial(prob: Problem, J: Array, e: Array, cost: Array, q: Array, lam: Array,
           idx: NDArray[np.intp]) -> tuple[Array, ...]:
    """One damped step from `q` and the true errors there: joints, error vectors, position
    and rotation errors, cost, the cost decrease the linear model predicted, and the
    Jacobian at the new joints."""
    ds = _bounded_step(prob, J, e, lam, q)
    qt = prob.project(q + ds * prob.col)
    # the step actually taken (a wrapped joint moved by its own step)
    dsp = np.where(prob.wrap, ds, (qt - q) / prob.col)
    lin = e - np.einsum("mrn,mn->mr", J, dsp)
    pred = cost - np.einsum("ij,ij->i", lin, lin)
    et, post, rott, Jt = prob.evaluate(qt, idx)
    ct = np.einsum("ij,ij->i", et, et)
    return qt, et, post, rott, ct, pred, Jt


def run(prob: Problem, q: Array, tol_p: float, tol_r: float, max_iter: int
         ) -> tuple[Array, Array, Array, NDArray[np.int_], NDArray[np.str_]]:
    """Levenberg-Marquardt from seeds `q` ``(N, n)``; every target has its own damping,
    acceptance and stopping. Returns q, position and rotation errors, iterations, status."""
    N = q.shape[0]
    q = q.copy()
    idx_all = np.arange(N)
    e, pos, rot, J = prob.evaluate(q, idx_all)
    cost = np.einsum("ij,ij->i", e, e)
    iters = np.zeros(N, dtype=int)
    status = np.full(N, "max-iterations", dtype="<U14")
    mu = np.full(N, _MU0)
    nu = np.full(N, 2.0)
    stall = np.zeros(N, dtype=int)
    done = (pos <= tol_p) & (rot <= tol_r)
    status[done] = "converged"
    active = np.flatnonzero(~done)
    for _ in range(max_iter):
        if active.size == 0:
            break
        a = active
        Ja, ea, qa = J[a], e[a], q[a]
        lam = mu[a] * np.sqrt(cost[a]) * prob.length
        qt, et, post, rott, ct, pred, Jt = _trial(prob, Ja, ea, cost[a], qa, lam, a)
        iters[a] += 1
        gain = cost[a] - ct
        rho = np.where(pred > 0, gain / np.where(pred > 0, pred, 1.0), -1.0)
        accept = (gain > 0) & (rho > 1e-4)
        mu_a = mu[a]
        # Nielsen's update: smooth in the gain ratio, doubling the damping on rejections
        nu_a = nu[a]
        fac = np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
        mu_a = np.where(accept, np.maximum(mu_a * fac, _MU_MIN), mu_a * nu_a)
        nu[a] = np.where(accept, 2.0, nu_a * 2.0)
        mu[a] = mu_a
        progress = accept & (gain > _FTOL * cost[a])
        stall[a] = np.where(progress, 0, stall[a] + 1)
        acc = a[accept]
        q[acc], e[acc], cost[acc] = qt[accept], et[accept], ct[accept]
        pos[acc], rot[acc], J[acc] = post[accept], rott[accept], Jt[accept]
        ok = accept & (post <= tol_p) & (rott <= tol_r)
        status[a[ok]] = "converged"
        stuck = ~ok & ((stall[a] >= _STALL) | (mu[a] > _MU_MAX))
        status[a[stuck]] = "unreachable"
        active = a[~(ok | stuck)]
    return q, pos, rot, iters, status


def condition_numbers(J: Array) -> Array:
    """Condition numbers ``(N,)`` of scaled Jacobians `J` ``(N, rows, n)`` (inf where
    singular)."""
    r, n = J.shape[1:]
    return gram_condition(J @ np.swapaxes(J, 1, 2) if r <= n else np.swapaxes(J, 1, 2) @ J)


def gram_condition(G: Array) -> Array:
    """`condition_numbers` from the Gram matrices ``(N, m, m)`` (``J J^T`` or ``J^T J``)."""
    ev = np.linalg.eigvalsh(G)
    hi = ev[:, -1]
    lo = np.maximum(ev[:, 0], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.sqrt(hi / lo)
    return np.where((lo > 0) & (hi > 0), c, np.inf)


