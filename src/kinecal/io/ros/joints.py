"""JointState names onto a model's joints.

By name when names are known: ``--joint-names`` (one per model joint, in the model's
order) or the model's own joint names (a URDF model's). Otherwise by the order of the
first message that has as many joints as the model, with one exception: the six joint
names of Universal Robots' drivers (``shoulder_pan_joint`` ... ``wrist_3_joint``, any
prefix), which ROS 2's joint_state_broadcaster publishes in another order, are put in
the arm's order. Later messages are mapped by the names of that first one.
"""

from __future__ import annotations

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
        if ur is not None:
            self.wanted, self.how = ur, "by UR joint names"
        elif len(names) == self.n:
            self.wanted, self.how = list(names), "by order"

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
            return InputError(f"{self.topic}: JointState joints ({seen}) are not the model's "
                              f"{self.n}: give --joint-names (the bag's name of each model "
                              "joint, in order)", option="--joints")
        return InputError(f"{self.topic}: joint names ({seen}) match no model joint; expected "
                          f"{', '.join(self.wanted)} (--joint-names)", option="--joints")
