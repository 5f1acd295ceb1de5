"""What the workbench draws, as plain arrays: a robot's skeleton at many poses, link
cylinders as instances of one unit cylinder, residual arrows and their colours.

Nothing here knows the browser: `kinecal.ui.scene` sends these arrays to viser. Every
length here is in the scene's unit, metres (`scene_scale` converts a model's length unit),
so that viser's grid, camera and lights suit a robot of any unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Skeleton",
    "cylinder_instances",
    "error_colors",
    "quaternions_z_to",
    "residual_arrows",
    "scene_scale",
    "serial_skeleton",
    "system_skeleton",
    "unit_cylinder",
]

Array = NDArray[np.float64]

#: scene units (metres) per model length unit
_UNITS = {"mm": 1e-3, "m": 1.0}


def scene_scale(length_unit: str) -> float:
    """Metres per unit of `length_unit` (``mm`` or ``m``)."""
    return _UNITS.get(length_unit, 1e-3)


@dataclass(frozen=True)
class Skeleton:
    """A robot drawn as links and joints at N poses (scene units).

    Attributes
    ----------
    points : ndarray, shape (N, K, 3)
        The chain's corner points per pose: base, the origins the translations reach, the
        tool point.
    segments : ndarray of int, shape (S, 2)
        Pairs of indices into the K points: one link cylinder each.
    joint_origins, joint_axes : ndarray, shape (N, J, 3)
        Where each joint is and its unit axis (a joint drawn as a short thick cylinder).
    """

    points: Array
    segments: NDArray[np.intp]
    joint_origins: Array
    joint_axes: Array

    @property
    def size(self) -> float:
        """Largest extent of the chain over its poses (scene units; at least 1e-3)."""
        p = self.points.reshape(-1, 3)
        return float(max(np.ptp(p, axis=0).max(initial=0.0), 1e-3))


def _stack(vec, n: int) -> Array:
    """A sweep vector (3 floats or arrays) as ``(n, 3)``."""
    return np.stack([np.broadcast_to(np.asarray(c, dtype=float), (n,)) for c in vec], axis=1)


def serial_skeleton(model, q: Array, params: Array | None = None) -> Skeleton:
    """The skeleton of a `SerialModel` at joint values `q` ``(N, n_joints)`` (rad).

    The points are the origin before the first motion after the base frame, the origin
    after every translation of the chain (``d`` along the joint axis, ``a`` along the
    common normal for D-H; a URDF joint's origin) and the tool point; a segment joins two
    successive points unless the nominal chain never separates them (a zero ``d``).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(q)
    sweep = model.sweep(q, params)
    motions = model.motions
    first = next((i for i, m in enumerate(motions) if not m.name.startswith("base.")),
                 len(motions))
    corners = [first]  # motion indices whose "origin before" is a corner
    for i in range(first, len(motions) - 1):
        if motions[i].kind == "T":
            corners.append(i + 1)
    pts = [_stack(sweep.frames[i][1], n) for i in corners]
    pts.append(np.asarray(sweep.positions, dtype=float))
    points = np.stack(pts, axis=1)
    scale = scene_scale(model.length_unit)
    # a segment where the nominal chain moves the origin (at the first pose)
    nominal = model.sweep(q[:1])
    npts = np.stack([_stack(nominal.frames[i][1], 1)[0] for i in corners]
                    + [np.asarray(nominal.positions, dtype=float)[0]])
    gaps = np.linalg.norm(np.diff(npts, axis=0), axis=1)
    keep = np.flatnonzero(gaps > 1e-9 * max(gaps.max(initial=0.0), 1.0))
    segments = np.stack([keep, keep + 1], axis=1).astype(np.intp)
    joints = [i for i, m in enumerate(motions) if m.joint is not None]
    origins = np.stack([_stack(sweep.frames[i][1], n) for i in joints], axis=1)
    axes = np.stack([_stack(sweep.frames[i][0], n) for i in joints], axis=1)
    return Skeleton(points * scale, segments, origins * scale, axes)


def system_skeleton(system, q: Array, params: Array | None = None) -> Skeleton:
    """The skeleton of a robot system (`kinecal.kinematics.tree.SystemModel`): every
    tip's chain as the polyline through its links' origins, shared links drawn once;
    joints at the origins of the links that a joint moves (axis: the link's z)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    links: list[str] = []
    segments: list[tuple[int, int]] = []
    for tip in system.tips:
        chain = list(system.chain_links(tip))
        prev = None
        for link in chain:
            if link not in links:
                links.append(link)
            k = links.index(link)
            if prev is not None and (prev, k) not in segments:
                segments.append((prev, k))
            prev = k
    poses = np.stack([system.link_poses(q, link, params) for link in links], axis=1)
    scale = scene_scale(getattr(system, "length_unit", "mm"))
    points = poses[:, :, :3, 3] * scale
    moved = [k for k, link in enumerate(links) if len(system.link_joints(link))]
    seg = np.array(segments, dtype=np.intp).reshape(-1, 2)
    gaps = np.linalg.norm(points[0, seg[:, 1]] - points[0, seg[:, 0]], axis=1)
    seg = seg[gaps > 1e-9]
    return Skeleton(points, seg, points[:, moved], poses[:, moved, :3, 2])


def unit_cylinder(sides: int = 16) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
    """A closed cylinder of radius 1 from z = 0 to z = 1: vertices ``(V, 3)``, faces
    ``(F, 3)`` (counter-clockwise seen from outside)."""
    t = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ring = np.stack([np.cos(t), np.sin(t)], axis=1)
    v = np.concatenate([np.c_[ring, np.zeros(sides)], np.c_[ring, np.ones(sides)],
                        [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]])
    i = np.arange(sides)
    j = (i + 1) % sides
    bottom, top = 2 * sides, 2 * sides + 1
    faces = np.concatenate([
        np.stack([i, j, j + sides], axis=1), np.stack([i, j + sides, i + sides], axis=1),
        np.stack([np.full(sides, bottom), j, i], axis=1),
        np.stack([np.full(sides, top), i + sides, j + sides], axis=1)])
    return v.astype(np.float32), faces.astype(np.uint32)


def quaternions_z_to(d: Array) -> Array:
    """Unit quaternions ``(N, 4)`` (w, x, y, z) turning the z axis onto the directions
    `d` ``(N, 3)`` (any length; a zero direction gives the identity)."""
    d = np.asarray(d, dtype=float)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    u = np.divide(d, norm, out=np.tile([0.0, 0.0, 1.0], (len(d), 1)), where=norm > 0)
    # half-way vector between z and u: q = (1 + z.u, z x u), normalised
    w = 1.0 + u[:, 2]
    xyz = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u))], axis=1)
    quat = np.c_[w, xyz]
    flip = w < 1e-9  # u = -z: half a turn about x
    quat[flip] = [0.0, 1.0, 0.0, 0.0]
    return quat / np.linalg.norm(quat, axis=1, keepdims=True)


def cylinder_instances(a: Array, b: Array, radius: float | Array
                       ) -> tuple[Array, Array, Array]:
    """Positions ``(N, 3)``, orientations ``(N, 4)`` and per-axis scales ``(N, 3)`` that
    place `unit_cylinder` from each point of `a` ``(N, 3)`` to the matching one of `b`."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = b - a
    length = np.linalg.norm(d, axis=1)
    r = np.broadcast_to(np.asarray(radius, dtype=float), length.shape)
    return a, quaternions_z_to(d), np.stack([r, r, length], axis=1)


def residual_arrows(predicted: Array, measured: Array, gain: float) -> Array:
    """Arrows ``(N, 2, 3)`` from each predicted point towards its measured point, the error
    drawn `gain` times its length (all in scene units)."""
    predicted = np.asarray(predicted, dtype=float)
    measured = np.asarray(measured, dtype=float)
    return np.stack([predicted, predicted + gain * (measured - predicted)], axis=1)


#: colour ramp of error sizes: green (small), yellow, red (at the top of the scale)
_RAMP = np.array([[40, 170, 80], [240, 200, 40], [220, 40, 40]], dtype=float)


def error_colors(errors: Array, top: float) -> NDArray[np.uint8]:
    """RGB colours ``(N, 3)`` of error sizes `errors` ``(N,)`` on a green-yellow-red ramp
    from 0 to `top` (sizes above `top` are red)."""
    t = np.clip(np.asarray(errors, dtype=float) / max(float(top), 1e-300), 0.0, 1.0) * 2.0
    k = np.minimum(t.astype(int), 1)
    f = (t - k)[:, None]
    return np.rint(_RAMP[k] * (1 - f) + _RAMP[k + 1] * f).astype(np.uint8)
