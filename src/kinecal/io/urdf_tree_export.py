"""URDF export of a robot system: the whole tree, nominal or calibrated.

Every element of the system (`kinecal.kinematics.tree.SystemModel.elements`) becomes a
URDF joint between the same links: its origin the product of its motions up to the joint
motion, the joint's constant part (its offset) folded in (``R(axis, c) R(axis, q) =
R(axis, c + q)``); a coupled joint keeps a ``<mimic>`` of its independent leader with the
identified multiplier (offset folded into its origin). Motions after the joint motion (a
D-H part's ``d, a, alpha``) go into a fixed joint to the element's child link, so every
link frame of the system is the exported link's. The measurement frame is the root
(``world``), and each tip gets a fixed ``TIP_tool`` link at its tool point.

A system read from a URDF is written into a copy of that URDF (meshes, inertias,
branches off the chains kept, as `kinecal.io.urdf_patch` does for one chain): the
origins and mimic tags of its joints take the system's values, and the measurement frame
and tool links are added.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from kinecal.errors import InputError
from kinecal.io.urdf_export import (
    _PER_M,
    URDFJoint,
    _axis,
    _motion,
    _Names,
    _num,
    joints_string,
    urdf_origin,
)
from kinecal.io.urdf_patch import _add_joint, _link, _parse, _set_origin
from kinecal.kinematics.tree.system import SystemModel

__all__ = ["patched_tree_urdf", "tree_joints", "tree_urdf_string"]


def _product(motions, values) -> np.ndarray:
    T = np.eye(4)
    for m in motions:
        T = T @ _motion(m, values[m.name])
    return T


def tree_joints(system: SystemModel, params: ArrayLike | None = None, *,
                taken=(), taken_joints=()) -> list[URDFJoint]:
    """The URDF joints of `system` at `params` (default nominal), root first (lengths in
    the system's unit); link and joint names kinecal adds (the measurement frame's joint,
    tool links) avoid the system's and `taken`, `taken_joints`."""
    p = system._one_vector(params)
    values = dict(zip(system.parameter_names, p.tolist(), strict=True))
    links = _Names(set(system.links) | set(taken))
    names = _Names({e.name for e in system.elements} | set(taken_joints))
    out: list[URDFJoint] = []
    for e in system.elements:
        if not e.moving:
            name = names(f"{e.child}_joint") if e.parent == system.root else e.name
            out.append(URDFJoint(name, "fixed", e.parent, e.child, _product(e.motions,
                                                                            values)))
            continue
        k = next(i for i, m in enumerate(e.motions) if m.joint is not None)
        origin = _product(e.motions[:k + 1], values)
        post = _product(e.motions[k + 1:], values)
        extra = {key: float(e.info[key]) for key in ("effort", "velocity") if key in e.info}
        if e.mimic is not None:
            extra["mimic"] = (e.mimic.leader, values[f"{e.joint}.multiplier"])
        child = e.child if np.array_equal(post, np.eye(4)) else links(f"{e.child}_joint")
        limits = None if e.type == "continuous" or e.limits is None else e.limits
        out.append(URDFJoint(e.name, e.type, e.parent, child, origin, _axis(e.motions[k]),
                             limits, extra))
        if child != e.child:
            out.append(URDFJoint(f"{e.name}_frame", "fixed", child, e.child, post))
    for tip in system.tips:
        spec = system.tip_spec(tip)
        out.append(URDFJoint(names(f"{tip}_tool_joint"), "fixed", spec.link,
                             links(f"{tip}_tool"), _product(spec.motions, values)))
    return out


def tree_urdf_string(system: SystemModel, params: ArrayLike | None = None, *,
                     name: str | None = None, comment: str | None = None) -> str:
    """The URDF text of the whole tree of `system` at `params` (metres, radians)."""
    return joints_string(tree_joints(system, params), system.length_unit,
                         name or system.name, comment)


def _mimic(el: ET.Element, leader: str, mult: float) -> None:
    node = el.find("mimic")
    if node is None:
        node = ET.SubElement(el, "mimic")
    node.attrib.clear()
    node.attrib.update({"joint": leader, "multiplier": _num(mult), "offset": "0.0"})


def patched_tree_urdf(source: str | Path, system: SystemModel,
                      params: ArrayLike | None = None, *, comment: str | None = None) -> str:
    """The text of `source` (the URDF `system` was read from) with `system`'s values at
    `params` on every chain (module docstring)."""
    source = Path(source)
    per_m = _PER_M[system.length_unit]
    robot = _parse(source)
    if robot.tag != "robot":
        raise InputError(f"root element <{robot.tag}>, expected <robot>", file=source)
    by_pair = {(_link(j, "parent"), _link(j, "child")): j for j in robot.findall("joint")}
    links = {lk.get("name") for lk in robot.findall("link")}
    children = {pair[1] for pair in by_pair}
    joints = tree_joints(system, params, taken=links,
                         taken_joints={j.get("name") for j in robot.findall("joint")})
    for jt in joints:
        el = by_pair.get((jt.parent, jt.child))
        if el is not None:
            _set_origin(el, jt.origin, per_m)
            if "mimic" in jt.extra:
                _mimic(el, *jt.extra["mimic"])
        elif jt.parent == system.root:  # the measurement frame above the chains' base
            base = jt.child
            if base in children:  # a base link below the file's root: a child frame of it
                name = _Names(links)("measurement_frame")
                from kinecal.spatial import invert_transform

                _add_joint(robot, URDFJoint(jt.name, "fixed", base, name,
                                            invert_transform(jt.origin)), per_m)
            else:
                robot.append(ET.Element("link", {"name": jt.parent}))
                el = ET.SubElement(robot, "joint", {"name": jt.name, "type": "fixed"})
                ET.SubElement(el, "origin", urdf_origin(jt.origin, per_m))
                ET.SubElement(el, "parent", {"link": jt.parent})
                ET.SubElement(el, "child", {"link": jt.child})
        elif jt.type == "fixed" and jt.parent in links:  # a tool link kinecal adds
            _add_joint(robot, jt, per_m)
        else:
            raise InputError(f"joint {jt.name} ({jt.parent} -> {jt.child}) is not in "
                             f"{source.name}: not the URDF the system came from", file=source)
    if comment:
        robot.insert(0, ET.Comment(" " + " ".join(comment.replace("--", "- -").split()) + " "))
    ET.indent(robot, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
