"""Batch inverse kinematics of serial arms: Levenberg-Marquardt on the analytic joint Jacobian.

`solve_ik` finds joint values that put the tool of any `SerialModel` (every convention,
base and tool frames, prismatic joints, fixed frames, nominal or calibrated parameters) at
given positions (3 DOF) or poses (6 DOF). It uses only the model's public kinematics
(`SerialModel.sweep`, which gives the tool poses and the joint Jacobian of one pass over
the chain, bit for bit what `SerialModel.fk` and `SerialModel.joint_jacobian` give; any
other model through its `fk` and `joint_jacobian`; `joint_limits`, `is_prismatic`), so
whatever the model adds to them (joint-angle corrections, markers, new conventions) IK
inherits.

All targets are solved at once: every iteration is one batched pass over the chain (the
trial poses, and the Jacobians of the accepted steps) and one batched linear solve over
the targets still active, with a damping factor, a step acceptance and a stopping
decision per target.

The step (damped least squares, Levenberg-Marquardt on scaled joints)::

    dq = J^T (J J^T + lam I)^-1 e        rows <= joints (minimum-norm: nearest solution)
    dq = (J^T J + lam I)^-1 J^T e        rows >  joints

with the error ``e = (p_target - p, w * log(R_target R^T))`` (the rotation rows weighted
by `rotation_weight`, a length per radian) and the damping ``lam = mu * |e| * L``: it
vanishes with the error, which keeps the convergence quadratic on reachable targets, also
at singular and redundant solutions (Fan and Yuan 2005, "On the quadratic convergence of
the Levenberg-Marquardt method without nonsingularity assumption", Computing 74; the
damping of roboticstoolbox's ``ik_LM`` "chan" method grows with the squared error instead).
``mu`` follows the gain ratio of each step (Nielsen's update); a step is accepted only
when the true forward kinematics at the new joints has a smaller error. Joint limits are
kept by projecting every trial onto the limit box; a joint held at a limit whose step
points outward is frozen and the step recomputed with the others; revolute joints whose
range spans a full turn wrap instead.

A target is `converged` only when the forward kinematics at the returned joints, evaluated
afresh after the iterations, is within `tol_position` (and `tol_rotation` for poses).
Everything else is reported with its reason (`STATUS`): a stationary point with a remaining error
(``unreachable``: out of reach, or a local minimum from that seed), a joint held at its
limit (``joint-limit``), or the iteration budget spent (``max-iterations``). Converged
targets at a configuration whose (scaled) Jacobian has a condition number above
`singular_threshold` are marked ``near-singular``: the tool is where it should be, but the
joints are sensitive to the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.ik_checks import check_seed, check_targets
from kinecal.kinematics.serial.ik_lm import (
    CONVERGED,
    Problem,
    condition_numbers,
    pose_error,
    run,
)
from kinecal.kinematics.serial.ik_one import run_one

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "STATUS",
    "IKResult",
    "characteristic_length",
    "default_tol_position",
    "pose_error",
    "solve_ik",
]

Array = NDArray[np.float64]

#: iteration budget of each random restart (roboticstoolbox's ik_LM: 30 per search)
RESTART_ITERATIONS = 30

#: per-target outcome of `solve_ik`; the first two are converged
STATUS = {
    "converged": "the tool is at the target within the tolerances",
    "near-singular": "converged, at a configuration close to a singularity (joints sensitive "
                     "to the target)",
    "unreachable": "stopped at a remaining error (target out of reach, or a local minimum "
                   "from this seed)",
    "joint-limit": "stopped with a joint held at its limit before reaching the target",
    "max-iterations": "the iteration budget ran out while the error was still falling",
}


@dataclass(frozen=True, repr=False)
class IKResult:
    """Outcome of `solve_ik`, one entry per target.

    Attributes
    ----------
    q : ndarray, shape (N, n_joints)
        Joint values (rad; prismatic joints in the length unit), within the joint limits.
        For targets that did not converge: the best joints found.
    converged : ndarray of bool, shape (N,)
        True where the fresh forward kinematics at `q` meets the tolerances.
    status : ndarray of str, shape (N,)
        One of `STATUS` per target.
    position_error : ndarray, shape (N,)
        Distance from the tool point at `q` to the target (length unit).
    rotation_error : ndarray, shape (N,)
        Angle between the tool frame at `q` and the target frame (rad); NaN for position
        targets.
    iterations : ndarray of int, shape (N,)
        Iterations used (over all restart attempts).
    condition : ndarray, shape (N,)
        Condition number of the scaled joint Jacobian at `q` (inf at an exact singularity).
    restarts : ndarray of int, shape (N,)
        Random restart attempts made for the target (0 when the seed converged).
    tol_position, tol_rotation : float
        The tolerances applied (length unit, rad).
    outputs : {"position", "pose"}
        Kind of targets.
    """

    q: Array
    converged: NDArray[np.bool_]
    status: NDArray[np.str_]
    position_error: Array
    rotation_error: Array
    iterations: NDArray[np.int_]
    condition: Array
    tol_position: float
    tol_rotation: float
    outputs: str
    restarts: NDArray[np.int_] = field(default_factory=lambda: np.zeros(0, dtype=int))
    length_unit: str = ""

    def __repr__(self) -> str:
        return (f"<IKResult {self.q.shape[0]} {self.outputs} targets: "
                f"{int(np.count_nonzero(self.converged))} converged>")

    def __len__(self) -> int:
        return int(self.q.shape[0])

    @property
    def success_rate(self) -> float:
        """Fraction of converged targets (0 for no targets)."""
        return float(self.converged.mean()) if len(self) else 0.0

    def counts(self) -> dict[str, int]:
        """Number of targets per status (every status listed, zeros included)."""
        return {s: int(np.count_nonzero(self.status == s)) for s in STATUS}

    def summary(self) -> str:
        """One line per status with a count, and the largest errors of converged targets."""
        n = len(self)
        unit = self.length_unit or "length unit"
        lines = [f"{int(self.converged.sum())} of {n} {self.outputs} targets converged "
                 f"(tolerance {self.tol_position:.3g} {unit}"
                 + (f", {self.tol_rotation:.3g} rad" if self.outputs == "pose" else "") + ")"]
        for s, c in self.counts().items():
            if c and s != "converged":
                lines.append(f"  {s}: {c} ({STATUS[s]})")
        if self.converged.any():
            ok = self.converged
            worst = f"largest position error {self.position_error[ok].max():.3g} {unit}"
            if self.outputs == "pose":
                worst += f", rotation {self.rotation_error[ok].max():.3g} rad"
            lines.append(f"  converged: {worst}; iterations mean "
                         f"{self.iterations[ok].mean():.1f}, max {self.iterations[ok].max()}")
        return "\n".join(lines)


def characteristic_length(model: SerialModel, params: ArrayLike | None = None) -> float:
    """A length that sets the scale of the arm: the sum of its absolute chain and tool
    lengths (an upper bound of the reach about the base; base-frame offsets excluded).

    Used to weight rotations against positions, to scale prismatic joints and for the
    round-off floor of the position tolerance. At least 1 length unit.
    """
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    length = getattr(model, "_chain_lengths", None)  # the mask, kept with the model
    if length is None:
        names = model.parameter_names
        length = ~model.is_angle() & np.array([not n.startswith("base.") for n in names])
        if isinstance(getattr(model, "__dict__", None), dict):
            model.__dict__["_chain_lengths"] = length
    return float(max(np.abs(p[length]).sum(), 1.0))


def default_tol_position(model: SerialModel, params: ArrayLike | None = None) -> float:
    """Default position tolerance: 1e-9 mm in the model's unit, or 64 round-off units of
    the arm's `characteristic_length` when that is larger (very large machines)."""
    return _tol_of_length(model, characteristic_length(model, params))


