"""Elementary motions and the joint conventions built from them.

Every geometric parameter enters a serial chain as one *elementary motion*: a rotation
about, or a translation along, one axis of the moving frame. A convention is a function
that lists one joint's motions in order (see ``docs/conventions.md``):

* `dh_motions` (standard D-H, paper 000 eq. 1): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``
* `craig_motions` (modified / proximal D-H): ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``
* `hayati_motions` (paper 002): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha) Ry(beta)``
* `urdf_motions` (the URDF joint, ROS REP 103 / urdf/XML/joint): origin
  ``Tx(x) Ty(y) Tz(z) Rz(yaw) Ry(pitch) Rx(roll)``, its local rotation error
  ``Rz(wz) Ry(wy) Rx(wx)``, then ``R(axis, offset + q)`` (revolute, continuous) or
  ``T(axis, offset + q)`` (prismatic) about / along a unit axis.

A prismatic D-H joint moves along z: its reading adds to ``d`` instead of ``theta``. A
fixed frame (a mount, a positioner base, a camera bracket) is an origin like a URDF
joint's (`frame_motions`).

Origins with a local rotation error (`origin_motions`): the nominal roll-pitch-yaw of a
URDF joint or a fixed frame is *held* (`Motion.held`: never calibrated by default), and
its error is the small rotation ``Rz(wz) Ry(wy) Rx(wx)`` composed after it, about the
origin frame's own axes; near zero, ``(wx, wy, wz)`` is a rotation vector to first order.
Roll-pitch-yaw angles are singular at ``pitch = +-pi/2`` (roll and yaw turn about one
axis there, which UR and Baxter URDFs use), so calibrating them directly lost one rank per
such origin; the local error's axes are independent whatever the nominal angles.

A joint's reading adds to exactly one motion (`Motion.joint`); code that needs the
derivative of the tool pose with respect to the joints uses that motion's column.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from kinecal.errors import InputError

__all__ = [
    "CONVENTIONS",
    "FRAME_KEYS",
    "PRISMATIC",
    "REVOLUTE",
    "Motion",
    "craig_motions",
    "dh_motions",
    "frame_motions",
    "hayati_motions",
    "joint_type",
    "local_pose_motions",
    "origin_motions",
    "pose_motions",
    "rotate_axes",
    "urdf_motions",
]

ROTATION, TRANSLATION = "R", "T"
X, Y, Z = 0, 1, 2
REVOLUTE, CONTINUOUS, PRISMATIC = "revolute", "continuous", "prismatic"

#: keys of a fixed-frame entry (and of the URDF joint origin), per convention
RXYZ = ("x", "y", "z", "rx", "ry", "rz")
RPY = ("x", "y", "z", "roll", "pitch", "yaw")
#: keys of an origin's local rotation error (rad, about the origin frame's x, y, z axes)
LOCAL = ("wx", "wy", "wz")


@dataclass(frozen=True)
class Motion:
    """One elementary motion of the chain.

    Attributes
    ----------
    kind : {"R", "T"}
        Rotation about, or translation along, an axis of the moving frame.
    axis : int or None
        0, 1, 2 for the x, y, z axis of the moving frame; None for a general `direction`.
    name : str
        Parameter name (``theta1``, ``base.x``, ``shoulder_pan_joint.offset``, ...).
    joint : int or None
        0-based index of the joint whose reading adds to this motion's value (``theta`` of
        a revolute D-H joint, ``d`` of a prismatic one, the axis motion of a URDF joint).
    direction : tuple of 3 floats or None
        Unit axis in the moving frame, for motions about / along a general axis (URDF).
    key : str
        Key of the value in its chain entry (``theta``, ``x``, ``offset``, ...).
    held : bool
        The value is an origin's nominal roll, pitch or yaw: held at nominal unless freed
        by name, its error being the origin's local rotation (`origin_motions`).
    const : float or None
        A constant value: the motion reads no parameter (the nominal roll, pitch or yaw
        of the base or tool frame, whose parameters are the local error after it:
        `local_pose_motions`).
    """

    kind: str
    axis: int | None
    name: str
    joint: int | None = None
    direction: tuple[float, float, float] | None = None
    key: str = ""
    held: bool = False
    const: float | None = None

    def vector(self, axes: Sequence[np.ndarray]) -> np.ndarray:
        """The motion's axis as a stack ``(3, ...)`` in the fixed frame, given the moving
        frame's axis stacks."""
        if self.direction is None:
            return axes[self.axis]
        d = self.direction
        return d[0] * axes[0] + d[1] * axes[1] + d[2] * axes[2]


