"""Kernels that compose a serial chain's elementary motions over a chunk of poses.

`SerialModel` hands each kernel one chunk of joint readings (sized for the cache by
`chunk_size`) and writes the chunk's result into its output; nothing here holds more
than one chunk. Three kernels share one representation:

* `point_chain` (positions only): the tool point is carried from the flange back to the
  measurement frame, ``p = M_1 (M_2 (... M_m p_tool))``. A translation along a frame
  axis is then one addition on one coordinate and a rotation four products on two, where
  composing frames forwards moves three axes and an origin (about 3.5x fewer operations
  for a D-H chain); no rotation stacks are built.
* `frame_chain` (poses, and the frames the identification Jacobian needs): the moving
  frame's three axes and origin carried forwards from the measurement frame, optionally
  recording the axis and origin before every motion.
* `joint_trig`: cosine and sine of every revolute joint's angle for the whole chunk in a
  few vectorised calls, by the tangent half-angle formulas ``t = tan(x / 2)``,
  ``cos x = (1 - t^2) / (1 + t^2)``, ``sin x = 2 t / (1 + t^2)``: one tangent instead of a
  sine and a cosine (numpy vectorises the float64 tangent; its float64 sine and cosine
  run element by element, 8x slower). Absolute error below 3e-16 against 6e-17 for
  libm's sine and cosine, i.e. 3e-13 mm at a one-metre reach.

Every coordinate is either an array broadcastable to ``(*batch, n)`` or a plain float,
combined by the folded arithmetic of `kinecal.kinematics.serial.folded` (an exact float zero or
one folds away: the constant part of a chain costs nothing per pose).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.folded import add, axpy, comb, dense, mul, sub, turn
from kinecal.kinematics.serial.motions import ROTATION, TRANSLATION, Motion

__all__ = ["CHUNK_ELEMENTS", "chunk_size", "chunks", "frame_chain", "joint_trig",
           "motion_values", "point_chain", "positions", "transforms"]

Array = NDArray[np.float64]
#: poses (times parameter vectors) per chunk: a few hundred bytes of live coordinates per
#: pose stay inside a 1-2 MB L2 cache; measured best for the UR5 between 4096 and 16384
CHUNK_ELEMENTS = 8192


def chunk_size(n_poses: int, batch: int = 1, elements: int = CHUNK_ELEMENTS) -> int:
    """Poses per chunk for `batch` parameter vectors (at least 16; `elements` 0: all).

    The poses are split into chunks of equal size: a last chunk of a few poses would cost
    as much Python overhead as a full one (10^4 UR5 poses in chunks of 8192 and 1808:
    189 ns a pose for the 4 x 4 frames; in two of 5000: 90 ns).
    """
    if elements <= 0:
        return max(n_poses, 1)
    most = max(16, min(n_poses, elements // max(batch, 1)))
    count = -(-n_poses // most)  # chunks of at most `most` poses
    return max(16, -(-n_poses // max(count, 1)))


# ---------------------------------------------------------------- values and trig
def motion_values(motions: Sequence[Motion], motion_index: NDArray[np.intp], p: Array
                  ) -> tuple[list, list]:
    """Per motion: its parameter value and whether it can be skipped.

    Parameters
    ----------
    motions : sequence of Motion
    motion_index : ndarray, shape (m,)
        Parameter index of each motion (-1: a constant, `Motion.const`).
    p : ndarray, shape (n_params,) or (P, n_params)

    Returns
    -------
    values : list
        Plain floats for one parameter vector, arrays ``(P, 1)`` for a population
        (constants: plain floats).
    skip : list of bool
        True where the motion is the identity for every parameter vector (value exactly
        zero and no joint reading).
    """
    if p.ndim == 1:
        flat = p.tolist()
        values = [flat[k] for k in motion_index]
        for i in np.flatnonzero(motion_index < 0).tolist():
            values[i] = motions[i].const
        nonzero = [v != 0.0 for v in values]
    else:
        cols = p[..., motion_index]  # (P, m)
        values = [cols[..., i][..., None] for i in range(len(motions))]
        nonzero = np.any(cols != 0.0, axis=0).tolist()
        for i in np.flatnonzero(motion_index < 0).tolist():
            values[i], nonzero[i] = motions[i].const, motions[i].const != 0.0
    skip = [m.joint is None and not nz for m, nz in zip(motions, nonzero, strict=True)]
    return values, skip


def joint_trig(motions: Sequence[Motion], values: list, qT: Array) -> dict[int, tuple]:
    """Cosine and sine of every revolute joint's angle ``value + q`` over a chunk.

    Parameters
    ----------
    motions : sequence of Motion
    values : list
        From `motion_values`.
    qT : ndarray, shape (n_joints, n)
        Joint readings of the chunk, joint-major.

    Returns
    -------
    dict
        Motion position -> ``(cos, sin)``, each ``(*batch, n)``.
    """
    trig = {}
    for i, m in enumerate(motions):
        if m.joint is None or m.kind != ROTATION:
            continue
        # one joint at a time: (n,) temporaries stay below the allocator's mmap threshold,
        # so a call does not fault fresh pages in for a (joints, n) block (10^4 poses: 1.7x)
        half = qT[m.joint] + values[i]  # (*batch, n)
        half *= 0.5
        t = np.tan(half, out=half)
        d = t * t
        c = 1.0 - d
        d += 1.0
        np.reciprocal(d, out=d)  # 1 / (1 + t^2)
        c *= d
        d *= t
        d *= 2.0  # sine: 2 t / (1 + t^2)
        trig[i] = (c, d)
    return trig


def _cos_sin(value) -> tuple:
    # numpy's for floats too: a parameter vector gives the same bits alone or in a population
    if isinstance(value, float):
        return float(np.cos(value)), float(np.sin(value))
    return np.cos(value), np.sin(value)


def _motion_cs(i: int, m: Motion, values: list, trig: dict) -> tuple:
    return trig[i] if m.joint is not None else _cos_sin(values[i])


def _motion_shift(m: Motion, value, qT: Array):
    return value if m.joint is None else qT[m.joint] + value


# ---------------------------------------------------------------- kernels
def point_chain(motions: Sequence[Motion], values: list, skip: list, qT: Array,
                trig: dict, point: Sequence | None = None) -> list:
    """Tool point in the measurement frame, composed from the flange backwards.

    Parameters
    ----------
    motions, values, skip
        The chain (`motion_values`).
    qT : ndarray, shape (n_joints, n)
        Joint readings of the chunk.
    trig : dict
        `joint_trig` of the chunk.
    point : sequence of 3, optional
        Start point beyond the last motion (floats or per-pose arrays; default the
        origin: the tool point is part of the motions).

    Returns
    -------
    list of 3
        x, y, z coordinates (arrays broadcastable to ``(*batch, n)``, or floats).
    """
    p = [0.0, 0.0, 0.0] if point is None else list(point)
    for i in range(len(motions) - 1, -1, -1):
        if skip[i]:
            continue
        m = motions[i]
        if m.kind == TRANSLATION:
            v = _motion_shift(m, values[i], qT)
            if m.direction is None:
                p[m.axis] = add(p[m.axis], v)
            else:
                p = [add(p[k], mul(v, m.direction[k])) for k in range(3)]
            continue
        c, s = _motion_cs(i, m, values, trig)
        if m.direction is None:
            a, b = (m.axis + 1) % 3, (m.axis + 2) % 3
            p[a], p[b] = turn(c, s, p[a], p[b])
            continue
        # Rodrigues about the unit axis d of the moving frame: c p + s (d x p) + (1-c)(d.p) d
        d = m.direction
        cross = [sub(mul(d[1], p[2]), mul(d[2], p[1])),
                 sub(mul(d[2], p[0]), mul(d[0], p[2])),
                 sub(mul(d[0], p[1]), mul(d[1], p[0]))]
        along = mul(sub(1.0, c), add(add(mul(d[0], p[0]), mul(d[1], p[1])),
                                         mul(d[2], p[2])))
        p = [add(add(mul(c, p[k]), mul(s, cross[k])), mul(along, d[k]))
             for k in range(3)]
    return p


def frame_chain(motions: Sequence[Motion], values: list, skip: list, qT: Array,
                trig: dict, record: bool = False) -> tuple[list, list, list]:
    """Tool frame in the measurement frame, composed from the base forwards.

    Parameters
    ----------
    motions, values, skip, qT, trig
        As in `point_chain`.
    record : bool
        Keep the axis and origin before each motion (for the Jacobian).

    Returns
    -------
    axes : list of 3 vectors
        ``axes[a][k]``: component k of the tool frame's axis a (floats or arrays). A vector
        is a list of 3 coordinates or, once they are all arrays, one array ``(3, ...)``.
    origin : vector
        The tool point.
    frames : list of (vector, vector)
        If `record`: per motion, its axis ``u`` and the origin ``o`` before it (vectors are
        replaced, never modified in place, so no copies).
    """
    axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    o = [0.0, 0.0, 0.0]
    frames: list = []
    for i, m in enumerate(motions):
        if m.direction is None:
            u = axes[m.axis]
        else:
            d = m.direction
            u = dense([add(add(mul(d[0], axes[0][k]), mul(d[1], axes[1][k])),
                             mul(d[2], axes[2][k])) for k in range(3)])
        if record:
            frames.append((u, o))
        if skip[i]:
            continue
        if m.kind == TRANSLATION:
            o = axpy(o, _motion_shift(m, values[i], qT), u)
            continue
        c, s = _motion_cs(i, m, values, trig)
        if m.direction is None:
            a, b = (m.axis + 1) % 3, (m.axis + 2) % 3
            va, vb = axes[a], axes[b]
            axes[a] = comb(c, va, s, vb)
            axes[b] = comb(c, vb, s, va, minus=True)
            continue
        # Rodrigues on each axis: v' = c v + s (u x v) + (1 - c)(u . v) u, with u . a_k =
        # d_k and u x a_k written through the right-handed frame
        d = m.direction
        a0, a1, a2 = axes
        k1 = sub(1.0, c)
        lin = [(a1, a2, d[2], d[1]), (a2, a0, d[0], d[2]), (a0, a1, d[1], d[0])]
        axes = [dense([add(add(mul(c, v[k]), mul(s, sub(mul(p, x[k]), mul(r, y[k])))),
                             mul(mul(k1, d[j]), u[k])) for k in range(3)])
                for j, (v, (x, y, p, r)) in enumerate(zip(axes, lin, strict=True))]
    return axes, o, frames


# ---------------------------------------------------------------- drivers
def chunks(motions: Sequence[Motion], motion_index: NDArray[np.intp], q: Array, p: Array,
           kernel, *args, elements: int = CHUNK_ELEMENTS, pose_values: dict | None = None):
    """Run `kernel` (`point_chain` or `frame_chain`) over chunks of poses.

    Parameters
    ----------
    motions, motion_index
        The chain (`motion_values`).
    q : ndarray, shape (N, n_joints)
        Joint readings (checked).
    p : ndarray, shape (n_params,) or (P, n_params)
        Parameter vector(s).
    kernel : callable
        ``kernel(motions, values, skip, qT, trig, *args)``.
    elements : int
        Poses times parameter vectors per chunk (`chunk_size`; 0: one chunk).
    pose_values : dict, optional
        Motion position -> values ``(*batch, N)`` that differ per pose (the tool point of
        each pose's marker, `kinecal.kinematics.serial.markers`); sliced with the chunk.

    Yields
    ------
    sel : slice
        The chunk's poses.
    result
        The kernel's result for them.
    """
    values, skip = motion_values(motions, motion_index, p)
    N = q.shape[0]
    step = chunk_size(N, int(np.prod(p.shape[:-1], dtype=int)), elements)
    for s0 in range(0, max(N, 1), step):
        sel = slice(s0, min(s0 + step, N))
        qT = np.ascontiguousarray(q[sel].T)
        vals, sk = values, skip
        if pose_values:
            vals, sk = list(values), list(skip)
            for i, v in pose_values.items():
                vals[i], sk[i] = v[..., sel], False
        yield sel, kernel(motions, vals, sk, qT, joint_trig(motions, vals, qT), *args)


def positions(motions: Sequence[Motion], motion_index: NDArray[np.intp], q: Array, p: Array,
              elements: int = CHUNK_ELEMENTS, pose_values: dict | None = None) -> Array:
    """Tool points ``(*batch, N, 3)`` by `point_chain`, chunk by chunk (see `chunks`)."""
    out = np.empty((*p.shape[:-1], q.shape[0], 3))
    for sel, point in chunks(motions, motion_index, q, p, point_chain, elements=elements,
                             pose_values=pose_values):
        for k in range(3):
            out[..., sel, k] = point[k]
    return out


def transforms(motions: Sequence[Motion], motion_index: NDArray[np.intp], q: Array, p: Array,
               elements: int = CHUNK_ELEMENTS, pose_values: dict | None = None) -> Array:
    """Tool frames ``(*batch, N, 4, 4)`` by `frame_chain`, chunk by chunk (see `chunks`).

    Each chunk's matrices are assembled in a small buffer (in cache) and copied into the
    result once: the big result array is written in one pass.
    """
    batch = p.shape[:-1]
    T = np.empty((*batch, q.shape[0], 4, 4))
    buf = None
    for sel, (axes, o, _) in chunks(motions, motion_index, q, p, frame_chain,
                                    elements=elements, pose_values=pose_values):
        n = sel.stop - sel.start
        if buf is None or buf.shape[-3] != n:
            # every entry is written below but the last row: np.empty, not np.zeros (a
            # calloc of fresh pages costs their faults at each call: 10^4 poses 180 -> 90 ns)
            buf = np.empty((*batch, n, 4, 4))
            buf[..., 3, :3] = 0.0
            buf[..., 3, 3] = 1.0
        for a in range(3):
            for k in range(3):
                buf[..., k, a] = axes[a][k]
            buf[..., a, 3] = o[a]
        T[..., sel, :, :] = buf
    return T
