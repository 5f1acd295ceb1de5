"""One pose in plain Python floats: the folded chain of one parameter vector written out as
straight-line code.

For a single configuration numpy's cost per call (1-3 us for a 4 x 4 product) is the whole
cost of forward kinematics; Python's own float arithmetic costs 10-20 ns an operation. So
`unroll` writes the chain of `kinecal.kinematics.serial.single.SingleChain` (the constant
transforms between the joints, each joint's axis and offset) as the source of a Python
function of the joint values, with every constant inlined (``repr``: the exact float),
products with exact zeros left out and products of constants folded, and compiles it once
per parameter vector:

* a joint about an axis of its frame (D-H, Craig, Hayati: z; URDF: x, y, z, also negated)
  mixes two columns of the rotation (12 products); a general axis multiplies by its
  Rodrigues matrix ``c I + s [u]x + (1 - c) u u^T``; a prismatic joint moves the origin
  along its axis;
* the constant after the joint multiplies the frame (products with its zeros dropped; its
  rotation entries within 1e-15 of 0 or +-1 taken as such: the cosine of a right angle,
  6e-17, would cost a product and change nothing above round-off);
* with the Jacobian, each joint's axis ``u`` and origin ``o`` in the measurement frame are
  kept and its column is ``u x (p - o)`` (and ``u``) for a revolute joint, ``u`` for a
  prismatic one, as `kinecal.kinematics.serial.sweep` differentiates.

The result equals the batch path's to round-off (tests/kinematics/test_single_pose.py:
1e-12 relative): the same products, summed in another order.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["unroll"]

Array = NDArray[np.float64]
Value = float | str  # a constant, or the name of a variable of the generated code


class _Code:
    """Lines of a generated function and the arithmetic that writes them (constants
    folded, exact zeros dropped)."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.count = 0

    def name(self, expr: str) -> str:
        name = f"v{self.count}"
        self.count += 1
        self.lines.append(f"    {name} = {expr}")
        return name

    def lin(self, terms: Sequence[tuple], const: float = 0.0) -> Value:
        """``sum(k * a * b) + const`` over terms ``(a, b)`` or ``(a, b, k)`` (``a``, ``b``
        constants or names, ``k`` a constant): a constant when every term is, else the
        name of a new variable (or of the one variable it equals)."""
        parts = []
        c = float(const)
        for term in terms:
            a, b = term[0], term[1]
            k = float(term[2]) if len(term) > 2 else 1.0
            if isinstance(a, float):
                a, b = b, a
            if isinstance(a, float):  # both constants: folded
                c += k * a * b
                continue
            if isinstance(b, float):
                k *= b
                b = None
            if k == 0.0:
                continue
            factor = a if b is None else f"{a} * {b}"
            parts.append(factor if k == 1.0 else f"-{factor}" if k == -1.0 else
                         f"{factor} * {k!r}")
        if not parts:
            return c
        if c == 0.0 and len(parts) == 1 and parts[0].isidentifier():
            return parts[0]
        expr = " + ".join(parts)
        return self.name(expr + (f" + {c!r}" if c != 0.0 else ""))


def _axis(u: Array) -> tuple[int, float] | None:
    """``(index, sign)`` when `u` is a coordinate axis or its negative, else None."""
    nz = np.flatnonzero(u)
    if nz.size == 1 and abs(u[nz[0]]) == 1.0:
        return int(nz[0]), float(u[nz[0]])
    return None


def _rotate(code: _Code, R: list, u: Array, c: str, s: str) -> list:
    """``R @ Rot(u, t)`` with ``c = cos t``, ``s = sin t``."""
    ax = _axis(u)
    if ax is not None:  # two columns mix: about e_x (1, 2), e_y (2, 0), e_z (0, 1)
        i, sign = ax
        a, b = (i + 1) % 3, (i + 2) % 3
        out = [row[:] for row in R]
        for r in range(3):
            out[r][a] = code.lin([(c, R[r][a]), (s, R[r][b], sign)])
            out[r][b] = code.lin([(c, R[r][b]), (s, R[r][a], -sign)])
        return out
    u = [float(x) for x in u]
    K = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]]
    omc = code.lin([(c, -1.0)], 1.0)  # 1 - cos t
    M = [[code.lin([(c, 1.0 if i == j else 0.0), (s, K[i][j]), (omc, u[i] * u[j])])
          for j in range(3)] for i in range(3)]
    return [[code.lin([(R[r][m], M[m][j]) for m in range(3)]) for j in range(3)]
            for r in range(3)]