def _tol_of_length(model: SerialModel, length: float) -> float:
    nm = 1e-9 if model.length_unit == "mm" else 1e-12  # 1e-9 mm
    return max(nm, 64.0 * _EPS * length)


_EPS = float(np.finfo(float).eps)


def solve_ik(
    model: SerialModel,
    targets: ArrayLike,
    q0: ArrayLike | None = None,
    *,
    params: ArrayLike | None = None,
    tol_position: float | None = None,
    tol_rotation: float = 1e-9,
    max_iterations: int = 100,
    rotation_weight: float | None = None,
    restarts: int = 0,
    rng: int | np.random.Generator | None = None,
    singular_threshold: float = 1e3,
) -> IKResult:
    """Joint values that put the tool at each target (batch Levenberg-Marquardt).

    Parameters
    ----------
    model : SerialModel
        The arm (any convention; base and tool frames included).
    targets : array_like, shape (N, 3) or (N, 4, 4)
        Tool-point positions (3-DOF targets, length unit) or tool frames ``tool2base``
        (6-DOF targets), in the measurement frame.
    q0 : array_like, shape (N, n_joints) or (n_joints,), optional
        Seed joints per target (rad; prismatic: length unit); the solver converges to the
        solution nearest the seed when the seed lies in its basin (nearest branch). Default:
        the middle of the joint limits. Seeds outside the limits are clipped to them.
    params : array_like, shape (n_params,), optional
        Parameter vector (e.g. a calibrated one); nominal if omitted.
    tol_position : float, optional
        Largest accepted position error (length unit); default `default_tol_position`
        (1e-9 mm).
    tol_rotation : float
        Largest accepted rotation error (rad) of pose targets.
    max_iterations : int
        Iteration budget per target and attempt.
    rotation_weight : float, optional
        Length units per rad of rotation error in the least-squares step (default: the
        arm's `characteristic_length`). It shapes the path, not the tolerances.
    restarts : int
        Targets that did not converge are solved again from this many random joint
        vectors within the limits (drawn with `rng`, all in one batch, at most
        `RESTART_ITERATIONS` each); the converged attempt nearest the seed is kept, else
        the attempt with the smallest error. Default 0: a solution far from the seed
        (another branch) is never substituted.
    rng : int or Generator, optional
        Randomness of the restarts (same seed, same result).
    singular_threshold : float
        Condition number of the scaled Jacobian above which a converged target is marked
        ``near-singular``.

    Returns
    -------
    IKResult

    Raises
    ------
    InputError
        Bad shapes, non-finite values, non-rigid target frames, bad options.
    """
    t = check_targets(targets)
    N = t.shape[0]
    q = check_seed(model, q0, N)
    p = None
    if params is not None:
        p = np.asarray(params, dtype=float)
        if p.shape != (model.n_params,) or not np.isfinite(p).all():
            raise InputError(f"params: expected one finite parameter vector ({model.n_params},), "
                             f"got shape {p.shape}")
    length = characteristic_length(model, p)
    tol_p = _tol_of_length(model, length) if tol_position is None else float(tol_position)
    if not tol_p > 0:
        raise InputError(f"tol_position: expected > 0, got {tol_position}")
    if not tol_rotation > 0:
        raise InputError(f"tol_rotation: expected > 0, got {tol_rotation}")
    if int(max_iterations) < 1:
        raise InputError(f"max_iterations: expected >= 1, got {max_iterations}")
    if int(restarts) < 0:
        raise InputError(f"restarts: expected >= 0, got {restarts}")
    w = length if rotation_weight is None else float(rotation_weight)
    if not w > 0:
        raise InputError(f"rotation_weight: expected > 0, got {rotation_weight}")
    pose = t.ndim == 3
    tol_r = float(tol_rotation) if pose else np.inf
    prob = Problem(model, p, t, w, length)
    # one target: the same iterations on plain floats and the unrolled single-pose chain
    chain = model._single(q[0], p, None) if N == 1 and hasattr(model, "_single") else None
    if chain is not None:
        one = run_one(prob, chain[0], chain[1], tol_p, tol_r, int(max_iterations))
        if not restarts or (one[1] <= tol_p and one[2] <= tol_r):
            return _finish_one(prob, one, tol_p, tol_r, singular_threshold)
        q, pos, rot = np.array([one[0]]), np.array([one[1]]), np.array([one[2]])
        iters, status = np.array([one[3]]), np.array([one[4]], dtype="<U14")
    else:
        q, pos, rot, iters, status = run(prob, prob.project(q), tol_p, tol_r,
                                         int(max_iterations))
    tries = np.zeros(N, dtype=int)
    bad = np.flatnonzero(~np.isin(status, CONVERGED))
    R = int(restarts)
    if R and bad.size:
        # all restarts of all unconverged targets in one batch: R random seeds per target
        # (target-major order), each with RESTART_ITERATIONS at most
        gen = np.random.default_rng(rng)
        seeds = _random_joints(model, bad.size * R, gen)
        sub = Problem(model, p, np.repeat(t[bad], R, axis=0), w, length)
        q2, pos2, rot2, it2, st2 = run(sub, sub.project(seeds), tol_p, tol_r,
                                       min(int(max_iterations), RESTART_ITERATIONS))
        q2 = q2.reshape(bad.size, R, -1)
        ok2 = np.isin(st2, CONVERGED).reshape(bad.size, R)
        cost2 = (pos2 ** 2 + (w * rot2) ** 2 if pose else pos2 ** 2).reshape(bad.size, R)
        # a converged restart nearest the seed, else the attempt with the lowest error
        dist = np.linalg.norm(q2 - q[bad][:, None, :], axis=2)
        pick = np.where(ok2.any(axis=1), np.argmin(np.where(ok2, dist, np.inf), axis=1),
                        np.argmin(cost2, axis=1))
        k = np.arange(bad.size) * R + pick
        cost_old = pos[bad] ** 2 + (w * rot[bad]) ** 2 if pose else pos[bad] ** 2
        better = ok2[np.arange(bad.size), pick] | (cost2[np.arange(bad.size), pick] < cost_old)
        b, kb = bad[better], k[better]
        q[b], pos[b], rot[b], status[b] = q2.reshape(-1, q.shape[1])[kb], pos2[kb], rot2[kb], \
            st2[kb]
        iters[bad] += it2.reshape(bad.size, R).sum(axis=1)
        tries[bad] = R
    return _finish(prob, q, iters, tries, status, tol_p, tol_r, singular_threshold)


