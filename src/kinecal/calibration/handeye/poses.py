"""Hand-eye pose planning: the star-polygon scheme of paper 001 and random poses.

Frames: the target frame has its origin at the target's geometric centre and its z axis
along the target normal, towards the camera. Poses are returned as ``cam2target``
(camera pose in the target frame, lengths in the unit of `distance` and `radius`).

Paper 001, sec. 3 (fig. 2), for 5 images: a reference frame C0 sits at height ``|Pc|``
above the target centre, its z axis pointing at the centre; the camera positions are the
vertices of a regular pentagram of circumradius r in C0's xy plane, every camera's z
axis points at the target centre, the first camera's x axis is tangent to the
circumscribed circle, and each following camera frame is the previous one rotated about
the axis through the target centre perpendicular to the vertical plane that contains
the star edge joining the two positions.

Generalisation to N points (kinecal): the vertices of the regular star polygon
``{N/k}`` visited in star order, vertex ``m`` at angle ``2 pi (m k mod N) / N``, with the
step ``k`` the largest integer below N/2 coprime with N (N = 5 gives k = 2, the
pentagram; N = 19 gives k = 9). Consecutive stations are then almost opposite on the
circle, which makes the rotation between consecutive images large and the axes of
consecutive motions differ by the star angle, as Tsai's error analysis recommends
(paper 001, sec. 3, eq. (6)). For N = 3, 4 and 6 no star exists and k = 1 (the convex
polygon). The rotation of each step about its edge axis is the rotation that carries one
position to the next (both are at the same distance from the target centre), so the z
axes keep pointing at the centre.
"""

from __future__ import annotations

from math import gcd

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import matrix_from_axis_angle, transform_from

Array = NDArray[np.float64]

__all__ = ["flange_poses", "look_at", "random_poses", "star_polygon_poses", "star_step"]


def star_step(count: int) -> int:
    """Step k of the star polygon {count/k}: the largest k < count/2 coprime with count."""
    if count < 3:
        raise InputError(f"count {count}: the star-polygon scheme needs at least 3 poses",
                         option="count")
    k = (count - 1) // 2
    while k > 1 and gcd(k, count) != 1:
        k -= 1
    return max(k, 1)


def _check(distance: float, radius: float, count: int) -> None:
    if not (np.isfinite(distance) and distance > 0):
        raise InputError(f"distance {distance}: expected a positive length", option="distance")
    if not (np.isfinite(radius) and radius > 0):
        raise InputError(f"radius {radius}: expected a positive length", option="radius")
    if count < 3:
        raise InputError(f"count {count}: expected at least 3 poses", option="count")


def look_at(positions: Array, x_hint: Array) -> Array:
    """Rotations ``(n, 3, 3)`` of cameras at `positions` ``(n, 3)`` looking at the origin.

    The z axis points at the origin; the x axis is `x_hint` ``(n, 3)`` made orthogonal to z.
    """
    z = -positions / np.linalg.norm(positions, axis=1, keepdims=True)
    x = x_hint - np.sum(x_hint * z, axis=1, keepdims=True) * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def star_polygon_poses(
    distance: float, radius: float, count: int, *, step: int | None = None,
    start_angle: float = 0.0,
) -> Array:
    """Camera poses of the star-polygon scheme (paper 001, sec. 3, generalised to N).

    Parameters
    ----------
    distance : float
        Height ``|Pc|`` of the star's plane above the target centre (length unit L).
    radius : float
        Circumradius r of the star polygon (L).
    count : int
        Number of poses N (>= 3).
    step : int, optional
        Star step k (coprime with N); default `star_step`.
    start_angle : float
        Angle (rad) of the first vertex about the target normal.

    Returns
    -------
    ndarray, shape (count, 4, 4)
        ``cam2target`` in visiting order.
    """
    _check(distance, radius, count)
    k = star_step(count) if step is None else int(step)
    if not 1 <= k < count or gcd(k, count) != 1:
        raise InputError(f"step {k}: expected 1 <= step < {count} coprime with {count}",
                         option="step")
    ang = start_angle + 2.0 * np.pi * ((np.arange(count) * k) % count) / count
    P = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.full(count, distance)], 1)
    tangent0 = np.array([[-np.sin(ang[0]), np.cos(ang[0]), 0.0]])
    R0 = look_at(P[:1], tangent0)[0]
    # rotation of step m: about the horizontal axis n_m through the target centre that is
    # perpendicular to the vertical plane containing the edge P_m -> P_m+1
    edge = P[1:] - P[:-1]
    n = np.stack([-edge[:, 1], edge[:, 0], np.zeros(count - 1)], 1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    u0 = P[:-1] - np.sum(P[:-1] * n, 1, keepdims=True) * n
    u1 = P[1:] - np.sum(P[1:] * n, 1, keepdims=True) * n
    phi = np.arctan2(np.sum(n * np.cross(u0, u1), 1), np.sum(u0 * u1, 1))
    steps = matrix_from_axis_angle(n * phi[:, None])
    R = np.empty((count, 3, 3))
    R[0] = R0
    for m in range(count - 1):  # a product of N rotations: inherently sequential
        R[m + 1] = steps[m] @ R[m]
    return transform_from(R, P)


def random_poses(
    distance: float, radius: float, count: int, rng: np.random.Generator | int | None = None,
    *, roll: float = np.pi,
) -> Array:
    """Random camera poses over the same region as the star scheme (paper 001, exp. 1).

    Positions uniform in the disc of radius `radius` at height `distance` above the target
    centre; the z axis points at the target centre; the rotation about it is uniform in
    ``[-roll, roll]`` (rad) around the look-at frame whose x axis is the target's x axis.

    Returns
    -------
    ndarray, shape (count, 4, 4)
        ``cam2target`` (length unit of the inputs).
    """
    _check(distance, radius, count)
    rng = np.random.default_rng(rng)
    rho = radius * np.sqrt(rng.random(count))
    th = rng.uniform(-np.pi, np.pi, count)
    P = np.stack([rho * np.cos(th), rho * np.sin(th), np.full(count, distance)], 1)
    R = look_at(P, np.tile([1.0, 0.0, 0.0], (count, 1)))
    z = R[:, :, 2]
    spin = matrix_from_axis_angle(z * rng.uniform(-roll, roll, count)[:, None])
    return transform_from(spin @ R, P)


def flange_poses(cam2target: Array, cam2flange: Array, target2base: Array) -> Array:
    """Eye-in-hand flange poses that put the camera at `cam2target`.

    Parameters
    ----------
    cam2target : ndarray, shape (n, 4, 4)
        Planned camera poses.
    cam2flange : ndarray, shape (4, 4)
        Hand-eye transform (nominal).
    target2base : ndarray, shape (4, 4)
        Target pose in the robot base frame.

    Returns
    -------
    ndarray, shape (n, 4, 4)
        ``flange2base = target2base @ cam2target @ cam2flange^-1``.
    """
    from kinecal.spatial import invert_transform

    return target2base @ cam2target @ invert_transform(cam2flange)
