"""One inverse-kinematics target on plain Python floats.

A controller asking for one corrected target calls `kinecal.kinematics.serial.ik.solve_ik`
with one pose; numpy then costs more per call (1-10 us for 6 x 6 arrays) than the
arithmetic. `run_one` runs the iterations of `kinecal.kinematics.serial.ik_lm.run` --
the same damped step ``J^T (J J^T + lam I)^-1 e`` (or ``(J^T J + lam I)^-1 J^T e`` with
more rows than joints), the damping ``lam = mu |e| L`` with Nielsen's update, the same
acceptance, stall and stopping rules, joint limits projected and full-turn joints wrapped
-- on lists of floats, with the model's unrolled chain
(`kinecal.kinematics.serial.unrolled`) for the pose and its joint Jacobian and a Cholesky
factor of the small damped matrix. A step with a joint held at its limit, and a rotation
error near pi, go through the numpy code of `ik_lm` (rare). The answer equals the batch
path's to round-off (tests/kinematics/test_single_pose.py: 1e-12).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.ik_lm import (
    _FTOL,
    _MU0,
    _MU_MAX,
    _MU_MIN,
    _STALL,
    _bounded_step,
    _rotation_log,
)

if TYPE_CHECKING:
    from kinecal.kinematics.serial.ik_lm import Problem

__all__ = ["run_one"]

Array = NDArray[np.float64]


class _Target:
    """What an iteration needs of the problem, as floats."""

    def __init__(self, prob: Problem, chain) -> None:
        self.prob = prob
        self.f = chain.unrolled("pose" if prob.pose else "position")
        self.n = n = len(chain.offset)
        self.rows = prob.rows
        self.step = _compiled("step", prob.rows, n)
        self.predict = _compiled("predict", prob.rows, n)
        self.gram = _compiled("gram", prob.rows, n)
        t = prob.targets[0]
        self.pose = prob.pose
        if self.pose:
            self.p_t = t[:3, 3].tolist()
            self.R_t = t[:3, :3].tolist()
        else:
            self.p_t = t.tolist()
        self.w = float(prob.w)
        self.col = prob.col.tolist()
        self.scaled = prob.scaled
        self.lo, self.hi = prob.lo.tolist(), prob.hi.tolist()
        self.wrap = prob.wrap.tolist()
        self.clipped = [k for k, w in enumerate(self.wrap) if not w]  # no wrapping

    def evaluate(self, q: list[float]) -> tuple[list[float], float, float, float, tuple]:
        """Weighted error ``(rows,)``, its squared norm (the cost), position and rotation
        errors, and the scaled, weighted Jacobian (row-major, ``rows x n``) at joints
        `q`."""
        v = self.f(*q, self.w) if self.pose else self.f(*q)
        J = v[12:]  # rotation rows weighted by the unrolled chain
        if self.scaled:
            col, n = self.col, self.n
            J = tuple(x * col[i % n] for i, x in enumerate(J))
        px, py, pz = self.p_t
        dx, dy, dz = px - v[3], py - v[7], pz - v[11]
        p2 = dx * dx + dy * dy + dz * dz
        if not self.pose:
            return [dx, dy, dz], p2, math.sqrt(p2), 0.0, J
        w = self.w
        rx, ry, rz = _log(self.R_t, v)
        ex, ey, ez = w * rx, w * ry, w * rz
        return ([dx, dy, dz, ex, ey, ez], p2 + (ex * ex + ey * ey + ez * ez), math.sqrt(p2),
                math.sqrt(rx * rx + ry * ry + rz * rz), J)

    def array(self, J: tuple) -> Array:
        """`J` as the batch's ``(rows, n)`` array."""
        return np.array(J).reshape(self.rows, self.n)

    def advance(self, q: list[float], ds: list[float]) -> tuple[list[float], list[float]]:
        """The trial joints ``q + ds * col`` brought into the limits (`project`), and the
        step actually taken (a wrapped joint: its own step)."""
        qt, taken = [], []
        for x, s, c, lo, hi, wrap in zip(q, ds, self.col, self.lo, self.hi, self.wrap,
                                         strict=True):
            y = x + s * c
            if y < lo or y > hi:
                y = self.project([y], [(lo, hi, wrap)])[0]
            qt.append(y)
            taken.append(s if wrap else (y - x) / c)
        return qt, taken

    def project(self, q: list[float], bounds=None) -> list[float]:
        """`ik_lm.Problem.project` of one joint vector (`bounds`: ``(lo, hi, wrap)`` per
        joint, default the problem's)."""
        out = []
        turn = 2.0 * math.pi
        bounds = bounds or zip(self.lo, self.hi, self.wrap, strict=True)
        for x, (lo, hi, wrap) in zip(q, bounds, strict=True):
            if wrap and x > hi:
                x -= turn * math.ceil((x - hi) / turn)
            elif wrap and x < lo:
                x += turn * math.ceil((lo - x) / turn)
            out.append(lo if x < lo else hi if x > hi else x)
        return out