def _finish_one(prob: Problem, one: tuple, tol_p: float, tol_r: float, threshold: float
                ) -> IKResult:
    """`_finish` of one target from `run_one`'s floats (its errors are the forward
    kinematics at the returned joints)."""
    q, pos, rot, it, status, G = one
    converged = pos <= tol_p and rot <= tol_r
    ev = np.linalg.eigvalsh(np.array(G)).tolist()  # `gram_condition` of one matrix
    hi, lo = ev[-1], max(ev[0], 0.0)
    cond = math.sqrt(hi / lo) if lo > 0.0 and hi > 0.0 else math.inf
    if converged:
        status = "near-singular" if cond > threshold else "converged"
    elif status in CONVERGED:
        status = "unreachable"
    if status == "unreachable" and any(
            (x <= lo + 1e-12 * c or x >= hi - 1e-12 * c) and not w for x, lo, hi, c, w in
            zip(q, prob.lo.tolist(), prob.hi.tolist(), prob.col.tolist(), prob.wrap.tolist(),
                strict=True)):
        status = "joint-limit"
    errors = np.array([[pos], [rot if prob.pose else np.nan], [cond]])
    return IKResult(
        q=np.array([q]), converged=np.array([converged]),
        status=np.array([status], dtype="<U14"), position_error=errors[0],
        rotation_error=errors[1], iterations=np.array([it]), condition=errors[2],
        tol_position=tol_p,
        tol_rotation=tol_r if prob.pose else np.nan,
        outputs="pose" if prob.pose else "position", restarts=np.zeros(1, dtype=int),
        length_unit=getattr(prob.model, "length_unit", ""))


