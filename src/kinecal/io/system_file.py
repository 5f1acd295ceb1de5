"""System files (``kind: system``): models composed into one robot system.

A system file (docs/systems.md, docs/file-formats.md)::

    kind: system
    name: rail-cell
    length_unit: mm          # every part's unit
    angle_unit: deg          # angles of this file (base frames) and revolute joint columns
    parts:
      - name: rail           # no dots, commas or spaces
        model: rail.yaml     # a bundled name, a model file, a URDF, or the model inline
        base: [0, 0, 0, 0, 0, 0]       # its base in the world (the measurement frame)
      - name: arm
        model: ur10
        on: rail                        # rides on the rail's flange ...
        base: [0, 0, 120, 0, 0, 90]     # ... mounted there
        tool: [0, 0, 150]               # its tool point (overrides the model's)
      - name: positioner
        model: {convention: dh, length_unit: mm, angle_unit: deg, joints: [...]}
        base: [1800, 0, 0, 0, 0, 0]
    fixed: [rail.base.x]     # optional: parameters held by default
    tolerances: {length: 1, angle: 0.05}   # optional

Each part is a chain and a tip named after it; ``on: PART`` puts its base on that part's
flange (``world``, the default: in the measurement frame). Parameters are the part's own,
prefixed with its name: ``arm.theta2``, ``rail.d1``, ``arm.base.x`` (the mount: given,
calibrated; absent, held at zero), ``arm.tool.x``; joints are ``PART.q1 ..`` (or
``PART.NAME`` for named joints, e.g. a URDF part's). Links: ``PART.base``, ``PART.link1
..`` after each moving joint (a URDF part's own link names, prefixed; a fixed frame's
name), and ``PART`` itself, the flange, where the tool and the parts riding on it sit.
Model paths are relative to the system file's folder.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from kinecal.errors import InputError
from kinecal.io.models import is_urdf_path, load_model, model_from_mapping, read_yaml
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.tree.elements import FIXED, Element, Tip
from kinecal.kinematics.tree.system import SystemModel

__all__ = ["load_system_file", "part_elements"]

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)
#: most parts of one system file (`kinecal.kinematics.tree.layout.MAX_TIPS`)
MAX_PARTS = 32


class PartSpec(BaseModel):
    """One part of a system file."""

    model_config = _STRICT
    name: str
    model: str | dict
    on: str = "world"
    base: tuple[float, float, float, float, float, float] | None = None
    tool: list[float] | None = None
    base_link: str | None = None
    tip_link: str | None = None

    @field_validator("name")
    @classmethod
    def _name(cls, v: str) -> str:
        if not v or v == "world" or any(c in v for c in ".,\"' \t\n"):
            raise ValueError(f"part name {v!r}: expected a non-empty name without dots, "
                             "commas, quotes or spaces, other than world")
        return v

    @field_validator("tool")
    @classmethod
    def _tool(cls, v):
        if v is not None and len(v) not in (3, 6):
            raise ValueError("expected 3 (a point) or 6 (a frame) values")
        return v


class SystemFile(BaseModel):
    """A ``kind: system`` file."""

    model_config = _STRICT
    kind: Literal["system"]
    name: str
    description: str = ""
    length_unit: str | None = None
    angle_unit: Literal["deg", "rad"] = "deg"
    parts: list[PartSpec]
    fixed: list[str] = []
    tolerances: dict[str, float] | None = None


def _part_model(part: PartSpec, folder: Path, path: Path) -> SerialModel:
    """The serial model of one part."""
    where = f"part {part.name}"
    if isinstance(part.model, dict):
        data = {"name": part.name, **part.model}
        return model_from_mapping(data, f"{path} ({where})")
    spec = Path(part.model)
    local = folder / spec
    target: str | Path = local if not spec.is_absolute() and local.exists() else part.model
    if is_urdf_path(target):
        from kinecal.io.urdf import load_urdf

        return load_urdf(target, base_link=part.base_link, tip_link=part.tip_link)
    if part.base_link or part.tip_link:
        raise InputError(f"{where}: base_link and tip_link apply to URDF models only",
                         file=path)
    return load_model(target)


def _renamed(part: str, motions) -> tuple:
    return tuple(dataclasses.replace(m, name=f"{part}.{m.name}") for m in motions)


def _child_link(part: str, entry: dict, joint: int | None, last: bool) -> str:
    if last:
        return part
    if "frame" in entry:
        return f"{part}.{entry['frame']}"
    return f"{part}.{entry['child']}" if entry.get("child") else f"{part}.link{joint}"


def part_elements(part: str, model: SerialModel, parent: str, base: np.ndarray | None,
                  tool: np.ndarray | None) -> tuple[list[Element], Tip]:
    """The elements and the tip of `model` as part `part` riding on link `parent`
    (module docstring); `base` / `tool` (rad) override the model's when given."""
    if model.joint_errors is not None or model.marker_names:
        raise InputError(f"part {part}: joint errors and markers of a part are not supported "
                         "in a system")
    chain = model.chain
    fixed = model.fixed_names
    values = dict(zip(model.parameter_names, model.nominal.tolist(), strict=False))
    by_owner: dict = {}
    for m, owner in zip(chain.motions, chain.owners, strict=True):
        by_owner.setdefault(owner, []).append(m)
    bm = by_owner["base"]
    bvals = {f"{part}.{m.name}": (float(base[k]) if base is not None else values[m.name])
             for k, m in enumerate(bm)}
    bfrozen = frozenset() if base is not None else frozenset(
        f"{part}.{m.name}" for m in bm if m.name in fixed)
    elements = [Element(f"{part}.base", parent, f"{part}.base", _renamed(part, bm), bvals,
                        bfrozen)]
    link, joint = f"{part}.base", 0
    for e, entry in enumerate(model.joints):
        ms = by_owner.get(e, [])
        moving = "frame" not in entry
        joint += moving
        child = _child_link(part, entry, joint, e == len(model.joints) - 1)
        vals = {f"{part}.{m.name}": values[m.name] for m in ms}
        frozen = frozenset(f"{part}.{m.name}" for m in ms if m.name in fixed)
        if moving:
            jname = f"{part}.{entry.get('name') or f'q{joint}'}"
            kind = entry.get("type", "revolute")
            lim = model.joint_limits[joint - 1]
            elements.append(Element(jname, link, child, _renamed(part, ms), vals, frozen, kind,
                                    jname, None, (float(lim[0]), float(lim[1])),
                                    {"entry": entry}))
        else:
            elements.append(Element(f"{part}.{entry['frame']}", link, child,
                                    _renamed(part, ms), vals, frozen, FIXED,
                                    info={"entry": entry}))
        link = child
    tm = by_owner.get("tool", [])
    tvals = {f"{part}.{m.name}": (float(tool[k]) if tool is not None and k < len(tool)
                                  else values[m.name]) for k, m in enumerate(tm)}
    tfrozen = frozenset() if tool is not None else frozenset(
        f"{part}.{m.name}" for m in tm if m.name in fixed)
    return elements, Tip(part, part, _renamed(part, tm), tvals, tfrozen)


