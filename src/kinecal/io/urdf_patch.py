"""A calibrated URDF written into the URDF it came from.

A robot's URDF carries more than the chain kinecal calibrates: meshes and inertias on the
links, other branches (a gripper, sensor frames), transmissions, simulator tags. Exporting
a model imported from a URDF therefore edits a copy of that file: the ``<origin>`` of
every joint on the chain gets the calibrated values (with a joint's ``offset`` folded into
its origin, since ``R(axis, c) R(axis, q) = R(axis, c + q)``), and kinecal adds

* the base frame, when it is not the identity: a new root link ``world`` (the measurement
  frame) above the chain's base link when that link is the file's root, else a child
  link ``measurement_frame`` of the base link (the inverse transform);
* the tool point (or one link per marker), a fixed child of the chain's last link.

Everything else, comments included, is kept as it is. Lengths are written in metres and
angles in radians, floats with the digits that round-trip.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from numpy.typing import ArrayLike

from kinecal._files import write_text_atomic
from kinecal.errors import InputError
from kinecal.io.urdf_export import URDFJoint, urdf_joints, urdf_origin
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import invert_transform

__all__ = ["patched_urdf", "save_patched_urdf"]


def _parse(source: Path) -> ET.Element:
    try:
        parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
        return ET.parse(source, parser=parser).getroot()
    except ET.ParseError as exc:
        raise InputError(f"not well-formed XML: {exc}", file=source) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc}", file=source) from None


def _link(el: ET.Element, tag: str) -> str | None:
    node = el.find(tag)
    return None if node is None else node.get("link")


def _set_origin(joint: ET.Element, T, per_m: float) -> None:
    origin = joint.find("origin")
    if origin is None:
        origin = ET.Element("origin")
        joint.insert(0, origin)
    origin.attrib.clear()
    origin.attrib.update(urdf_origin(T, per_m))


def _add_joint(robot: ET.Element, jt: URDFJoint, per_m: float) -> None:
    ET.SubElement(robot, "link", {"name": jt.child})
    el = ET.SubElement(robot, "joint", {"name": jt.name, "type": "fixed"})
    ET.SubElement(el, "origin", urdf_origin(jt.origin, per_m))
    ET.SubElement(el, "parent", {"link": jt.parent})
    ET.SubElement(el, "child", {"link": jt.child})


def patched_urdf(source: str | Path, model: SerialModel, params: ArrayLike | None = None, *,
                 comment: str | None = None) -> str:
    """The text of `source` with `model`'s values at `params` on its chain.

    Parameters
    ----------
    source : str or Path
        The URDF `model` was loaded from (`kinecal.io.urdf.load_urdf`).
    model : SerialModel
        Convention ``urdf``; its joints' ``parent``/``child`` links must be joints of
        `source`.
    params : array_like, shape (n_params,), optional
        Parameter vector (e.g. identified values); nominal if omitted.
    comment : str, optional
        An XML comment put first inside ``<robot>``.
    """
    source = Path(source)
    if model.convention != "urdf":
        raise InputError(f"model {model.name!r} is a {model.convention} model: only a model "
                         "loaded from this URDF can be written into it", file=source)
    per_m = {"m": 1.0, "mm": 1000.0}[model.length_unit]
    robot = _parse(source)
    if robot.tag != "robot":
        raise InputError(f"root element <{robot.tag}>, expected <robot>", file=source)
    elements = {(_link(j, "parent"), _link(j, "child")): j for j in robot.findall("joint")}
    children = {pair[1] for pair in elements}
    links = {lk.get("name") for lk in robot.findall("link")}
    for entry in model.joints:
        pair = (entry.get("parent"), entry.get("child"))
        name = entry.get("name") or entry.get("frame")
        el = elements.get(pair)
        fixed = "frame" in entry
        if el is None or name not in (el.get("name"), f"{el.get('name')}_frame") or \
                fixed != (el.get("type") == "fixed"):
            raise InputError(f"joint {name} ({pair[0]} -> {pair[1]}) of model {model.name!r} "
                             f"is not in {source.name}: not the URDF the model came from",
                             file=source)
    joints = urdf_joints(model, params, taken_links=links,
                         taken_joints={j.get("name") for j in robot.findall("joint")})
    base_link = model.joints[0]["parent"]
    for jt in joints:
        el = elements.get((jt.parent, jt.child))
        if el is not None:
            _set_origin(el, jt.origin, per_m)
        elif jt.child == base_link and base_link in children:  # measurement frame below
            name, k = "measurement_frame", 2
            while name in links:
                name, k = f"measurement_frame_{k}", k + 1
            _add_joint(robot, URDFJoint(jt.name, "fixed", base_link, name,
                                        invert_transform(jt.origin)), per_m)
        elif jt.child == base_link:  # a new root above the file's root
            robot.append(ET.Element("link", {"name": jt.parent}))
            el = ET.SubElement(robot, "joint", {"name": jt.name, "type": "fixed"})
            ET.SubElement(el, "origin", urdf_origin(jt.origin, per_m))
            ET.SubElement(el, "parent", {"link": jt.parent})
            ET.SubElement(el, "child", {"link": jt.child})
        else:  # tool point(s) and a flange kinecal adds below the chain
            _add_joint(robot, jt, per_m)
    if comment:
        robot.insert(0, ET.Comment(" " + " ".join(comment.replace("--", "- -").split()) + " "))
    ET.indent(robot, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def save_patched_urdf(source: str | Path, model: SerialModel, path: str | Path,
                      params: ArrayLike | None = None, *, comment: str | None = None) -> None:
    """Write `patched_urdf` to `path` (atomic)."""
    write_text_atomic(path, patched_urdf(source, model, params, comment=comment))
