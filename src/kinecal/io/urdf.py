"""URDF import: a serial chain of a URDF file as a ``urdf``-convention `SerialModel`.

The file is parsed by yourdfpy (the maintained URDF parser of the Python robotics stack;
``pip install kinecal[urdf]``); meshes are never loaded. The chain runs from `base_link`
(default: the root link) to `tip_link` (default: the end of the one branch that carries
moving joints, see `chain_path`). Each joint on it becomes one chain entry
(`kinecal.kinematics.serial.motions.urdf_motions`):

* ``revolute``, ``continuous``, ``prismatic``: a moving joint ``{name, type, x, y, z,
  roll, pitch, yaw, offset: 0, axis}``; its calibratable parameters are the origin's
  translation, the local rotation error composed after its ``rpy`` (which is held) and the
  offset: ``<joint>.x, .y, .z, .wz, .wy, .wx, .offset``
  (`kinecal.kinematics.serial.motions.origin_motions`: no gimbal lock at pitch = +-pi/2);
* ``fixed``: a fixed frame ``{frame: <joint>, x .. yaw}`` (held at nominal unless the
  model file says ``calibrate: true``).

Units stay the URDF's: metres, and radians in the API. The model's ``angle_unit`` is
``deg`` so that measurement CSVs carry revolute joint readings in degrees like every
kinecal model (prismatic readings in metres). The model gets a base frame and a tool
point (both zero, both calibratable): a laser tracker never sits in ``base_link`` and its
target never at the tip link's origin; the identifiability analysis decides which of the
many origin parameters are free.

Mimic joints, floating and planar joints on the chain, several roots, and branching
without `tip_link` raise `InputError` naming the joints or links involved. Several tips,
and chains with mimic (coupled) joints, are a system: `kinecal.io.urdf_tree`.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from kinecal import diagnostics
from kinecal._files import MAX_TEXT_BYTES, check_input_file
from kinecal.errors import InputError
from kinecal.io.urdf_chain import chain_path
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import xyz_rpy_from_transform

__all__ = ["MAX_URDF_JOINTS", "MOVING", "chain_path", "joint_entry", "load_urdf", "read_urdf",
           "urdf_entries"]

MOVING = ("revolute", "continuous", "prismatic")
_UNSUPPORTED = ("floating", "planar")
_RESERVED = ("base", "tool")
#: most ``<joint`` tags a URDF file may hold (transmissions name joints too): ten times the
#: largest real robot descriptions; counted on the bytes, before any parsing
MAX_URDF_JOINTS = 10_000
#: metaheuristics' search box of an imported URDF: 1 mm and 0.3 degrees
URDF_TOLERANCES = {"length": 1e-3, "angle": np.deg2rad(0.3)}


def _yourdfpy():
    try:
        import yourdfpy
    except ImportError:  # pragma: no cover - yourdfpy is a dev dependency
        raise InputError("reading URDF files needs yourdfpy: pip install kinecal[urdf]"
                         ) from None
    return yourdfpy


def read_urdf(path: str | Path):
    """Parse a URDF file with yourdfpy (no meshes, no scene graph).

    Returns
    -------
    yourdfpy.URDF

    Raises
    ------
    InputError
        Missing file, a xacro file, XML that does not parse (with the line), or a URDF that
        yourdfpy finds incomplete (first error).
    """
    path = Path(path)
    if path.suffix.lower() == ".xacro" or path.name.lower().endswith(".urdf.xacro"):
        raise InputError("a xacro file: expand it first (xacro robot.urdf.xacro > robot.urdf)",
                         file=path)
    check_input_file(path, "a URDF file")
    if path.is_dir():
        raise InputError("is a directory, expected a URDF file", file=path)
    if not path.exists():
        raise InputError("file not found", file=path)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_TEXT_BYTES + 1)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None
    if len(data) > MAX_TEXT_BYTES:
        raise InputError(f"more than {MAX_TEXT_BYTES / 1e6:.0f} MB: too large for a URDF",
                         file=path)
    tags = data.count(b"<joint")  # before parsing: a 400 000-joint file took minutes
    if tags > MAX_URDF_JOINTS:
        raise InputError(f"{tags:,} <joint> tags: expected at most {MAX_URDF_JOINTS:,} in a "
                         "robot description", file=path)
    try:  # a clean message with the line before yourdfpy's recovering parser sees it; one
        # feed of the whole text (ET.parse's 64 kB feeds made expat quadratic in a long
        # token: a 300 MB comment took many minutes)
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise InputError(f"not well-formed XML: {exc}", file=path) from None
    if root.tag != "robot":
        raise InputError(f"root element <{root.tag}>, expected <robot>", file=path)
    for tag in ("link", "joint"):
        seen: set = set()
        for element in root.findall(tag):
            name = element.get("name")
            if name in seen:
                raise InputError(f"two <{tag}> elements named {name!r}: expected unique "
                                 f"{tag} names", file=path)
            seen.add(name)
    links = {link.get("name") for link in root.findall("link")}
    if not root.findall("joint"):
        raise InputError("no <joint> elements: expected a chain of joints between links",
                         file=path)
    for k, joint in enumerate(root.findall("joint")):
        missing = [t for t in ("parent", "child") if joint.find(t) is None
                   or not joint.find(t).get("link")]
        if joint.get("name") is None or missing:
            what = "a name" if joint.get("name") is None else " and ".join(
                f"<{t} link=...>" for t in missing)
            raise InputError(f"joint {joint.get('name') or k + 1}: missing {what}", file=path)
        _check_numbers(joint, path)
        for t in ("parent", "child"):
            if joint.find(t).get("link") not in links:
                raise InputError(f"joint {joint.get('name')}: {t} link "
                                 f"{joint.find(t).get('link')!r} is not a <link> of the file",
                                 file=path)
        if joint.get("type") in ("revolute", "prismatic") and joint.find("limit") is None:
            raise InputError(f"{joint.get('type')} joint {joint.get('name')}: missing <limit "
                             "lower=... upper=... effort=... velocity=...> (URDF requires it)",
                             file=path)
    yourdfpy = _yourdfpy()
    log = logging.getLogger("yourdfpy")
    level = log.level
    log.setLevel(logging.CRITICAL)  # yourdfpy logs and recovers; kinecal raises instead
    try:
        urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                                  load_collision_meshes=False,
                                  build_collision_scene_graph=False)
    except Exception as exc:  # yourdfpy raises whatever its XML handling meets
        raise InputError(f"not a readable URDF: {type(exc).__name__}: {exc}",
                         file=path) from None
    finally:
        log.setLevel(level)
    urdf.validate(validation_fn=lambda errors: not errors)
    # limits are judged by urdf_entries (for the chain's joints only, as urdfdom does)
    errors = [e for e in urdf.errors if "<limit>" not in str(e)]
    if errors:
        raise InputError(f"invalid URDF: {errors[0]}", file=path)
    return urdf


def _check_numbers(joint: ET.Element, path: Path) -> None:
    """A joint's origin xyz / rpy and axis xyz: three finite numbers each (yourdfpy turns an
    infinite origin into NaNs of other components, and a short one into a numpy error)."""
    for tag, attr in (("origin", "xyz"), ("origin", "rpy"), ("axis", "xyz")):
        element = joint.find(tag)
        text = None if element is None else element.get(attr)
        if text is None:
            continue
        cells = text.split()
        try:
            values = [float(c) for c in cells]
        except ValueError:
            values = []
        if len(cells) != 3 or len(values) != 3 or not np.isfinite(values).all():
            raise InputError(f"joint {joint.get('name')}: <{tag} {attr}=\"{text.strip()}\">: "
                             "expected three finite numbers", file=path)


def _origin(joint) -> list[float]:
    T = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
    return [float(v) + 0.0 for v in xyz_rpy_from_transform(T)]  # no -0.0


def urdf_entries(chain: list, path: str | Path = "") -> tuple[list[dict], np.ndarray]:
    """Chain entries of the joints in `chain` and the moving joints' limits ``(n, 2)``
    (rad; prismatic: metres)."""
    path = Path(path)
    entries, limits = [], []
    for k, j in enumerate(chain):
        if j.mimic is not None:
            raise InputError(f"joint {j.name} mimics joint {j.mimic.joint}: coupled joints are "
                             "a system's (give the chain's tips with --tip-link, or end the "
                             "chain before it with --tip-link)", file=path)
        moving_before = any(c.type in MOVING for c in chain[:k])
        entry, lim = joint_entry(j, path, moving_before)
        entries.append(entry)
        if lim is not None:
            limits.append(lim)
    return entries, np.asarray(limits, dtype=float).reshape(-1, 2)


def joint_entry(j, path: Path, moving_before: bool = True
                ) -> tuple[dict, list[float] | None]:
    """The chain entry of one URDF joint (a moving joint or a fixed frame, module docstring)
    and, for a moving joint, its limits ``[lower, upper]`` (rad; prismatic: metres).

    `moving_before`: whether a moving joint precedes it (the hint of a floating joint)."""
    if j.type in _UNSUPPORTED:
        hint = "" if moving_before else f"; start the chain below it with --base-link {j.child}"
        raise InputError(f"joint {j.name} is {j.type}: kinecal models revolute, continuous, "
                         f"prismatic and fixed joints{hint}", file=path)
    x, y, z, roll, pitch, yaw = _origin(j)
    pose = {"x": x, "y": y, "z": z, "roll": roll, "pitch": pitch, "yaw": yaw,
            "parent": j.parent, "child": j.child}
    if j.type == "fixed":
        name = f"{j.name}_frame" if j.name in _RESERVED else j.name
        return {"frame": name, **pose}, None
    axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, dtype=float)
    entry = {"name": j.name, "type": j.type, **pose, "offset": 0.0,
             "axis": [float(v) for v in axis]}
    lim = j.limit
    for key in ("effort", "velocity"):
        value = None if lim is None else getattr(lim, key)
        if value is not None:
            entry[key] = float(value)
    lo = None if lim is None else lim.lower
    hi = None if lim is None else lim.upper
    if j.type == "continuous":
        return entry, [-np.pi, np.pi]
    if lo is None or hi is None or not lo < hi:
        if j.type == "prismatic":
            raise InputError(f"prismatic joint {j.name}: expected <limit lower=... "
                             "upper=...> with lower < upper (metres)", file=path)
        diagnostics.warn("urdf-joint-limits",
                         f"{path.name}: revolute joint {j.name} has no usable limits "
                         f"(lower={lo}, upper={hi}); using [-180, 180] deg")
        return entry, [-np.pi, np.pi]
    return entry, [float(lo), float(hi)]


def load_urdf(path: str | Path, *, base_link: str | None = None,
              tip_link: str | None = None) -> SerialModel:
    """Load the serial chain `base_link` -> `tip_link` of a URDF file.

    Parameters
    ----------
    path : str or Path
        The ``.urdf`` file (xacro must be expanded first).
    base_link, tip_link : str, optional
        Ends of the chain (defaults: the root link; the end of the one branch with moving
        joints, `chain_path`).

    Returns
    -------
    SerialModel
        Convention ``urdf``, lengths in metres, ``angle_unit: deg`` (revolute readings in
        measurement files), a calibratable base frame and tool point, both zero.

    Raises
    ------
    InputError
        Unreadable or invalid URDF, unknown links, branching, mimic / floating / planar
        joints on the chain, a chain without moving joints.
    """
    path = Path(path)
    urdf = read_urdf(path)
    chain = chain_path(urdf, base_link, tip_link, path)
    entries, limits = urdf_entries(chain, path)
    if len(limits) == 0:
        start = chain[0].parent if chain else base_link or "the root link"
        end = chain[-1].child if chain else tip_link or start
        raise InputError(f"no moving joint between {start} and {end}", file=path)
    start, end = chain[0].parent, chain[-1].child
    try:
        return SerialModel(
            name=urdf.robot.name or path.stem, convention="urdf", joints=entries,
            base=np.zeros(6), tool=np.zeros(3), length_unit="m", angle_unit="deg",
            joint_limits=limits, tolerances=dict(URDF_TOLERANCES),
            description=f"URDF {path.name}: chain {start} -> {end} "
                        f"({len(limits)} moving joints)",
        )
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