def rotate_axes(axes: list, u: np.ndarray, d: Sequence[float], c, s) -> list:
    """Rotate a frame's axis stacks about the unit axis ``u = sum_k d_k axes_k``.

    Rodrigues' formula ``v' = c v + s (u x v) + (1 - c) (u . v) u`` with ``u . axes_k = d_k``
    and ``u x axes_k`` written through the right-handed frame (no cross products of stacks).

    Parameters
    ----------
    axes : list of 3 ndarrays, each (3, ...)
        The moving frame's x, y, z axes in the fixed frame.
    u : ndarray, shape (3, ...)
        The rotation axis in the fixed frame.
    d : sequence of 3 floats
        The rotation axis in the moving frame (unit).
    c, s : float or ndarray
        Cosine and sine of the angle (broadcast against the stacks).
    """
    a0, a1, a2 = axes
    k = 1.0 - c
    return [
        c * a0 + s * (d[2] * a1 - d[1] * a2) + (k * d[0]) * u,
        c * a1 + s * (d[0] * a2 - d[2] * a0) + (k * d[1]) * u,
        c * a2 + s * (d[1] * a0 - d[0] * a1) + (k * d[2]) * u,
    ]


def joint_type(entry: Mapping, allowed: Sequence[str] = (REVOLUTE, PRISMATIC)) -> str:
    """The joint type of a chain entry (``revolute`` unless it says otherwise)."""
    kind = entry.get("type", REVOLUTE)
    if kind not in allowed:
        raise InputError(f"joint type {kind!r}: expected one of {', '.join(allowed)}")
    return kind


def _no_beta(i: int, joint: Mapping, convention: str) -> None:
    if "beta" in joint:
        raise InputError(f"joint {i}: beta is only defined for the hayati convention, "
                         f"not {convention}")


def _dh_pair(i: int, prismatic: bool) -> tuple[Motion, Motion]:
    """``Rz(theta [+ q]) Tz(d [+ q])``: the joint reading adds to theta or to d."""
    j = i - 1
    return (Motion(ROTATION, Z, f"theta{i}", None if prismatic else j, key="theta"),
            Motion(TRANSLATION, Z, f"d{i}", j if prismatic else None, key="d"))


def dh_motions(i: int, joint: Mapping) -> list[Motion]:
    """Standard D-H joint ``i`` (1-based): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``.

    Paper 000 eq. (1) writes ``Rotate(Z, theta) Transfer(0, 0, h) Transfer(d, 0, 0)
    Rotate(X, alpha)``: its (d, h) are our (a, d). A prismatic joint (``type:
    prismatic``) adds its reading to ``d``.
    """
    _no_beta(i, joint, "dh")
    rz, tz = _dh_pair(i, joint_type(joint) == PRISMATIC)
    return [rz, tz, Motion(TRANSLATION, X, f"a{i}", key="a"),
            Motion(ROTATION, X, f"alpha{i}", key="alpha")]


def craig_motions(i: int, joint: Mapping) -> list[Motion]:
    """Modified (proximal, Craig) D-H joint ``i``: ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``
    (prismatic: ``Tz(d + q)``)."""
    _no_beta(i, joint, "craig")
    rz, tz = _dh_pair(i, joint_type(joint) == PRISMATIC)
    return [Motion(ROTATION, X, f"alpha{i}", key="alpha"),
            Motion(TRANSLATION, X, f"a{i}", key="a"), rz, tz]


def hayati_motions(i: int, joint: Mapping) -> list[Motion]:
    """Hayati joint ``i`` (paper 002): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha) [Ry(beta)]``.

    ``beta`` is present only on joints that declare it (nearly parallel consecutive axes).
    A prismatic joint adds its reading to ``d``.
    """
    rz, tz = _dh_pair(i, joint_type(joint) == PRISMATIC)
    motions = [rz, tz, Motion(TRANSLATION, X, f"a{i}", key="a"),
               Motion(ROTATION, X, f"alpha{i}", key="alpha")]
    if "beta" in joint:
        motions.append(Motion(ROTATION, Y, f"beta{i}", key="beta"))
    return motions


def pose_motions(prefix: str, keys: Sequence[str] = RXYZ) -> list[Motion]:
    """A constant pose ``Tx Ty Tz Rz Ry Rx`` (``R = Rz Ry Rx``, roll-pitch-yaw) named
    ``prefix.key`` for `keys` = (x, y, z, about-x, about-y, about-z)."""
    x, y, z, rx, ry, rz = keys
    return [
        Motion(TRANSLATION, X, f"{prefix}.{x}", key=x),
        Motion(TRANSLATION, Y, f"{prefix}.{y}", key=y),
        Motion(TRANSLATION, Z, f"{prefix}.{z}", key=z),
        Motion(ROTATION, Z, f"{prefix}.{rz}", key=rz),
        Motion(ROTATION, Y, f"{prefix}.{ry}", key=ry),
        Motion(ROTATION, X, f"{prefix}.{rx}", key=rx),
    ]