def _log(Rt: list[list[float]], v: tuple) -> tuple[float, float, float]:
    """``log(R_target R^T)`` (`ik_lm._rotation_log` of one rotation) with ``R`` the tool
    frame in the unrolled chain's output `v`."""
    r00, r01, r02, _, r10, r11, r12, _, r20, r21, r22 = v[:11]
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = Rt
    m21 = a20 * r10 + a21 * r11 + a22 * r12
    m12 = a10 * r20 + a11 * r21 + a12 * r22
    m02 = a00 * r20 + a01 * r21 + a02 * r22
    m20 = a20 * r00 + a21 * r01 + a22 * r02
    m10 = a10 * r00 + a11 * r01 + a12 * r02
    m01 = a00 * r10 + a01 * r11 + a02 * r12
    tr = (a00 * r00 + a01 * r01 + a02 * r02) + (a10 * r10 + a11 * r11 + a12 * r12) + (
        a20 * r20 + a21 * r21 + a22 * r22)
    sx, sy, sz = 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01)
    c = 0.5 * (tr - 1.0)
    sn = math.sqrt(sx * sx + sy * sy + sz * sz)
    if c < 0.0 and sn < 0.5:  # near pi: through the quaternion (numpy)
        R = np.array([v[0:3], v[4:7], v[8:11]])
        return tuple(_rotation_log((np.array(Rt) @ R.T)[None])[0].tolist())
    if sn > 0.0:
        k = math.atan2(sn, c) / sn
        return sx * k, sy * k, sz * k
    return sx, sy, sz


def _unpack(r: int, n: int) -> list[str]:
    """Lines unpacking `J` (row-major, ``r x n``) into ``j{row}_{joint}``."""
    return ["    " + ", ".join(f"j{i}_{k}" for i in range(r) for k in range(n)) + ", = J"]


def _step_source(r: int, n: int) -> str:
    """Source of ``step(J, e, lam)``: `ik_lm._step` of one target written out for a
    Jacobian of `r` rows and `n` joints (`J` row-major, `e` the error, both weighted): the
    damped small matrix, its Cholesky factor and the two triangular solves; None when the
    matrix is not positive definite (the caller then takes numpy's solver)."""
    lines = ["def step(J, e, lam, sqrt=sqrt):", *_unpack(r, n),
             "    " + ", ".join(f"e{i}" for i in range(r)) + ", = e"]
    if r <= n:  # J^T (J J^T + lam I)^-1 e: minimum norm
        m = r
        entry = [[" + ".join(f"j{i}_{k} * j{j}_{k}" for k in range(n)) for j in range(m)]
                 for i in range(m)]
        rhs = [f"e{i}" for i in range(m)]
    else:  # (J^T J + lam I)^-1 J^T e
        m = n
        entry = [[" + ".join(f"j{k}_{i} * j{k}_{j}" for k in range(r)) for j in range(m)]
                 for i in range(m)]
        rhs = [" + ".join(f"j{k}_{i} * e{k}" for k in range(r)) for i in range(m)]
    for i in range(m):
        for j in range(i + 1):
            lines.append(f"    a{i}_{j} = {entry[i][j]}")
    trace = " + ".join(f"a{i}_{i}" for i in range(m))
    lines += [f"    d = 1e-14 * ({trace})", "    if lam > d:", "        d = lam"]
    for i in range(m):  # Cholesky: a = L L^T
        for j in range(i + 1):
            acc = "".join(f" - l{i}_{k} * l{j}_{k}" for k in range(j))
            if i == j:
                lines += [f"    s = a{i}_{i} + d{acc}", "    if not s > 0.0:",
                          "        return None", f"    l{i}_{i} = sqrt(s)"]
            else:
                lines.append(f"    l{i}_{j} = (a{i}_{j}{acc}) / l{j}_{j}")
    for i in range(m):
        acc = "".join(f" - l{i}_{k} * y{k}" for k in range(i))
        lines.append(f"    y{i} = ({rhs[i]}{acc}) / l{i}_{i}")
    for i in range(m - 1, -1, -1):
        acc = "".join(f" - l{k}_{i} * x{k}" for k in range(i + 1, m))
        lines.append(f"    x{i} = (y{i}{acc}) / l{i}_{i}")
    if r <= n:
        out = [" + ".join(f"j{i}_{k} * x{i}" for i in range(r)) for k in range(n)]
    else:
        out = [f"x{k}" for k in range(n)]
    lines.append("    return [" + ", ".join(out) + "]")
    return "\n".join(lines) + "\n"