def _random_joints(model: SerialModel, n: int, gen: np.random.Generator) -> Array:
    lim = np.array(model.joint_limits, dtype=float)
    rev = ~model.is_prismatic()
    lim[rev] = np.clip(lim[rev], -np.pi, np.pi)
    return gen.uniform(lim[:, 0], lim[:, 1], size=(n, model.n_joints))


def _finish(prob: Problem, q: Array, iters: NDArray[np.int_], tries: NDArray[np.int_],
            status: NDArray[np.str_], tol_p: float, tol_r: float, threshold: float
            ) -> IKResult:
    """Fresh forward kinematics at the final joints decides `converged`."""
    N = q.shape[0]
    _, pos, rot, J = prob.evaluate(q, np.arange(N))
    converged = (pos <= tol_p) & (rot <= tol_r)
    cond = condition_numbers(J) if N else np.zeros(0)
    status = status.copy()
    # never a wrong answer marked converged; a converged target is never reported failed
    status[~converged & np.isin(status, CONVERGED)] = "unreachable"
    status[converged] = np.where(cond[converged] > threshold, "near-singular", "converged")
    at_limit = (((q <= prob.lo + 1e-12 * prob.col) | (q >= prob.hi - 1e-12 * prob.col))
                & ~prob.wrap).any(1)
    status[(status == "unreachable") & at_limit] = "joint-limit"
    return IKResult(
        q=q, converged=converged, status=status, position_error=pos,
        rotation_error=rot if prob.pose else np.full(N, np.nan), iterations=iters,
        condition=cond, tol_position=tol_p, tol_rotation=tol_r if prob.pose else np.nan,
        outputs="pose" if prob.pose else "position", restarts=tries,
        length_unit=getattr(prob.model, "length_unit", ""),
    )
