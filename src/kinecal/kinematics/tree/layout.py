"""The layout of a system: its parameter vector, its joints and the motions of each chain.

`build_layout` walks the elements from the root to every tip (and to further links that
measurements may name, e.g. a positioner's table carrying a workpiece):

* parameters: the motions' parameters of every element on those paths, each once, in
  path order; then the coupled joints' multipliers (``JOINT.multiplier``); then each tip's
  tool. A name met in two different elements is refused (two chains share a parameter
  only by sharing its element);
* joints: the independent moving joints on the paths and the leaders of the coupled ones,
  in path order: the system's joint readings (the CSV columns);
* chains: per tip, the motions root -> tip link -> tool, each indexing the parameter
  vector, and per chain joint the system joint it reads and its multiplier
  (`kinecal.kinematics.tree.chain.PathChain`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.motions import PRISMATIC, ROTATION, TRANSLATION, Motion
from kinecal.kinematics.tree.chain import PathChain
from kinecal.kinematics.tree.elements import Element, Tip, paths_to, resolve_mimics

__all__ = ["MAX_TIPS", "Layout", "build_layout"]

#: most tips (chains) of one system: far beyond dual arms, a torso with a head and two
#: arms, or a cell of a few robots and positioners
MAX_TIPS = 32


@dataclass
class Layout:
    """What `build_layout` found (module docstring).

    Attributes
    ----------
    names : list of str
        The parameter vector.
    nominal : ndarray, shape (n_params,)
    angle : ndarray of bool, shape (n_params,)
        True for angles (the value of a rotation; a multiplier is not one).
    frozen : set of str
        Parameters held by default.
    joints : list of str
        System joint names (reading columns), in order.
    kinds : list of str
        ``revolute`` or ``prismatic`` per joint.
    limits : ndarray, shape (n_joints, 2)
    chains : dict of str to PathChain
        Per tip.
    paths : dict of str to tuple of Element
        Root to each link reached (tips' links and the further links).
    owners : dict of str to str
        Element (or ``tool of TIP``, ``multiplier of J``) of each parameter.
    elements : list of Element
        Every element on the paths (mimics resolved), in path order.
    """

    names: list[str]
    nominal: NDArray[np.float64]
    angle: NDArray[np.bool_]
    frozen: set[str]
    joints: list[str]
    kinds: list[str]
    limits: NDArray[np.float64]
    chains: dict[str, PathChain]
    paths: dict[str, tuple[Element, ...]]
    owners: dict[str, str] = field(default_factory=dict)
    elements: list[Element] = field(default_factory=list)


def _add_params(names, values, angle, owners, motions, vals: Mapping, owner: str) -> None:
    for m in motions:
        if m.name in owners:
            if owners[m.name] != owner:
                raise InputError(f"parameter {m.name!r} belongs to both {owners[m.name]} and "
                                 f"{owner}: expected one name per parameter")
            continue
        try:
            v = float(vals[m.name])
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{owner}: parameter {m.name!r} has no numeric value") from None
        if not np.isfinite(v):
            raise InputError(f"{owner}: parameter {m.name!r} = {v}: expected a finite value")
        owners[m.name] = owner
        names.append(m.name)
        values.append(v)
        angle.append(m.kind == ROTATION)


def _joints(paths: Mapping[str, Sequence[Element]], every: Sequence[Element]
            ) -> tuple[list[str], list[Element]]:
    """System joints in path order (leaders of coupled joints where first needed) and the
    element of each."""
    by_joint = {e.joint: e for e in every if e.moving}
    out: list[str] = []
    owner: list[Element] = []
    for path in paths.values():
        for e in path:
            if not e.moving:
                continue
            j = e.mimic.leader if e.mimic is not None else e.joint
            if j not in out:
                out.append(j)
                owner.append(by_joint[j])
    return out, owner


def _chain(name: str, path: Sequence[Element], tail: Sequence[Motion], index: Mapping,
           joints: list[str], n_params: int, point: bool = False) -> PathChain:
    """The `PathChain` of `path` then the motions `tail` (a tool; none for a link)."""
    motions, source, mult = [], [], []
    for e in path:
        for m in e.motions:
            if m.joint is not None:
                m = replace(m, joint=len(source))
                leader = e.mimic.leader if e.mimic is not None else e.joint
                source.append(joints.index(leader))
                mult.append(index[f"{e.joint}.multiplier"] if e.mimic is not None else -1)
            motions.append(m)
    motions += list(tail)
    idx = np.array([index[m.name] for m in motions], dtype=np.intp)
    return PathChain(name, motions, idx, n_params, np.array(source, dtype=np.intp),
                     np.array(mult, dtype=np.intp), point)


def build_layout(elements: Sequence[Element], tips: Sequence[Tip], root: str,
                 links: Sequence[str] = ()) -> Layout:
    """The layout of the system of `elements` with `tips` (module docstring).

    Raises
    ------
    InputError
        No tip, too many, duplicate tip or joint names, a tip link not below `root`, a
        parameter in two elements, a coupled joint's bad law (`resolve_mimics`).
    """
    if not tips:
        raise InputError("a system needs at least one tip (the end of a chain)")
    if len(tips) > MAX_TIPS:
        raise InputError(f"{len(tips)} tips: expected at most {MAX_TIPS} chains in one system")
    names_seen = [t.name for t in tips]
    twice = sorted({n for n in names_seen if names_seen.count(n) > 1})
    if twice:
        raise InputError(f"tip {twice[0]!r} is given twice: expected each tip once",
                         option="--tip-link")
    every = resolve_mimics(elements)
    moving = [e.joint for e in every if e.moving]
    twice = sorted({j for j in moving if moving.count(j) > 1})
    if twice:
        raise InputError(f"two joints named {twice[0]!r}: expected unique joint names")
    reach = list(dict.fromkeys([t.link for t in tips] + list(links)))
    paths = paths_to(every, reach, root)
    used: list[Element] = []
    for path in paths.values():
        used += [e for e in path if e not in used]
    for path in list(paths.values()):  # every link on the way is reached too
        for i, e in enumerate(path):
            paths.setdefault(e.child, path[:i + 1])
    paths.setdefault(root, ())
    names: list[str] = []
    values: list[float] = []
    angle: list[bool] = []
    owners: dict[str, str] = {}
    frozen: set[str] = set()
    for e in used:
        _add_params(names, values, angle, owners, e.motions, e.values, f"joint {e.name}")
        frozen |= set(e.frozen)
        if e.mimic is not None:  # the coupled joint's offset adds to its joint motion
            k = next(names.index(m.name) for m in e.motions if m.joint is not None)
            values[k] += e.mimic.offset
    for e in used:
        if e.mimic is not None:
            m = Motion(TRANSLATION, None, f"{e.joint}.multiplier")  # a ratio, not an angle
            _add_params(names, values, angle, owners, [m], {m.name: e.mimic.multiplier},
                        f"multiplier of {e.joint}")
    for t in tips:
        _add_params(names, values, angle, owners, t.motions, t.values, f"tool of {t.name}")
        frozen |= set(t.frozen)
    joints, joint_elements = _joints(paths, every)
    kinds = [PRISMATIC if e.type == PRISMATIC else "revolute" for e in joint_elements]
    limits = np.array([e.limits if e.limits is not None else (-np.pi, np.pi)
                       for e in joint_elements], dtype=float).reshape(-1, 2)
    index = {n: k for k, n in enumerate(names)}
    chains = {t.name: _chain(t.name, paths[t.link], t.motions, index, joints, len(names))
              for t in tips}
    if not joints:
        raise InputError("no moving joint between the root and the tips")
    return Layout(names, np.array(values), np.array(angle, dtype=bool), frozen, joints,
                  kinds, limits, chains, paths, owners, used)


def link_chain(layout: Layout, link: str, point: bool = False) -> PathChain:
    """The `PathChain` from the root to `link` (no tool), ending in a per-row point when
    `point`; `InputError` for a link the system does not reach."""
    if link not in layout.paths:
        shown = ", ".join(sorted(layout.paths))
        raise InputError(f"link {link!r} is not on a chain of this system (links reached: "
                         f"{shown})")
    index = {n: k for k, n in enumerate(layout.names)}
    return _chain(link, layout.paths[link], (), index, layout.joints, len(layout.names),
                  point)
