"""A camera mount added to an exported URDF: the hand-eye result as a fixed joint.

Eye-in-hand: the camera link is a fixed child of the chain's flange link (the frame the
robot's flange poses were given in); eye-to-hand: of the chain's base link. The joint's
origin is the hand-eye ``X`` (``cam2flange`` or ``cam2base``) in metres; the new link is
the camera's optical frame (`kinecal.io.ros.static_tf`). The rest of the text is kept as
it is.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.io.urdf_export import urdf_joints, urdf_origin
from kinecal.kinematics.serial.frames import frame_transform
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["add_camera_mount", "chain_links"]


def chain_links(model: SerialModel, params: ArrayLike | None = None) -> tuple[str, str]:
    """The names of the chain's base link and flange link in `model`'s URDF export."""
    p = model.nominal if params is None else np.asarray(params, dtype=float)
    joints = urdf_joints(model, p)
    has_base = not np.array_equal(frame_transform(model, p, "base"), np.eye(4))
    base = joints[0].child if has_base else joints[0].parent
    return base, joints[-1].parent


def add_camera_mount(urdf: str, parent: str, child: str, X_m: NDArray[np.float64],
                     joint_name: str = "camera_mount_joint") -> str:
    """`urdf` text with link `child` fixed to link `parent` at ``X_m`` ``(4, 4)`` (metres).

    Raises
    ------
    InputError
        `parent` is no link of the URDF, or `child` / the joint name already is one.
    """
    try:
        root = ET.fromstring(urdf.encode("utf-8"))
    except ET.ParseError as exc:
        raise InputError(f"the URDF to extend is not well-formed XML: {exc}") from None
    links = {el.get("name") for el in root.findall("link")}
    joints = {el.get("name") for el in root.findall("joint")}
    if parent not in links:
        raise InputError(f"link {parent!r} is not in the URDF (links: "
                         f"{', '.join(sorted(n for n in links if n))})", option="--parent-frame")
    if child in links:
        raise InputError(f"link {child!r} is already in the URDF: name the camera frame "
                         "otherwise", option="--child-frame")
    name, k = joint_name, 2
    while name in joints:
        name, k = f"{joint_name}_{k}", k + 1
    origin = urdf_origin(np.asarray(X_m, dtype=float), 1.0)
    snippet = (f"  <link name={quoteattr(child)}/>\n"
               f"  <joint name={quoteattr(name)} type=\"fixed\">\n"
               f"    <origin xyz={quoteattr(origin['xyz'])} rpy={quoteattr(origin['rpy'])}/>\n"
               f"    <parent link={quoteattr(parent)}/>\n"
               f"    <child link={quoteattr(child)}/>\n"
               "  </joint>\n")
    end = urdf.rfind("</robot>")
    return urdf[:end] + snippet + urdf[end:]
