"""JointState names onto a model's joints.

By name when names are known: ``--joint-names`` (one per model joint, in the model's
order) or the model's own joint names (a URDF model's). A model without joint names (a
D-H model file) takes the names of the first message when they say the order themselves:
the six joint names of Universal Robots' drivers (``shoulder_pan_joint`` ...
``wrist_3_joint``, any prefix), which ROS 2's joint_state_broadcaster publishes in another
order, in the arm's order; or as many names as the model has joints that differ only by
their numbers (``joint_1`` ... ``joint_6``, ``a1`` ... ``a6``), in the order of the numbers.
Any other names are refused: the order of a message says nothing of which joint is which
(a recording whose names came shuffled would be read scrambled), and ``--joint-names``
must say it. Later messages are mapped by the names of that first one.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError

__all__ = ["UR_JOINTS", "JointMapper"]

#: the joints of a UR arm, base to flange, as its ROS drivers name them
UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint")


def _ur_order(names: Sequence[str]) -> list[str] | None:
    found = []
    for j in UR_JOINTS:
        hits = [n for n in names if n == j or n.endswith("_" + j) or n.endswith("/" + j)]
        if len(hits) != 1:
            return None
        found.append(hits[0])
    return found


_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def _numbered(names: Sequence[str]) -> list[str] | None:
    """The names in the order of their numbers when they differ only by a number running
    over ``1..n`` or ``0..n-1`` (``joint_1`` ... ``joint_6``), else None."""
    found = [_NUMBERED.match(n) for n in names]
    if not all(found) or len({m.group(1) for m in found}) != 1:
        return None
    numbers = sorted((int(m.group(2)), m.group(0)) for m in found)
    first = numbers[0][0]
    if first not in (0, 1) or [k for k, _ in numbers] != list(range(first,
                                                                  first + len(names))):
        return None
    return [n for _, n in numbers]


def _repeated(names: Sequence[str]) -> list[str]:
    return sorted({n for n in names if list(names).count(n) > 1})


class JointMapper:
    """Positions of a JointState in the model's joint order (module docstring).

    Parameters
    ----------
    n_joints : int
    names : sequence of str, optional
        The bag's name of each model joint, in the model's order.
    topic : str
        For messages.
    """

    def __init__(self, n_joints: int, names: Sequence[str] | None, topic: str) -> None:
        self.n = n_joints
        if names and len(set(names)) < len(names):
            raise InputError(f"{', '.join(_repeated(names))} given twice: expected one bag "
                             "joint name per model joint", option="--joint-names")
        self.wanted = list(names) if names else None
        self.topic = topic
        self.how = "by name" if names else None
        self._cache: dict[tuple[str, ...], NDArray[np.intp] | None] = {}
        self.seen: tuple[str, ...] | None = None

    def _first(self, names: tuple[str, ...]) -> None:
        ur = _ur_order(names) if self.n == 6 else None
        numbered = _numbered(names) if len(names) == self.n else None
        if ur is not None:
            self.wanted, self.how = ur, "by UR joint names"
        elif numbered is not None:
            self.wanted, self.how = numbered, "by joint number"

    def index(self, names: tuple[str, ...]) -> NDArray[np.intp] | None:
        """Indices of the model's joints in a message's `names` (None: not all there)."""
        if names in self._cache:
            return self._cache[names]
        if len(set(names)) < len(names):  # which position is which joint is unknown
            raise InputError(f"{self.topic}: a JointState names {', '.join(_repeated(names))} "
                             "more than once: expected each joint once", option="--joints")
        self.seen = self.seen or names
        if self.wanted is None:
            self._first(names)
        idx = None
        if self.wanted is not None and set(self.wanted) <= set(names):
            pos = {n: k for k, n in enumerate(names)}
            idx = np.array([pos[n] for n in self.wanted], dtype=np.intp)
        self._cache[names] = idx
        return idx

    def fail(self) -> InputError:
        """The error when no message carried the model's joints."""
        seen = ", ".join(self.seen or ()) or "no names"
        if self.wanted is None:
            return InputError(f"{self.topic}: JointState joints ({seen}) do not say which of "
                              f"the model's {self.n} joints each is (the model names none, "
                              "and the order of a message is no answer): give --joint-names "
                              "(the bag's name of each model joint, in order)",
                              option="--joint-names")
        return InputError(f"{self.topic}: joint names ({seen}) match no model joint; expected "
                          f"{', '.join(self.wanted)} (--joint-names)", option="--joints")