def local_pose_motions(prefix: str, rpy: Sequence[float] = (0.0, 0.0, 0.0),
                       translation: bool = True) -> list[Motion]:
    """A frame parametrised locally about its nominal orientation (the base and the tool):
    ``Tx(x) Ty(y) Tz(z)`` named ``prefix.x .. prefix.z``, the nominal roll-pitch-yaw
    ``Rz(rz0) Ry(ry0) Rx(rx0)`` as constants (`Motion.const`; left out where zero), then
    the local rotation error ``Rz(rz) Ry(ry) Rx(rx)`` named ``prefix.rz .. prefix.rx``
    (zero nominally; about the nominal frame's own axes, independent whatever the
    nominal angles, as an origin's ``wx, wy, wz`` in `origin_motions`).

    `translation` False: the rotations only (a frame whose translation is elsewhere).
    """
    x, y, z, rx, ry, rz = RXYZ
    out = [Motion(TRANSLATION, X, f"{prefix}.{x}", key=x),
           Motion(TRANSLATION, Y, f"{prefix}.{y}", key=y),
           Motion(TRANSLATION, Z, f"{prefix}.{z}", key=z)] if translation else []
    for axis, key, value in ((Z, rz, rpy[2]), (Y, ry, rpy[1]), (X, rx, rpy[0])):
        if float(value) != 0.0:
            out.append(Motion(ROTATION, axis, f"{prefix}.nominal_{key}", key=key,
                              const=float(value)))
    return [*out, Motion(ROTATION, Z, f"{prefix}.{rz}", key=rz),
            Motion(ROTATION, Y, f"{prefix}.{ry}", key=ry),
            Motion(ROTATION, X, f"{prefix}.{rx}", key=rx)]


def origin_motions(prefix: str, keys: Sequence[str] = RPY) -> list[Motion]:
    """An origin with a local rotation error: ``Tx Ty Tz Rz Ry Rx`` (`pose_motions`, the
    three rotations `held` at nominal) then ``Rz(wz) Ry(wy) Rx(wx)`` named
    ``prefix.wz .. prefix.wx`` (zero nominally; see the module docstring)."""
    pose = pose_motions(prefix, keys)
    held = [Motion(m.kind, m.axis, m.name, key=m.key, held=True) for m in pose[3:]]
    wx, wy, wz = LOCAL
    return [*pose[:3], *held,
            Motion(ROTATION, Z, f"{prefix}.{wz}", key=wz),
            Motion(ROTATION, Y, f"{prefix}.{wy}", key=wy),
            Motion(ROTATION, X, f"{prefix}.{wx}", key=wx)]


def _unit_axis(name: str, axis) -> tuple[float, float, float]:
    try:
        a = np.asarray(axis, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InputError(f"joint {name}: axis: expected 3 numbers, got {axis!r}") from None
    n = float(np.linalg.norm(a))
    if not (np.isfinite(a).all() and n > 1e-9):
        raise InputError(f"joint {name}: axis {a.tolist()}: expected a non-zero direction")
    return tuple(float(v) for v in a / n)


def urdf_motions(i: int, joint: Mapping) -> list[Motion]:
    """URDF joint ``i`` named ``joint["name"]``: the origin ``Tx(x) Ty(y) Tz(z) Rz(yaw)
    Ry(pitch) Rx(roll)`` (URDF's ``rpy``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``) and its local
    rotation error ``Rz(wz) Ry(wy) Rx(wx)`` (`origin_motions`), then the motion about
    (revolute, continuous) or along (prismatic) the unit `axis` of the joint frame by
    ``offset + q``.

    An axis along +x, +y or +z is an elementary motion; any other axis a Rodrigues step.
    """
    name = joint.get("name")
    if not isinstance(name, str) or not name:
        raise InputError(f"joint {i}: a urdf joint needs a name")
    kind = joint_type(joint, (REVOLUTE, CONTINUOUS, PRISMATIC))
    d = _unit_axis(name, joint.get("axis", (1.0, 0.0, 0.0)))
    elementary = [k for k in range(3) if d[k] == 1.0]
    axis, direction = (elementary[0], None) if elementary else (None, d)
    move = TRANSLATION if kind == PRISMATIC else ROTATION
    return [*origin_motions(name, RPY),
            Motion(move, axis, f"{name}.offset", i - 1, direction, key="offset")]


def frame_motions(name: str, keys: Sequence[str] = RXYZ) -> list[Motion]:
    """A fixed frame ``name`` in the chain: ``Tx Ty Tz Rz Ry Rx`` named ``name.x ...``
    and its local rotation error ``name.wz, name.wy, name.wx`` (`origin_motions`)."""
    return origin_motions(name, keys)


CONVENTIONS: dict[str, Callable[[int, Mapping], list[Motion]]] = {
    "dh": dh_motions,
    "craig": craig_motions,
    "hayati": hayati_motions,
    "urdf": urdf_motions,
}

#: keys of a fixed-frame entry per convention (URDF names its angles roll, pitch, yaw)
FRAME_KEYS: dict[str, tuple[str, ...]] = {"dh": RXYZ, "craig": RXYZ, "hayati": RXYZ,
                                           "urdf": RPY}