def _with_tool(model: SerialModel, size: int) -> SerialModel:
    """`model` with a tool of `size` values (3 or 6) when its own has fewer."""
    have = 3 if model.tool is None else np.asarray(model.tool).size
    if have >= size:
        return model
    tool = np.zeros(size)
    if model.tool is not None:
        tool[:have] = np.asarray(model.tool, dtype=float)
    return dataclasses.replace(model, tool=tool, joint_limits=np.array(model.joint_limits),
                               tolerances=dict(model.tolerances or {}))


def load_system_file(path: str | Path) -> SystemModel:
    """Read a ``kind: system`` file (module docstring).

    Raises
    ------
    InputError
        Schema violations, unknown or cyclic mounts, parts in other length units, unreadable
        part models (with the file and the part).
    """
    path = Path(path)
    data = read_yaml(path)
    if isinstance(data.get("parts"), list):  # YAML 1.1 reads the key on: as true
        data["parts"] = [{("on" if k is True else k): v for k, v in part.items()}
                         if isinstance(part, dict) else part for part in data["parts"]]
    try:
        spec = SystemFile.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        raise InputError(f"invalid system file: {loc}: {err['msg']}", file=path) from None
    if not spec.parts or len(spec.parts) > MAX_PARTS:
        raise InputError(f"invalid system file: {len(spec.parts)} parts, expected 1 to "
                         f"{MAX_PARTS}", file=path)
    names = [p.name for p in spec.parts]
    scale = np.pi / 180.0 if spec.angle_unit == "deg" else 1.0
    elements: list[Element] = []
    tips: list[Tip] = []
    unit = spec.length_unit
    for part in spec.parts:
        if names.count(part.name) > 1:
            raise InputError(f"part {part.name!r} is given twice", file=path)
        if part.on != "world" and part.on not in names:
            raise InputError(f"part {part.name}: on: {part.on!r} is not a part of the system "
                             f"(parts: {', '.join(names)}; or world)", file=path)
        try:
            model = _part_model(part, path.parent, path)
        except InputError as exc:
            raise InputError(f"part {part.name}: {exc.one_line()}", file=path) from None
        unit = unit or model.length_unit
        if model.length_unit != unit:
            raise InputError(f"part {part.name}: length unit {model.length_unit}, the system's "
                             f"is {unit}: expected one length unit for every part", file=path)
        base = None if part.base is None else np.r_[part.base[:3], np.array(part.base[3:])
                                                    * scale]
        tool = None
        if part.tool is not None:
            tool = np.r_[part.tool[:3], np.array(part.tool[3:]) * scale]
            model = _with_tool(model, tool.size)
        els, tip = part_elements(part.name, model, part.on, base, tool)
        elements += els
        tips.append(tip)
    tol = dict(spec.tolerances or {})
    if "angle" in tol:
        tol["angle"] *= scale
    try:
        return SystemModel(spec.name, elements, tips, root="world", length_unit=unit,
                           angle_unit=spec.angle_unit, tolerances=tol, fixed=spec.fixed,
                           description=spec.description, source={"system": str(path)})
    except InputError as exc:
        raise InputError(exc.message, file=path, option=exc.option) from None
