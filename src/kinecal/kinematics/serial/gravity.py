"""Generalised gravity forces of a serial chain, for joint-compliance models.

A point mass ``m`` at ``p`` (robot base frame), carried by link ``k`` (the link moved by
joint ``k``), loads joint ``j <= k`` with the generalised gravity force

* ``tau_j = (u_j x (p - o_j)) . g``  for a revolute joint (torque about its axis ``u_j``
  through ``o_j``),
* ``tau_j = u_j . g``                for a prismatic joint (force along its axis),

i.e. ``tau_j = (dp / dq_j) . g``, times ``m`` and the magnitude of gravity (``g`` is the
unit gravity direction in the robot base frame; torques are per unit mass and gravity, in
the length unit). A compliant joint deflects by ``dq_j = c_j tau_j``
(`kinecal.kinematics.serial.joint_errors`).

Everything here is evaluated on a *reference* geometry (the nominal kinematics), so the
forces are functions of the joint readings only: the calibration's parameters enter the
corrections linearly and the identification Jacobian stays exact.

The derivative of ``tau_j`` with respect to joint ``i`` (needed for the joint Jacobian of
the corrected chain, e.g. by inverse kinematics) follows from how joint ``i`` moves the
vectors involved: a revolute joint ``i <= j`` turns the whole lever ``v = u_j x (p - o_j)``
(``dv = u_i x v``), a joint ``j < i <= k`` moves only the mass (``dp = u_i x (p - o_i)``
or ``u_i``), prismatic joints upstream of ``j`` translate everything (no change).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.motions import PRISMATIC, TRANSLATION, Motion, rotate_axes

__all__ = ["ChainFrames", "LoadPoint", "chain_frames", "gravity_forces"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ChainFrames:
    """Frames of a chain at a set of joint readings, in the robot base frame.

    Attributes
    ----------
    axes : list of ndarray, each (3, N)
        Joint ``j``'s unit axis.
    origins : list of ndarray, each (3, N)
        A point on joint ``j``'s axis (the moving frame's origin before the joint motion).
    links : list of (list of 3 ndarrays (3, N), ndarray (3, N))
        Link ``j``'s frame (axes x, y, z and origin) at the end of joint ``j``'s entry.
    flange : (list of 3 ndarrays (3, N), ndarray (3, N))
        The frame before the tool motions.
    tool : ndarray, shape (3, N)
        The tool point.
    """

    axes: list
    origins: list
    links: list
    flange: tuple
    tool: Array


@dataclass(frozen=True)
class LoadPoint:
    """A point mass for `gravity_forces`: ``positions`` (3, N) carried by link ``link``
    (0-based joint index; the tool point and payload use the last joint)."""

    link: int
    positions: Array
    mass: float = 1.0


def chain_frames(motions: Sequence[Motion], owners: Sequence, motion_index: NDArray[np.intp],
                 n_joints: int, p: Array, q: Array) -> ChainFrames:
    """Compose the chain without its base frame and record the frames gravity needs.

    Parameters
    ----------
    motions : sequence of Motion
        The chain's motions (base, entries, tool).
    owners : sequence
        Per motion: its chain entry index, ``"base"`` or ``"tool"``.
    motion_index : ndarray, shape (m,)
        Parameter index of each motion.
    n_joints : int
        Number of moving joints.
    p : ndarray, shape (n,)
        Parameter vector (length unit, rad); base values are ignored.
    q : ndarray, shape (N, n_joints)
        Joint readings.
    """
    N = q.shape[0]
    axes = [np.zeros((3, N)) for _ in range(3)]
    for i in range(3):
        axes[i][i] = 1.0
    o = np.zeros((3, N))
    joint_axes: list = [None] * n_joints
    joint_origins: list = [None] * n_joints
    entry_of_joint = [None] * n_joints
    ends: dict = {}  # chain entry -> its frame at the end of the entry
    previous = None
    values = p.tolist()
    for m, k, owner in zip(motions, motion_index, owners, strict=True):
        if owner == "base":
            continue
        if owner != previous:
            if previous is not None:
                ends[previous] = (list(axes), o)
            if owner == "tool":
                ends["flange"] = (list(axes), o)
            previous = owner
        u = axes[m.axis] if m.direction is None else m.vector(axes)
        value = values[k] if k >= 0 else m.const
        if m.joint is not None:
            joint_axes[m.joint], joint_origins[m.joint] = u, o
            entry_of_joint[m.joint] = owner
            value = value + q[:, m.joint]
        elif value == 0.0:
            continue
        if m.kind == TRANSLATION:
            o = o + value * u
            continue
        c, s = np.cos(value), np.sin(value)
        if m.direction is not None:
            axes = rotate_axes(axes, u, m.direction, c, s)
            continue
        a, b = (m.axis + 1) % 3, (m.axis + 2) % 3
        va, vb = axes[a], axes[b]
        axes = list(axes)
        axes[a] = c * va + s * vb
        axes[b] = c * vb - s * va
    links = [ends[e] for e in entry_of_joint]
    return ChainFrames(joint_axes, joint_origins, links, ends["flange"], o)


def gravity_forces(frames: ChainFrames, kinds: Sequence[str], gravity: Array,
                   pairs: Sequence[tuple[int, LoadPoint]], derivatives: bool = False
                   ) -> tuple[Array, Array | None]:
    """Generalised gravity force of each (joint, point mass) pair, and its derivatives.

    Parameters
    ----------
    frames : ChainFrames
    kinds : sequence of str
        ``"revolute"`` or ``"prismatic"`` per joint.
    gravity : ndarray, shape (3,)
        Unit gravity direction in the robot base frame.
    pairs : sequence of (int, LoadPoint)
        Joint index ``j`` (0-based) and a point mass on a link ``k >= j``.
    derivatives : bool
        Also return the derivatives with respect to every joint reading.

    Returns
    -------
    tau : ndarray, shape (N, n_pairs)
        ``mass * (dp / dq_j) . g`` (mass x length unit for revolute joints, mass for
        prismatic ones).
    dtau : ndarray, shape (N, n_pairs, n_joints) or None
        ``d tau / d q_i``.
    """
    g = np.asarray(gravity, dtype=float)
    n = len(kinds)
    N = frames.tool.shape[1]
    tau = np.zeros((N, len(pairs)))
    dtau = np.zeros((N, len(pairs), n)) if derivatives else None
    U = [frames.axes[j] for j in range(n)]
    O = [frames.origins[j] for j in range(n)]
    for c, (j, load) in enumerate(pairs):
        p = load.positions
        if kinds[j] == PRISMATIC:
            tau[:, c] = load.mass * (g @ U[j])
            if dtau is not None:
                for i in range(j):  # upstream rotations turn the axis
                    if kinds[i] != PRISMATIC:
                        dtau[:, c, i] = load.mass * (g @ np.cross(U[i], U[j], axis=0))
            continue
        v = np.cross(U[j], p - O[j], axis=0)  # the lever (3, N)
        tau[:, c] = load.mass * (g @ v)
        if dtau is None:
            continue
        for i in range(load.link + 1):
            if i <= j:
                if kinds[i] != PRISMATIC:  # the whole lever turns about u_i
                    dtau[:, c, i] = load.mass * (g @ np.cross(U[i], v, axis=0))
                continue
            if kinds[i] == PRISMATIC:  # the mass slides along u_i
                dp = U[i]
            else:
                dp = np.cross(U[i], p - O[i], axis=0)
            dtau[:, c, i] = load.mass * (g @ np.cross(U[j], dp, axis=0))
    return tau, dtau
