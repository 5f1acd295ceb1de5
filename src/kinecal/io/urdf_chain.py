"""Which chain of a URDF tree to read: the joints from a base link to a tip link
(`chain_path`), and the default tip when none is given (the end of the one branch that
carries moving joints). Used by `kinecal.io.urdf` (one chain) and `kinecal.io.urdf_tree`
(several tips)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import check_chain_size

__all__ = ["chain_path"]


def _tree(joints, path: Path) -> tuple[dict, dict, str]:
    """Joint by child link, joints by parent link, and the single root link."""
    by_child: dict = {}
    by_parent: dict = {}
    for j in joints:
        if j.child in by_child:
            raise InputError(f"link {j.child!r} is the child of two joints "
                             f"({by_child[j.child].name}, {j.name}): not a tree", file=path)
        by_child[j.child] = j
        by_parent.setdefault(j.parent, []).append(j)
    links = set(by_child) | set(by_parent)
    roots = sorted(links - set(by_child))
    if len(roots) != 1:
        raise InputError(f"{len(roots)} root links ({', '.join(roots) or 'a cycle'}), "
                         "expected one", file=path)
    return by_child, by_parent, roots[0]


def _moving_below(link: str, by_parent: Mapping) -> bool:
    stack = [link]
    while stack:
        for j in by_parent.get(stack.pop(), []):
            if j.type != "fixed":
                return True
            stack.append(j.child)
    return False


#: words of the link names users give as a chain's tip (tool0, flange, tcp, ee_link,
#: end_effector_link, ...)
TIP_WORDS = ("tool", "flange", "tcp", "ee", "end_effector", "endeffector", "tip", "eef")


def _tip_like(link: str) -> bool:
    words = link.lower().replace("-", "_").split("_")
    low = link.lower()
    return any(w in words or (len(w) > 3 and w in low) for w in TIP_WORDS)


def _below(link: str, by_parent: Mapping) -> list[str]:
    out, stack = [], [link]
    while stack:
        cur = stack.pop()
        out.append(cur)
        stack += [j.child for j in by_parent.get(cur, [])]
    return out


def _tip_candidates(link: str, kids: list, by_parent: Mapping, ends_here: bool) -> list[str]:
    """The --tip-link candidates offered at a branching `link`: the links named like tips
    (``end_effector_link``, ``tool0``, ``flange``: the link itself when only fixed frames
    hang below it, as Kinova's sensor frames do), then every leaf below, fixed-only side
    branches too (the tool link of a kinecal export sits beside a gripper's fingers)."""
    below = [t for j in kids for t in _below(j.child, by_parent)]
    named = [t for t in ([link] if ends_here else []) + below if _tip_like(t)]
    leaves = [t for j in kids for t in _leaves(j.child, by_parent)]
    return list(dict.fromkeys(sorted(named) + sorted(set(leaves) - set(named))))


def _leaves(link: str, by_parent: Mapping) -> list[str]:
    out, stack = [], [link]
    while stack:
        cur = stack.pop()
        kids = by_parent.get(cur, [])
        if not kids:
            out.append(cur)
        stack += [j.child for j in kids]
    return sorted(out)


def chain_path(urdf, base_link: str | None = None, tip_link: str | None = None,
               path: str | Path = "") -> list:
    """The joints from `base_link` to `tip_link`, base first.

    Without `tip_link` the chain follows, at every link with several children, the one
    branch that carries moving joints; branches made of fixed joints only (sensor frames,
    ROS-Industrial's ``base``) are side frames and left out. Two moving branches, or
    several fixed-only branches and no moving one, are ambiguous: `InputError` listing the
    candidate tip links.
    """
    path = Path(path)
    by_child, by_parent, root = _tree(urdf.robot.joints, path)
    links = sorted(set(by_child) | set(by_parent) | {lk.name for lk in urdf.robot.links})
    for option, link in (("--base-link", base_link), ("--tip-link", tip_link)):
        if link is not None and link not in links:
            shown = ", ".join(links[:12]) + (" ..." if len(links) > 12 else "")
            raise InputError(f"no link {link!r} in {path.name}; links: {shown}",
                             option=option)
    base = root if base_link is None else base_link
    if tip_link is not None:
        chain, cur = [], tip_link
        while cur != base:
            if cur not in by_child:
                raise InputError(f"link {tip_link!r} is not below {base!r}: no chain "
                                 "between them", option="--tip-link")
            chain.append(by_child[cur])
            cur = by_child[cur].parent
        return _sized(chain[::-1], path)
    chain, cur = [], base
    while by_parent.get(cur):
        kids = by_parent[cur]
        moving = [j for j in kids if j.type != "fixed" or _moving_below(j.child, by_parent)]
        if len(moving) == 1:
            nxt = moving[0]
        elif not moving and len(kids) == 1:
            nxt = kids[0]
        else:
            branches = moving or kids
            tips = _tip_candidates(cur, kids, by_parent, ends_here=not moving)
            raise InputError(
                f"link {cur!r} branches ({', '.join(j.name for j in branches)}): choose the "
                f"chain's end with --tip-link (one of {', '.join(tips)})", file=path)
        chain.append(nxt)
        cur = nxt.child
    return _sized(chain, path)


def _sized(chain: list, path: Path) -> list:
    """`chain`, refused when longer than a model may be (`check_chain_size`)."""
    try:
        check_chain_size(len(chain), sum(j.type != "fixed" for j in chain),
                         f"{chain[0].parent} -> {chain[-1].child}: " if chain else "")
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    return chain