def _predict_source(r: int, n: int) -> str:
    """Source of ``predict(J, e, d)``: ``|e - J d|^2`` for a Jacobian of `r` rows and `n`
    joints (row-major)."""
    lines = ["def predict(J, e, d):", *_unpack(r, n),
             "    " + ", ".join(f"d{k}" for k in range(n)) + ", = d"]
    for i in range(r):
        lines.append(f"    l{i} = e[{i}] - (" + " + ".join(f"j{i}_{k} * d{k}" for k in range(n))
                     + ")")
    lines.append("    return " + " + ".join(f"l{i} * l{i}" for i in range(r)))
    return "\n".join(lines) + "\n"


def _gram_source(r: int, n: int) -> str:
    """Source of ``gram(J)``: ``J J^T`` (rows <= joints) or ``J^T J`` as nested lists
    (`ik_lm.condition_numbers` takes its eigenvalues)."""
    lines = ["def gram(J):", *_unpack(r, n)]
    if r <= n:
        entry = [[" + ".join(f"j{i}_{k} * j{j}_{k}" for k in range(n)) for j in range(r)]
                 for i in range(r)]
    else:
        entry = [[" + ".join(f"j{k}_{i} * j{k}_{j}" for k in range(r)) for j in range(n)]
                 for i in range(n)]
    lines.append("    return [" + ", ".join("[" + ", ".join(row) + "]" for row in entry) + "]")
    return "\n".join(lines) + "\n"


_SOURCES = {"step": _step_source, "predict": _predict_source, "gram": _gram_source}
_COMPILED: dict[tuple[str, int, int], object] = {}


def _compiled(kind: str, r: int, n: int):
    """The compiled ``step`` or ``predict`` for `r` rows and `n` joints (cached)."""
    f = _COMPILED.get((kind, r, n))
    if f is None:
        namespace = {"sqrt": math.sqrt}
        exec(_SOURCES[kind](r, n), namespace)
        f = _COMPILED[kind, r, n] = namespace[kind]
    return f


def _any_blocked(t: _Target, q: list[float], ds: list[float]) -> bool:
    """Whether a joint that cannot wrap sits at a limit and the step points outward
    (`ik_lm._bounded_step` then freezes it)."""
    for k in t.clipped:
        x, s = q[k], ds[k]
        if (x <= t.lo[k] and s < 0) or (x >= t.hi[k] and s > 0):
            return True
    return False


def run_one(prob: Problem, chain, q: list[float], tol_p: float, tol_r: float, max_iter: int
            ) -> tuple[list[float], float, float, int, str, list[list[float]]]:
    """`ik_lm.run` for a problem of one target, on floats (module docstring); `chain` is
    the model's `kinecal.kinematics.serial.single.SingleChain` of the parameter vector and
    `q` the seed. Returns the joints, position and rotation errors there (the forward
    kinematics at the returned joints), iterations, status and the Gram matrix of the
    scaled, weighted Jacobian there (``J J^T`` or ``J^T J``, as `ik_lm.condition_numbers`
    forms it)."""
    t = _Target(prob, chain)
    q = t.project(q)
    e, cost, pos, rot, J = t.evaluate(q)
    status, it = "max-iterations", 0
    mu, nu, stall = _MU0, 2.0, 0
    if pos <= tol_p and rot <= tol_r:
        status, max_iter = "converged", 0
    step, predict, length = t.step, t.predict, prob.length
    for _ in range(max_iter):
        lam = mu * math.sqrt(cost) * length
        ds = step(J, e, lam)
        if ds is None or (t.clipped and _any_blocked(t, q, ds)):  # the batch's numpy path
            ds = _bounded_step(prob, t.array(J)[None], np.array([e]), np.array([lam]),
                               np.array([q]))[0].tolist()
        qt, taken = t.advance(q, ds)
        pred = cost - predict(J, e, taken)
        et, ct, post, rott, Jt = t.evaluate(qt)
        it += 1
        gain = cost - ct
        rho = gain / pred if pred > 0 else -1.0
        accept = gain > 0 and rho > 1e-4
        if accept:  # Nielsen's update, as in `run`
            mu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), _MU_MIN)
            nu = 2.0
        else:
            mu, nu = mu * nu, nu * 2.0
        stall = 0 if accept and gain > _FTOL * cost else stall + 1
        if accept:
            q, e, cost, pos, rot, J = qt, et, ct, post, rott, Jt
        if accept and post <= tol_p and rott <= tol_r:
            status = "converged"
            break
        if stall >= _STALL or mu > _MU_MAX:
            status = "unreachable"
            break
    return q, pos, rot, it, status, t.gram(J)
