"""URDF trees: several chains of one URDF file as a `SystemModel`, coupled joints read.

``load_urdf_system(path, tips, base_link=None)`` takes every chain from `base_link`
(default: the root link) to each of the tip links. Each URDF joint on those chains is one
element of the system (`kinecal.kinematics.tree.elements.Element`) with the parameters a
single chain gives it (`kinecal.io.urdf`: ``JOINT.x .. JOINT.wx, JOINT.offset`` for a
moving joint, a held fixed frame otherwise), so chains through one joint share its
parameters by name. The measurement frame (``world``, or ``measurement`` when the file has
a link named world) holds the base frame ``base.x .. base.rz`` (zero, calibratable: one
tracker frame for every chain); each tip carries its tool point ``TIP.tool.x, .y, .z``
(zero, calibratable).

A ``<mimic joint="J" multiplier="m" offset="o">`` joint on a chain reads ``m * J + o``:
its offset is its ``.offset`` parameter, its multiplier the parameter
``JOINT.multiplier``; both are calibrated like the others. The leader ``J`` becomes a
joint of the system (a column of the measurement files) even when it is on no chain.
Mimics of mimics resolve to the independent joint; cycles are refused. Mimic tags on fixed
joints (TALOS's grippers) move nothing and are ignored.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinecal.errors import InputError
from kinecal.io.urdf import MOVING, URDF_TOLERANCES, joint_entry, read_urdf
from kinecal.io.urdf_chain import _tree, chain_path
from kinecal.kinematics.serial.motions import FRAME_KEYS, frame_motions, pose_motions, urdf_motions
from kinecal.kinematics.tree.elements import FIXED, Element, Mimic, Tip
from kinecal.kinematics.tree.system import SystemModel

__all__ = ["load_urdf_system", "urdf_element"]


def urdf_element(joint, path: Path) -> Element:
    """The `Element` of one URDF joint (module docstring)."""
    entry, lim = joint_entry(joint, path)
    if "frame" in entry:
        motions = frame_motions(entry["frame"], FRAME_KEYS["urdf"])
        values = {m.name: float(entry.get(m.key, 0.0)) for m in motions}
        return Element(joint.name, joint.parent, joint.child, tuple(motions), values,
                       frozenset(values), FIXED, info={"entry": entry})
    try:
        motions = urdf_motions(1, entry)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    values = {m.name: float(entry.get(m.key, 0.0)) for m in motions}
    mimic = None
    if joint.mimic is not None:
        m = joint.mimic
        mult = 1.0 if m.multiplier is None else float(m.multiplier)
        off = 0.0 if m.offset is None else float(m.offset)
        if not (np.isfinite(mult) and np.isfinite(off)):
            raise InputError(f"joint {joint.name}: <mimic multiplier={mult} offset={off}>: "
                             "expected finite numbers", file=path)
        mimic = Mimic(str(m.joint), mult, off)
    info = {k: entry[k] for k in ("effort", "velocity") if k in entry}
    return Element(joint.name, joint.parent, joint.child, tuple(motions), values,
                   frozenset(m.name for m in motions if m.held), joint.type, joint.name,
                   mimic, (float(lim[0]), float(lim[1])), {**info, "entry": entry})


def _leaders(joint, by_name: dict, path: Path) -> list:
    """The joints `joint` mimics, directly or through other mimics (cycles stop)."""
    out, cur = [], joint
    while cur.mimic is not None and cur.type in MOVING:
        leader = by_name.get(cur.mimic.joint)
        if leader is None:
            raise InputError(f"joint {cur.name} mimics {cur.mimic.joint!r}, which is not a "
                             "joint of the file", file=path)
        if leader in out or leader is joint:
            break
        out.append(leader)
        cur = leader
    return out


def load_urdf_system(path: str | Path, tips: Sequence[str], *,
                     base_link: str | None = None) -> SystemModel:
    """The chains from `base_link` (default: the root link) to each of `tips` (link names).

    Raises
    ------
    InputError
        Unreadable URDF, unknown links, a tip not below the base, floating or planar
        joints on a chain, bad or cyclic mimics (with the file).
    """
    path = Path(path)
    if not tips:
        raise InputError("expected at least one tip link", option="--tip-link")
    urdf = read_urdf(path)
    by_child, _, root = _tree(urdf.robot.joints, path)
    base = root if base_link is None else base_link
    by_name = {j.name: j for j in urdf.robot.joints}
    joints, seen, leaders = [], set(), []
    for tip in tips:
        for j in chain_path(urdf, base_link, tip, path):
            for k in [j, *_leaders(j, by_name, path)]:
                if k is not j and k.type in MOVING and k.child not in leaders:
                    leaders.append(k.child)
                if k.name not in seen:
                    seen.add(k.name)
                    joints.append(k)
    for link in leaders:  # a leader off the chains: its link is reached too (an export
        for j in chain_path(urdf, base_link, link, path):  # keeps the coupling)
            if j.name not in seen:
                seen.add(j.name)
                joints.append(j)
    try:
        elements = [urdf_element(j, path) for j in joints]
        links = {lk.name for lk in urdf.robot.links} | set(by_child)
        world = "world" if "world" not in links else "measurement"
        bm = pose_motions("base")
        elements.insert(0, Element("base", world, base, tuple(bm), dict.fromkeys(
            (m.name for m in bm), 0.0)))
        tip_list = []
        for tip in tips:
            tm = pose_motions(f"{tip}.tool")[:3]
            tip_list.append(Tip(tip, tip, tuple(tm), dict.fromkeys((m.name for m in tm), 0.0)))
        return SystemModel(
            urdf.robot.name or path.stem, elements, tip_list, root=world, length_unit="m",
            angle_unit="deg", tolerances=dict(URDF_TOLERANCES), links=leaders,
            description=f"URDF {path.name}: {base} -> {', '.join(tips)}",
            source={"urdf": str(path), "base_link": base_link, "tips": list(tips)})
    except InputError as exc:
        if exc.file is None:
            raise InputError(exc.message, file=path, option=exc.option) from None
        raise
