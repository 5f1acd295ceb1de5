"""URDF export of any `SerialModel` (dh, craig, hayati, urdf), nominal or calibrated.

The URDF is built from the chain's actual joint frames, not from a D-H -> URDF formula:

1. the chain's motions are composed at the zero configuration (with the given parameter
   vector); each moving joint's URDF origin is the product of the motions since the last
   link frame, including the joint's own constant part (``theta``, a urdf ``offset``, the
   ``d`` of a prismatic D-H joint), since ``R(axis, c) R(axis, q) = R(axis, c + q)``;
2. for the D-H family, each joint frame is then slid along its own axis to the point of the
   axis nearest the previous joint frame's origin. Sliding along the axis changes nothing
   kinematically (a rotation about, or translation along, an axis commutes with a
   translation along it; the next origin takes the opposite shift), but keeps the origins
   within the arm's size where D-H puts them far away: nearly parallel consecutive axes
   place the common normal, and with it ``d``, arbitrarily far along the axis (the
   hundreds-of-metres offsets of naive conversions of calibrated UR D-H tables).
   Origins of ``urdf`` models are kept where the model has them (their link frames carry
   the user's meshes).

Tree: ``world`` (the measurement frame; only when the base frame is not the identity)
-> ``base_joint`` -> the base link -> one joint per moving joint and per fixed frame ->
``flange_joint`` -> ``flange`` (when the last joint frame is not the flange frame) ->
``tool_joint`` -> ``tool`` (the tool point or frame; with several markers one
``tool_NAME_joint`` -> ``tool_NAME`` per marker). Lengths are written in metres and
angles in radians whatever the model's units, floats with the digits that round-trip.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal._files import write_text_atomic
from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import marker_parameter_names
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC, ROTATION, Motion
from kinecal.spatial import matrix_from_axis_angle, rot_x, rot_y, rot_z, xyz_rpy_from_transform

__all__ = ["URDFJoint", "joints_string", "save_urdf", "urdf_joints", "urdf_origin",
           "urdf_string"]

Array = NDArray[np.float64]
_ROT = (rot_x, rot_y, rot_z)
#: divisor from the model's length unit to metres (a division keeps 109.15 mm -> 0.10915)
_PER_M = {"m": 1.0, "mm": 1000.0}
#: components below this (metres, radians) are round-off of cos(pi/2) and the like: 0
_ROUND_OFF = 1e-15


@dataclass
class URDFJoint:
    """One joint of the exported tree (lengths in the model's unit until written).

    Attributes
    ----------
    name, type, parent, child : str
        URDF joint name, type (``fixed``, ``revolute``, ``continuous``, ``prismatic``) and
        link names.
    origin : ndarray, shape (4, 4)
        Joint frame in the parent link frame.
    axis : ndarray, shape (3,) or None
        Unit axis in the joint frame (moving joints).
    limits : tuple of float or None
        ``(lower, upper)`` (rad; prismatic: model length unit).
    extra : dict
        ``effort`` and ``velocity`` kept from an imported URDF.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: Array
    axis: Array | None = None
    limits: tuple[float, float] | None = None
    extra: dict = field(default_factory=dict)


def _axis(m: Motion) -> Array:
    if m.direction is not None:
        return np.asarray(m.direction, dtype=float)
    a = np.zeros(3)
    a[m.axis] = 1.0
    return a


def _motion(m: Motion, value: float) -> Array:
    """The 4x4 transform of motion `m` by `value`."""
    T = np.eye(4)
    if m.kind == ROTATION:
        T[:3, :3] = (_ROT[m.axis](value) if m.direction is None
                     else matrix_from_axis_angle(_axis(m) * value))
    else:
        T[:3, 3] = _axis(m) * value
    return T


def _translation(v: Array) -> Array:
    T = np.eye(4)
    T[:3, 3] = v
    return T


class _Names:
    """Names generated for links and joints kinecal adds (``world``, ``link_2``, ``tool``),
    never equal to a name the model or the source URDF already uses (`taken`)."""

    def __init__(self, taken) -> None:
        self.used: set[str] = set(taken)

    def __call__(self, name: str) -> str:
        out, k = name, 2
        while out in self.used:
            out, k = f"{name}_{k}", k + 1
        self.used.add(out)
        return out


def urdf_joints(model: SerialModel, params: ArrayLike | None = None, *,
                taken_links=(), taken_joints=()) -> list[URDFJoint]:
    """The exported tree of `model` at `params` (default nominal), root first.

    See the module docstring for the construction. Lengths stay in the model's unit here.
    Links and joints the chain names (a ``urdf`` model's ``parent``, ``child`` and joint
    names) keep their names; those kinecal adds avoid them and `taken_links`,
    `taken_joints` (the other names of a source URDF).
    """
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    if p.shape != (model.n_params,):
        raise InputError(f"parameters: expected {model.n_params} values, got {p.shape}")
    chain = model.chain
    idx = {n: k for k, n in enumerate(model.parameter_names)}
    slide = model.convention != "urdf"
    entries = list(model.joints)
    given = {e[k] for e in entries for k in ("parent", "child") if e.get(k)}
    names = _Names(given | set(taken_links))
    joint_names = _Names({e.get("name") or e.get("frame") for e in entries} | set(taken_joints))
    out: list[URDFJoint] = []
    groups: dict = {}
    for m, owner in zip(chain.motions, chain.owners, strict=True):
        groups.setdefault(owner, []).append(m)

    def product(motions) -> Array:
        T = np.eye(4)
        for m in motions:
            T = T @ _motion(m, m.const if m.const is not None else p[idx[m.name]])
        return T

    first = entries[0] if entries else {}
    parent = first.get("parent") or names("base_link")
    base_T = product(groups["base"])
    if not np.array_equal(base_T, np.eye(4)):
        out.append(URDFJoint(joint_names("base_joint"), "fixed", names("world"), parent,
                             base_T))
    W = np.eye(4)  # parent link frame in the base link frame (zero configuration)
    pending = np.eye(4)
    j = 0
    for e, entry in enumerate(entries):
        motions = groups.get(e, [])
        if "frame" in entry:
            child = entry.get("child") or names(entry["frame"])
            origin = pending @ product(motions)
            out.append(URDFJoint(entry["frame"], "fixed", parent, child, origin))
            W, parent, pending = W @ origin, child, np.eye(4)
            continue
        k = next(i for i, m in enumerate(motions) if m.joint is not None)
        joint = motions[k]
        origin = pending @ product(motions[: k + 1])  # the joint's constant part included
        axis = _axis(joint)
        t = 0.0
        if slide:  # slide the joint frame along its axis, next to the previous origin
            frame = W @ origin
            u = frame[:3, :3] @ axis
            t = float(u @ (W[:3, 3] - frame[:3, 3]))
            origin = origin @ _translation(t * axis)
        kind = entry.get("type", "revolute")
        name = entry.get("name") or joint_names(f"joint_{j + 1}")
        child = entry.get("child") or names(f"link_{j + 1}")
        lo, hi = (float(v) for v in model.joint_limits[j])
        extra = {key: float(entry[key]) for key in ("effort", "velocity") if key in entry}
        out.append(URDFJoint(name, kind, parent, child, origin, axis,
                             None if kind == "continuous" else (lo, hi), extra))
        W, parent = W @ origin, child
        pending = _translation(-t * axis) @ product(motions[k + 1:])
        j += 1
    if not np.array_equal(pending, np.eye(4)):
        child = names("flange")
        out.append(URDFJoint(joint_names("flange_joint"), "fixed", parent, child, pending))
        parent = child
    if model.marker_names:  # several markers: one tool link each
        for marker in model.marker_names:
            xyz = p[model.index(marker_parameter_names(marker))]
            out.append(URDFJoint(joint_names(f"tool_{marker}_joint"), "fixed", parent,
                                 names(f"tool_{marker}"), _translation(xyz)))
        return out
    out.append(URDFJoint(joint_names("tool_joint"), "fixed", parent, names("tool"),
                         product(groups["tool"])))
    return out


def _num(v: float) -> str:
    v = float(v)
    return repr(0.0 if abs(v) < _ROUND_OFF else v)  # shortest round-trip digits, no -0.0


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def urdf_origin(T: Array, per_m: float) -> dict[str, str]:
    """``{"xyz": ..., "rpy": ...}`` attributes of a URDF ``<origin>`` for the transform `T`
    ``(4, 4)`` (translation divided by `per_m` to metres)."""
    xyzrpy = xyz_rpy_from_transform(T)
    return {"xyz": _vec(xyzrpy[:3] / per_m), "rpy": _vec(xyzrpy[3:])}


def urdf_string(model: SerialModel, params: ArrayLike | None = None, *,
                name: str | None = None, comment: str | None = None) -> str:
    """The URDF text of `model` at `params` (metres, radians).

    Parameters
    ----------
    model : SerialModel
        Any convention.
    params : array_like, shape (n_params,), optional
        Parameter vector (e.g. a calibration's identified values); nominal if omitted.
    name : str, optional
        Robot name (default: the model's).
    comment : str, optional
        Text of an XML comment at the top (what the file was made from).
    """
    return joints_string(urdf_joints(model, params), model.length_unit, name or model.name,
                         comment)


def joints_string(joints: list[URDFJoint], length_unit: str, name: str,
                  comment: str | None = None) -> str:
    """The URDF text of the tree `joints` (root first; lengths in `length_unit`, written
    in metres). A joint whose ``extra`` has ``mimic: (leader, multiplier)`` gets a
    ``<mimic>`` tag (its offset is in its origin)."""
    per_m = _PER_M.get(length_unit)
    if per_m is None:
        raise InputError(f"length unit {length_unit!r}: expected mm or m")
    robot = ET.Element("robot", {"name": name})
    if comment:
        robot.append(ET.Comment(" " + " ".join(comment.replace("--", "- -").split()) + " "))
    links = list(dict.fromkeys([joints[0].parent] + [jt.child for jt in joints]))
    for link in links:
        ET.SubElement(robot, "link", {"name": link})
    for jt in joints:
        el = ET.SubElement(robot, "joint", {"name": jt.name, "type": jt.type})
        ET.SubElement(el, "origin", urdf_origin(jt.origin, per_m))
        ET.SubElement(el, "parent", {"link": jt.parent})
        ET.SubElement(el, "child", {"link": jt.child})
        if jt.axis is not None:
            ET.SubElement(el, "axis", {"xyz": _vec(jt.axis)})
            limit = {"effort": _num(jt.extra.get("effort", 0.0)),
                     "velocity": _num(jt.extra.get("velocity", 0.0))}
            if jt.limits is not None:
                f = per_m if jt.type == PRISMATIC else 1.0
                limit = {"lower": _num(jt.limits[0] / f), "upper": _num(jt.limits[1] / f),
                         **limit}
            ET.SubElement(el, "limit", limit)
            if "mimic" in jt.extra:
                leader, mult = jt.extra["mimic"]
                ET.SubElement(el, "mimic", {"joint": leader, "multiplier": _num(mult),
                                            "offset": "0.0"})
    ET.indent(robot, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def save_urdf(model: SerialModel, path: str | Path, params: ArrayLike | None = None, *,
              name: str | None = None, comment: str | None = None) -> None:
    """Write `urdf_string` to `path` (atomic)."""
    write_text_atomic(path, urdf_string(model, params, name=name, comment=comment))
