"""``default_kinematics.yaml`` of ur_description: a UR-type D-H model as ur_robot_driver
and MoveIt load it.

ur_description builds each arm joint as a URDF joint: a fixed origin ``x, y, z`` and
``roll, pitch, yaw`` (``R = Rz(yaw) Ry(pitch) Rx(roll)``) read from the file's
``kinematics: {shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3}``, then the rotation
by the joint reading about the joint's z axis; ``tool0`` is ``wrist_3`` turned by
``rpy(0, -pi/2, -pi/2)`` then ``rpy(pi/2, 0, pi/2)``, which is the identity. The chain
starts in ``base_link_inertia`` (= UR's ``base`` frame, ``base_link`` turned by pi about z),
which is D-H frame 0.

A standard D-H chain ``prod Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` is regrouped
exactly into that form, since ``Rz(q)`` commutes with ``Rz(theta)`` and ``Tz(d)``:
joint 1's origin is ``Rz(theta_1) Tz(d_1)``, joint i's ``Tx(a_{i-1}) Rx(alpha_{i-1})
Rz(theta_i) Tz(d_i)``. Then ``wrist_3`` is D-H frame 6 when ``a_6 = alpha_6 = 0`` (every UR
arm and every controller calibration has them zero; a model with other values is refused,
ur_description has no place for them). Joint frames 1-5 may further be slid along and
turned about their own axes (``Tz(t) Rz(phi)`` commutes with the joint's rotation; the next
origin takes the inverse), which changes no pose of ``tool0``: kinecal uses that freedom
to put each link frame next to the nominal arm's (`kinecal.io.ur.robots`), so the meshes
of ur_description sit where the links are, also when a calibration moved ``d_2 .. d_4``
metres along the parallel axes.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal._files import write_text_atomic
from kinecal.errors import InputError
from kinecal.io.ur.geometry import (
    FACTORY_FRACTION,
    closest_types,
    reach,
    robot_type,
    within_factory,
)
from kinecal.io.ur.robots import nominal_dh
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import rot_x, rot_z, rpy_from_matrix

__all__ = ["SEGMENTS", "dh_table", "joint_origins", "save_ur_kinematics", "ur_kinematics",
           "ur_kinematics_text"]

Array = NDArray[np.float64]

#: the kinematics keys of ur_description, base to wrist
SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
_PER_M = {"m": 1.0, "mm": 1000.0}
#: a_6 and alpha_6 this close to zero (m, rad) are zero: beyond, tool0 would be off
_TAIL_TOL = 1e-9
_ROUND_OFF = 1e-15


def dh_table(model: SerialModel, params: ArrayLike | None = None) -> Array:
    """The D-H table of a UR-type model, ``(6, 4)``: theta, a, d, alpha (rad, metres).

    Raises
    ------
    InputError
        Not a six-revolute-joint ``dh`` chain without fixed frames, or ``a6`` / ``alpha6``
        not zero.
    """
    if model.convention != "dh" or model.n_joints != 6 or len(model.joints) != 6 or \
            model.is_prismatic().any():
        raise InputError(f"model {model.name!r}: ur-kinematics needs a UR-type chain: six "
                         f"revolute joints in the dh convention without fixed frames (got "
                         f"{model.n_joints} joints, convention {model.convention})")
    per_m = _PER_M.get(model.length_unit)
    if per_m is None:
        raise InputError(f"length unit {model.length_unit!r}: expected mm or m")
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    if p.shape != model.nominal.shape or not np.isfinite(p).all():
        raise InputError(f"model {model.name!r}: expected {model.nominal.size} finite "
                         f"parameter values, got shape {p.shape}"
                         + ("" if p.shape != model.nominal.shape else " with NaN or inf"))
    names = [f"{k}{i}" for i in range(1, 7) for k in ("theta", "a", "d", "alpha")]
    t = p[model.index(names)].reshape(6, 4)
    t[:, 1:3] /= per_m
    if abs(t[5, 1]) > _TAIL_TOL or abs(t[5, 3]) > _TAIL_TOL:
        raise InputError(f"model {model.name!r}: a6 = {t[5, 1] * per_m:.6g} "
                         f"{model.length_unit}, alpha6 = {np.degrees(t[5, 3]):.6g} deg: "
                         "ur_description fixes tool0 to the last joint's frame and has no "
                         "place for them (UR arms have a6 = alpha6 = 0): hold them at zero "
                         "in the calibration (--free without a6, alpha6)")
    return t


def _tf(R: Array, p) -> Array:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def _origin(table: Array, i: int) -> Array:
    """Joint ``i``'s origin (0-based) in the previous joint's frame, from the D-H table."""
    theta, _, d, _ = table[i]
    own = _tf(rot_z(theta), (0.0, 0.0, d))
    if i == 0:
        return own
    return _tf(rot_x(table[i - 1, 3]), (table[i - 1, 1], 0.0, 0.0)) @ own


def _frames(table: Array) -> Array:
    """Joint frames 1..6 in the base frame at the zero reading, ``(6, 4, 4)``."""
    F = np.zeros((6, 4, 4))
    W = np.eye(4)
    for i in range(6):
        W = W @ _origin(table, i)
        F[i] = W
    return F


def _gauges(F: Array, ref: Array) -> Array:
    """``Tz(t) Rz(phi)`` per joint frame (identity for frame 6) moving frames 1-5 along and
    about their z axes next to the reference frames `ref` ``(6, 4, 4)``."""
    G = np.tile(np.eye(4), (6, 1, 1))
    for i in range(5):
        t = float(F[i, :3, 2] @ (ref[i, :3, 3] - F[i, :3, 3]))
        v = F[i, :3, :3].T @ ref[i, :3, 0]
        G[i] = _tf(rot_z(float(np.arctan2(v[1], v[0]))), (0.0, 0.0, t))
    return G


def _inverse(T: Array) -> Array:
    return _tf(T[:3, :3].T, -T[:3, :3].T @ T[:3, 3])


def joint_origins(table: ArrayLike, reference: ArrayLike | None = None) -> Array:
    """The six joint origins (each in the previous joint's frame), ``(6, 4, 4)`` (metres).

    Parameters
    ----------
    table : array_like, shape (6, 4)
        theta, a, d, alpha (rad, m) with ``a6 = alpha6 = 0``.
    reference : array_like, shape (6, 4), optional
        A nominal table: joint frames 1-5 are moved along / about their axes next to its
        frames (module docstring): origin ``i`` becomes ``G_{i-1}^-1 origin_i G_i``. Without
        it, or for the reference table itself, the plain regrouping.
    """
    table = np.asarray(table, dtype=float)
    origins = np.stack([_origin(table, i) for i in range(6)])
    if reference is None:
        return origins
    G = _gauges(_frames(table), _frames(np.asarray(reference, dtype=float)))
    out = origins.copy()
    for i in range(6):
        left = np.eye(4) if i == 0 else _inverse(G[i - 1])
        out[i] = left @ origins[i] @ G[i]
    return out


def _clean(v: float) -> float:
    v = float(v)
    return 0.0 if abs(v) < _ROUND_OFF else v


def ur_kinematics(model: SerialModel, params: ArrayLike | None = None,
                  robot: str | None = None) -> tuple[dict, str | None]:
    """The ``kinematics`` mapping of `model` at `params` and the UR type used as reference.

    Parameters
    ----------
    model : SerialModel
        A UR-type ``dh`` model (`dh_table`).
    params : array_like, shape (n_params,), optional
        Identified parameters (default nominal).
    robot : str, optional
        The UR type whose link frames the exported ones are moved next to (default: the
        type the model is a calibration of, `kinecal.io.ur.geometry.robot_type`; none: the
        plain regrouping). A type the model's flange strays from by more than a factory
        calibration does is used, with a warning (``ur-kinematics-not-ur``).

    Returns
    -------
    dict
        ``{SEGMENT: {x, y, z, roll, pitch, yaw}, "hash": ...}`` (metres, radians).
    str or None
        The reference type.
    """
    table = dh_table(model, params)
    if robot is None:
        robot = robot_type(table)
        if robot is None:
            _warn_not_ur(model, table)
    else:
        nominal_dh(robot)  # an unknown type is refused
        robot = robot.strip().lower()
        _check_type(model, table, robot)
    ref = nominal_dh(robot) if robot is not None else None
    origins = joint_origins(table, ref)
    out: dict = {}
    for seg, T in zip(SEGMENTS, origins, strict=True):
        rpy = rpy_from_matrix(T[:3, :3])
        out[seg] = {k: _clean(v) for k, v in zip(("x", "y", "z", "roll", "pitch", "yaw"),
                                                  (*T[:3, 3], *rpy), strict=True)}
    digest = hashlib.sha256(repr(sorted((s, tuple(v.values())) for s, v in out.items()))
                            .encode()).hexdigest()
    out["hash"] = f"kinecal_{digest[:16]}"
    return out, robot


def _warn_not_ur(model: SerialModel, table: Array) -> None:
    from kinecal.diagnostics import warn

    name, dev = closest_types(table)[0]
    warn("ur-kinematics-not-ur",
         f"model {model.name!r} (d1 {table[0, 2] * 1000:.1f} mm, a2 {table[1, 1] * 1000:.1f} "
         f"mm, a3 {table[2, 1] * 1000:.1f} mm) is no calibration of a UR type (its flange "
         f"strays {_mm(dev)} from the closest, a {name}'s, over the joint range): the "
         "file is its exact kinematics, but ur_description draws a UR's links and meshes "
         "along it; for an arm that is not a UR export --format urdf (give --robot TYPE to "
         "keep a UR type's link frames anyway)")


def _check_type(model: SerialModel, table: Array, robot: str) -> None:
    """Warn when `model` is no calibration of the `robot` the user named."""
    ranked = dict(closest_types(table))
    if within_factory(robot, ranked[robot]):
        return
    from kinecal.diagnostics import warn

    fits = [t for t, e in ranked.items() if within_factory(t, e)]
    warn("ur-kinematics-not-ur",
         f"model {model.name!r} is no {robot}: its flange strays {_mm(ranked[robot])} from "
         f"a nominal {robot}'s over the joint range (a factory calibration: at most "
         f"{FACTORY_FRACTION * reach(robot) * 1000:.3g} mm); "
         + (f"it is a {' or '.join(fits)}: give --robot {fits[0]}. " if fits else "")
         + f"The file is the model's exact kinematics, but ur_description draws a {robot}'s "
         "links and meshes along it")


def _mm(metres: float) -> str:
    return f"{metres * 1000:.4g} mm" if np.isfinite(metres) else "an undefined distance"


def ur_kinematics_text(model: SerialModel, params: ArrayLike | None = None,
                       robot: str | None = None, comment: str | None = None) -> str:
    """The ``default_kinematics.yaml`` text (`ur_kinematics`), with a comment on top."""
    kin, _ = ur_kinematics(model, params, robot)
    lines = [f"# {line}" for line in (comment or "").splitlines() if line.strip()]
    lines.append("kinematics:")
    for seg in SEGMENTS:
        lines.append(f"  {seg}:")
        lines.extend(f"    {k}: {v!r}" for k, v in kin[seg].items())
    lines.append(f"  hash: {kin['hash']}")
    return "\n".join(lines) + "\n"


def save_ur_kinematics(path: str | Path, model: SerialModel, params: ArrayLike | None = None,
                       robot: str | None = None, comment: str | None = None) -> None:
    """Write `ur_kinematics_text` to `path` (atomic)."""
    write_text_atomic(path, ur_kinematics_text(model, params, robot, comment))
