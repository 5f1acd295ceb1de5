"""The pieces a robot system is built from: `Element` (the motions between a parent and a
child link), `Tip` (a chain's end with its tool point) and the checks of the tree they make.

An element is what a URDF joint is (an origin, then a motion about or along an axis), or a
part of a composed system (a mount, one D-H joint); its motions are the elementary motions
of `kinecal.kinematics.serial.motions`, already named by the *system's* parameter names, so
that two chains through one element share its parameters by name.

A coupled (mimic) joint moves with another joint: ``value = multiplier * leader + offset``
(URDF ``<mimic joint= multiplier= offset=>``). Its offset is the element's own joint-offset
parameter (the two would be indistinguishable); its multiplier becomes a parameter
``JOINT.multiplier``. A mimic of a mimic is resolved to the independent joint at the end
(`resolve_mimics`: multipliers multiplied, offsets carried), so that each coupled joint is
one multiplier times one reading; a cycle is refused.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from kinecal.errors import InputError
from kinecal.kinematics.serial.motions import Motion

__all__ = ["FIXED", "Element", "Mimic", "Tip", "paths_to", "resolve_mimics"]

FIXED = "fixed"
#: the element types that move (a reading adds to one of their motions)
MOVING = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class Mimic:
    """A coupled joint's law ``value = multiplier * leader + offset``.

    Attributes
    ----------
    leader : str
        The joint it follows (after `resolve_mimics`: an independent joint).
    multiplier : float
    offset : float
        Radians (revolute) or length unit (prismatic).
    """

    leader: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Element:
    """The motions between `parent` and `child` link (module docstring).

    Attributes
    ----------
    name : str
        The joint's or frame's name (URDF joint name, ``PART.q3``, ``PART.base``).
    parent, child : str
        Link names.
    motions : tuple of Motion
        In order from the parent link frame; parameter names are the system's. The moving
        motion of a moving element has ``joint = 0`` (renumbered per chain).
    values : dict
        Nominal value of each motion's parameter (length unit, rad).
    frozen : frozenset of str
        Parameters held at nominal unless freed by name.
    type : str
        ``fixed``, ``revolute``, ``continuous`` or ``prismatic``.
    joint : str or None
        The joint's name in the system (moving elements; the CSV column of its reading).
    mimic : Mimic or None
        Coupled joints: the law (no reading of their own).
    limits : tuple of float or None
        Joint range (rad; prismatic: length unit).
    info : dict
        What an export keeps (``effort``, ``velocity`` of a URDF joint).
    """

    name: str
    parent: str
    child: str
    motions: tuple[Motion, ...]
    values: Mapping[str, float]
    frozen: frozenset = frozenset()
    type: str = FIXED
    joint: str | None = None
    mimic: Mimic | None = None
    limits: tuple[float, float] | None = None
    info: Mapping = field(default_factory=dict)

    @property
    def moving(self) -> bool:
        """True for revolute, continuous and prismatic elements."""
        return self.type in MOVING


@dataclass(frozen=True)
class Tip:
    """The end of one chain: a link and the tool point (or frame) on it.

    Attributes
    ----------
    name : str
        The tip's name (the link of a URDF tip, the part of a composed system): what a
        measurement row's ``tip`` column says.
    link : str
        The link the tool sits on.
    motions : tuple of Motion
        The tool's motions after the link frame (``TIP.tool.x ..``).
    values : dict
        Their nominal values.
    frozen : frozenset of str
        Tool parameters held (a tool absent from the file: zero and held).
    """

    name: str
    link: str
    motions: tuple[Motion, ...]
    values: Mapping[str, float]
    frozen: frozenset = frozenset()


def paths_to(elements: Sequence[Element], links: Sequence[str], root: str
             ) -> dict[str, tuple[Element, ...]]:
    """The elements from `root` to each of `links`, root first.

    Raises
    ------
    InputError
        A link that is the child of two elements, or not below `root`.
    """
    by_child: dict[str, Element] = {}
    for e in elements:
        if e.child in by_child:
            raise InputError(f"link {e.child!r} is the child of two joints "
                             f"({by_child[e.child].name}, {e.name}): not a tree")
        by_child[e.child] = e
    out = {}
    for link in links:
        path, cur, seen = [], link, set()
        while cur != root:
            if cur not in by_child or cur in seen:
                raise InputError(f"link {link!r} is not below {root!r}: no chain between them")
            seen.add(cur)
            path.append(by_child[cur])
            cur = by_child[cur].parent
        out[link] = tuple(path[::-1])
    return out


def resolve_mimics(elements: Sequence[Element]) -> list[Element]:
    """`elements` with every mimic resolved to an independent leader (module docstring).

    Raises
    ------
    InputError
        A mimic of an unknown or fixed joint, or a cycle of mimics.
    """
    joints = {e.joint: e for e in elements if e.moving and e.joint is not None}
    out = []
    for e in elements:
        if e.mimic is None or not e.moving:
            out.append(e)
            continue
        mult, off, cur, seen = 1.0, 0.0, e, [e.joint]
        while cur.mimic is not None:
            m = cur.mimic
            mult, off = mult * m.multiplier, mult * m.offset + off
            if m.leader not in joints:
                raise InputError(f"joint {cur.joint} mimics {m.leader!r}, which is not a "
                                 "moving joint of the file (expected a revolute, continuous "
                                 "or prismatic joint)")
            if m.leader in seen:
                raise InputError(f"joints {' -> '.join([*seen, m.leader])} mimic each other in "
                                 "a cycle: expected each coupled joint to follow an independent "
                                 "one")
            seen.append(m.leader)
            cur = joints[m.leader]
        if mult == 0.0 or not abs(mult) < 1e6:
            raise InputError(f"joint {e.joint}: mimic multiplier {mult:g}: expected a finite "
                             "non-zero multiplier")
        out.append(Element(e.name, e.parent, e.child, e.motions, e.values, e.frozen, e.type,
                           e.joint, Mimic(cur.joint, mult, off), e.limits, e.info))
    return out
