"""How far a UR-type D-H table puts the flange from a UR type's nominal one, over the whole
joint range: the test a controller's ``calibration.conf`` (and the type of an export) is
judged by.

The deltas of a real factory calibration are not small one by one. Joints 2, 3 and 4 of a
UR turn about nearly parallel axes, so the standard D-H common normals between them lie
far out along the axes: ``delta_d`` of hundreds of metres on those joints, cancelling in
their sum, with ``delta_theta`` and ``delta_a`` of the same joints far from zero and
``delta_theta`` beyond a turn (Universal Robots' ur_calibration documents a UR10e whose
upper arm sits 439 m out). What such a file gives is an arm whose flange lies within a
few millimetres of the nominal arm's at every joint reading: that, not the size of one
delta, says whether the file is a calibration of this type.

`flange_deviation` is the largest distance between the flange origins of two D-H tables
at the same joint readings, over a grid of joints 2-5 across a full turn each (joint 1
turns both flanges alike about the same base axis and joint 6 turns the flange about its
own origin, ``a6`` being zero on a UR: neither changes the distance). `FACTORY_FRACTION` of
the arm's reach bounds what a factory calibration moves; beyond the reach the file describes
no arm of the type.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.io.ur.robots import UR_TYPES, nominal_dh

__all__ = ["FACTORY_FRACTION", "GRID", "closest_types", "fitting_types", "flange_deviation",
           "reach", "robot_type", "within_factory"]

Array = NDArray[np.float64]

#: joint readings per joint (2-5) of the grid the flanges are compared on
GRID = 8
#: a factory calibration moves the flange by at most this fraction of the arm's reach
#: (real UR10 / UR10e files: 0.26-0.3 %)
FACTORY_FRACTION = 0.01


@functools.lru_cache(maxsize=1)
def _grid() -> Array:
    """``(GRID**4, 6)`` joint readings (rad): joints 2-5 on a full-turn grid, 1 and 6 zero."""
    turn = np.linspace(-np.pi, np.pi, GRID, endpoint=False) + np.pi / GRID
    mesh = np.meshgrid(turn, turn, turn, turn, indexing="ij")
    q = np.zeros((GRID**4, 6))
    q[:, 1:5] = np.stack([m.ravel() for m in mesh], axis=1)
    return q


def _flanges(table: Array) -> Array:
    """Flange origins ``(N, 3)`` (m) of a D-H table ``(6, 4)`` (theta, a, d, alpha) on the
    grid."""
    q = _grid()
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    for (theta, a, d, alpha), qi in zip(table, q.T, strict=True):
        c, s = np.cos(theta + qi), np.sin(theta + qi)
        ca, sa = np.cos(alpha), np.sin(alpha)
        A = np.zeros((len(q), 4, 4))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = c, -s * ca, s * sa, a * c
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = s, c * ca, -c * sa, a * s
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, d
        A[:, 3, 3] = 1.0
        T = T @ A
    return T[:, :3, 3]


def reach(robot: str) -> float:
    """The reach of a UR type (m): ``|a2| + |a3| + d5 + d6``, the flange's largest
    distance from the shoulder axis."""
    _d1, a2, a3, _d4, d5, d6 = UR_TYPES[robot]
    return abs(a2) + abs(a3) + d5 + d6


def flange_deviation(table: ArrayLike, robot: str) -> float:
    """The largest distance (m) between the flange origins of a D-H table ``(6, 4)``
    (theta, a, d, alpha; rad, m) and of the nominal `robot` at the same joint readings
    (module docstring); ``inf`` when the table gives no finite flange."""
    got = _flanges(np.asarray(table, dtype=float))
    ref = _flanges(nominal_dh(robot))
    with np.errstate(invalid="ignore", over="ignore"):
        dist = np.linalg.norm(got - ref, axis=1)
    return float(dist.max()) if np.isfinite(dist).all() else float("inf")


def closest_types(table: ArrayLike) -> list[tuple[str, float]]:
    """Every UR type with its `flange_deviation` from `table` (m), closest first."""
    t = np.asarray(table, dtype=float)
    return sorted(((name, flange_deviation(t, name)) for name in UR_TYPES),
                  key=lambda item: item[1])


def fitting_types(deltas: ArrayLike) -> list[tuple[str, float]]:
    """Every UR type with the `flange_deviation` its nominal table plus `deltas` ``(6, 4)``
    gives from itself (m), best first: the types a ``calibration.conf`` may be of."""
    d = np.asarray(deltas, dtype=float)
    return sorted(((name, flange_deviation(nominal_dh(name) + d, name)) for name in UR_TYPES),
                  key=lambda item: item[1])


def robot_type(table: ArrayLike) -> str | None:
    """The UR type a D-H table ``(6, 4)`` (theta, a, d, alpha; rad, m) is a calibration
    of: the one whose nominal flange it stays closest to, when that is within what a factory
    calibration moves (`within_factory`); None for a table that is no UR's."""
    name, dev = closest_types(table)[0]
    return name if within_factory(name, dev) else None


def within_factory(robot: str, deviation: float) -> bool:
    """True when `deviation` (m) is one a factory calibration of `robot` gives."""
    return deviation <= FACTORY_FRACTION * reach(robot)