def _snap(T: Array) -> Array:
    """`T` with the rotation entries within `ROUND_OFF` of 0 or +-1 set to them: the
    cosine of a right angle is 6e-17, not 0, and a product with it would cost as much as
    any other while adding nothing above round-off (a unit-size entry's own round-off is
    1.1e-16)."""
    T = np.array(T, dtype=float)
    R = T[..., :3, :3]
    for target in (0.0, 1.0, -1.0):
        R[np.abs(R - target) <= ROUND_OFF] = target
    return T


#: rotation entries of the constant transforms this close to 0 or +-1 are taken as such
ROUND_OFF = 1e-15


def _source(first: Array, after: Array, axis: Array, revolute: NDArray[np.bool_],
            offset: Array, jacobian: str | None) -> str:
    """The function's source: ``f(q0, ..., q{n-1})`` returns the 12 entries of the tool
    frame's top 3 x 4 rows, row-major; with `jacobian` (``"pose"`` / ``"position"``) then
    the Jacobian's 6 (3) x n entries, row-major (``"pose"``: ``f(..., w=1.0)`` multiplies
    the rotation rows by ``w``, the weight of a least-squares step)."""
    n = len(axis)
    code = _Code()
    first, after = _snap(first), _snap(after)
    R: list = [[float(first[i, j]) for j in range(3)] for i in range(3)]
    t: list = [float(first[i, 3]) for i in range(3)]
    before = []
    for k in range(n):
        ang = code.lin([(f"q{k}", 1.0)], float(offset[k]))
        before.append((R, t))
        if revolute[k]:
            c, s = code.name(f"cos({ang})"), code.name(f"sin({ang})")
            R = _rotate(code, R, axis[k], c, s)
        else:  # along the axis: the origin moves by t R u
            d = [code.lin([(R[i][m], float(axis[k][m])) for m in range(3)]) for i in range(3)]
            t = [code.lin([(ang, d[i]), (t[i], 1.0)]) for i in range(3)]
        C = after[k]
        R, t = ([[code.lin([(R[i][m], float(C[m, j])) for m in range(3)]) for j in range(3)]
                 for i in range(3)],
                [code.lin([(R[i][m], float(C[m, 3])) for m in range(3)] + [(t[i], 1.0)])
                 for i in range(3)])
    out = [v for i in range(3) for v in (*R[i], t[i])]
    if jacobian is not None:
        rows: list[list[Value]] = [[] for _ in range(6 if jacobian == "pose" else 3)]
        for k, (Rb, tb) in enumerate(before):
            u = [code.lin([(Rb[i][m], float(axis[k][m])) for m in range(3)]) for i in range(3)]
            if revolute[k]:  # u x (p - o)
                d = [code.lin([(t[i], 1.0), (tb[i], -1.0)]) for i in range(3)]
                lin = [code.lin([(u[(i + 1) % 3], d[(i + 2) % 3]),
                                 (u[(i + 2) % 3], d[(i + 1) % 3], -1.0)]) for i in range(3)]
                rot = u
            else:
                lin, rot = u, [0.0, 0.0, 0.0]
            for i in range(3):
                rows[i].append(lin[i])
                if jacobian == "pose":  # the rotation rows times the weight w
                    rows[3 + i].append(code.lin([(rot[i], "w")]))
        out += [v for row in rows for v in row]
    args = ", ".join(f"q{k}" for k in range(n))
    body = "\n".join(code.lines)
    values = ", ".join(v if isinstance(v, str) else repr(v) for v in out)
    weight = ", w=1.0" if jacobian == "pose" else ""
    return f"def f({args}{weight}, cos=cos, sin=sin):\n{body}\n    return ({values},)\n"


def unroll(first: Array, after: Array, axis: Array, revolute: NDArray[np.bool_],
           offset: Array, jacobian: str | None = None) -> Callable[..., tuple[float, ...]]:
    """Compile the chain ``first, (joint k, after[k]) ...`` into a function of the joint
    values (`_source`).

    Parameters
    ----------
    first : ndarray, shape (4, 4)
        The constant transform before the first joint.
    after : ndarray, shape (n, 4, 4)
        The constant transform after each joint.
    axis : ndarray, shape (n, 3)
        Each joint's unit axis in the frame before its motion.
    revolute : ndarray of bool, shape (n,)
    offset : ndarray, shape (n,)
        Added to each joint's value (rad, or length for a prismatic joint).
    jacobian : {"pose", "position"}, optional
        Also return the joint Jacobian's entries.

    Returns
    -------
    callable
        ``f(q_1, ..., q_n) -> tuple`` of floats (`_source`).
    """
    namespace = {"cos": math.cos, "sin": math.sin}
    exec(_source(first, after, axis, revolute, offset, jacobian), namespace)
    return namespace["f"]
