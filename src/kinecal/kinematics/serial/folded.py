"""Folded arithmetic on chain coordinates: the operations `kinecal.kinematics.serial.compose`
builds its kernels from.

Every coordinate is either an array broadcastable to ``(*batch, n)`` or a plain float;
operations with an exact float zero (or one) are folded away, so the constant part of a
chain (a base frame before the first joint, a tool point on a joint axis, the identity
frame at the start) costs nothing per pose. A frame's vector (an axis, an origin) is a list
of 3 coordinates until all three are arrays of one shape, then one stacked array
``(3, *batch, n)`` (`dense`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["add", "axpy", "comb", "dense", "fits", "mul", "sub", "turn", "zero"]


def zero(x) -> bool:
    """Whether `x` is an exact float zero (folded away)."""
    return isinstance(x, float) and x == 0.0


def mul(a, x):
    """``a x``, folding exact zeros and ones."""
    if zero(x) or zero(a):
        return 0.0
    if isinstance(a, float) and a == 1.0:
        return x
    if isinstance(x, float) and x == 1.0:
        return a
    return a * x


def add(x, y):
    """``x + y``, folding exact zeros."""
    if zero(x):
        return y
    if zero(y):
        return x
    return x + y


def sub(x, y):
    """``x - y``, folding exact zeros."""
    if zero(y):
        return x
    if zero(x):
        return -y
    return x - y


def turn(c, s, x, y):
    """``(c x - s y, s x + c y)``: a plane rotation of the coordinate pair (x, y)."""
    return sub(mul(c, x), mul(s, y)), add(mul(s, x), mul(c, y))


# A frame's vector (an axis, the origin) is a list of 3 coordinates (floats or arrays) until
# all three are arrays of one shape; then one array (3, *batch, n): an operation on it is
# one numpy call instead of three (what matters at a few thousand poses per chunk).
def dense(v: list):
    a, b, c = v
    if (type(a) is np.ndarray and type(b) is np.ndarray and type(c) is np.ndarray
            and a.shape == b.shape == c.shape):
        out = np.empty((3, *a.shape))
        out[0], out[1], out[2] = a, b, c
        return out
    return v


def fits(v, c, s=0.0) -> bool:
    """Whether coefficients broadcast over the pose axes of the stacked vector `v`."""
    return (type(v) is np.ndarray and getattr(c, "ndim", 0) < v.ndim
            and getattr(s, "ndim", 0) < v.ndim)


def comb(c, va, s, vb, minus: bool = False):
    """``c va + s vb`` (``c va - s vb`` with `minus`) of two vectors."""
    if fits(va, c, s) and type(vb) is np.ndarray and va.ndim == vb.ndim:
        out, t = c * va, s * vb  # new arrays (frames keep references)
        if out.shape != t.shape:  # (3, P, 1) against (3, P, n): no in-place result
            return out - t if minus else out + t
        if minus:
            out -= t
        else:
            out += t
        return out
    f = sub if minus else add
    return dense([f(mul(c, va[k]), mul(s, vb[k])) for k in range(3)])


def axpy(o, v, u):
    """``o + v u``: the origin moved by `v` along the unit vector `u`."""
    if fits(u, v):
        if isinstance(o, np.ndarray) and o.ndim == u.ndim:
            out = v * u
            if out.shape != np.broadcast_shapes(out.shape, o.shape):
                return out + o
            out += o
            return out
        if not isinstance(o, np.ndarray) and all(zero(x) for x in o):
            return v * u
    return dense([add(o[k], mul(v, u[k])) for k in range(3)])
