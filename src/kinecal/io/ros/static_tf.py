"""A hand-eye result as a ROS static transform: frames, arguments, a ROS 2 launch file.

kinecal's hand-eye result ``X`` is ``cam2flange`` (eye-in-hand) or ``cam2base``
(eye-to-hand): the pose of the camera in the flange (or robot base) frame, which maps
camera coordinates to flange (or base) coordinates. In ROS tf terms that is the transform
with the flange (or base) as *parent* (``frame_id``) and the camera as *child*
(``child_frame_id``): ``tf2_ros static_transform_publisher`` takes exactly those numbers.
The camera frame of a hand-eye calibration is the camera's optical frame (OpenCV: z along
the view, x right, y down), ROS's ``*_optical_frame``.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json
from kinecal.errors import InputError
from kinecal.spatial import check_transform, quaternion_from_matrix

__all__ = ["StaticTransform", "check_frame", "metres_in_cell", "metres_per_unit",
           "read_handeye_result", "static_transform"]

Array = NDArray[np.float64]
_PER_M = {"m": 1.0, "mm": 1000.0}
#: default frame names: parent per set-up, child
DEFAULT_PARENT = {"eye-in-hand": "tool0", "eye-to-hand": "base_link"}
DEFAULT_CHILD = "camera_optical_frame"
_SETUPS = tuple(DEFAULT_PARENT)
#: a camera farther than this (m) from its parent frame: refused; warned beyond FAR_METRES
MAX_METRES = 1e4
FAR_METRES = 10.0


@dataclass(frozen=True)
class StaticTransform:
    """The pose of `child` in `parent` (metres; quaternion x, y, z, w as ROS orders it)."""

    parent: str
    child: str
    xyz: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]
    what: str = "X"

    def arguments(self) -> list[str]:
        """``static_transform_publisher`` arguments (the ``--x ... --child-frame-id`` form)."""
        x, y, z = self.xyz
        qx, qy, qz, qw = self.quaternion_xyzw
        nums = (("--x", x), ("--y", y), ("--z", z), ("--qx", qx), ("--qy", qy),
                ("--qz", qz), ("--qw", qw))
        out = [s for k, v in nums for s in (k, repr(float(v)))]
        return out + ["--frame-id", self.parent, "--child-frame-id", self.child]

    def command(self) -> str:
        """The ``ros2 run tf2_ros static_transform_publisher ...`` line."""
        return " ".join(["ros2", "run", "tf2_ros", "static_transform_publisher",
                         *(shlex.quote(a) for a in self.arguments())])

    def words(self) -> str:
        """The direction of the transform, stated both ways."""
        return (f"parent frame (frame_id) {self.parent}, child frame (child_frame_id) "
                f"{self.child}: the transform is the pose of {self.child} in {self.parent}; "
                f"it maps {self.child} coordinates to {self.parent} coordinates "
                f"(kinecal's {self.what}). Read the other way, {self.parent} seen from "
                f"{self.child} is its inverse, which is not what is published.")

    def launch_file(self, node_name: str = "kinecal_handeye", comment: str = "") -> str:
        """A ROS 2 Python launch file starting the publisher."""
        args = ",\n".join(f"                {a!r}" for a in self.arguments())
        head = "".join(f"# {line}\n" for line in comment.splitlines() if line.strip())
        return (f"{head}# {self.words()}\n"
                "from launch import LaunchDescription\n"
                "from launch_ros.actions import Node\n\n\n"
                "def generate_launch_description():\n"
                "    return LaunchDescription([\n"
                "        Node(\n"
                "            package='tf2_ros',\n"
                "            executable='static_transform_publisher',\n"
                f"            name={node_name!r},\n"
                "            arguments=[\n"
                f"{args},\n"
                "            ],\n"
                "        ),\n"
                "    ])\n")


def read_handeye_result(path: str | Path) -> tuple[Array, str, str]:
    """``X`` ``(4, 4)``, the set-up and the length unit of a hand-eye result JSON (``kinecal
    handeye --out`` or ``kinecal handeye-images --out``).

    Raises
    ------
    InputError
        Not such a result (no 4x4 ``X`` that is a rigid transform, no known ``setup``).
    """
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict) or "X" not in data:
        raise InputError("not a hand-eye result: expected a JSON object with X (kinecal "
                         "handeye --out or handeye-images --out)", file=path)
    try:
        X = np.array(data["X"], dtype=float)
    except (TypeError, ValueError):
        X = np.zeros(0)
    if X.shape != (4, 4) or not np.isfinite(X).all():
        raise InputError("X: expected a 4x4 matrix of finite numbers", file=path)
    try:
        check_transform(X, name="X")
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    setup = data.get("setup")
    if setup not in _SETUPS:
        raise InputError(f"setup: expected {' or '.join(_SETUPS)}, got {setup!r}", file=path)
    return X, str(setup), str(data.get("length_unit") or "")


def metres_per_unit(length_unit: str, unit: str | None, path: str | Path) -> float:
    """The factor from the result's lengths to metres: `unit` (``--unit``) when given, else
    the result's own `length_unit` when it is mm or m."""
    chosen = unit if unit is not None else length_unit.strip()
    if chosen not in _PER_M:
        if unit is not None:
            raise InputError(f"unknown unit {unit!r}; expected mm or m", option="--unit")
        raise InputError(f"the result's lengths are in {length_unit or 'an unnamed unit'!r}: "
                         "give --unit mm or --unit m (the unit of the robot poses and board "
                         "it was computed from)", file=path)
    return 1.0 / _PER_M[chosen]


def metres_in_cell(X: Array, scale: float, path: str | Path) -> Array:
    """``X`` ``(4, 4)`` with its translation times `scale` (metres): `InputError` beyond
    `MAX_METRES` (no robot cell: another unit), a warning (``camera-mount-far``) beyond
    `FAR_METRES` (a result in mm exported as metres puts the camera 1000 times too far)."""
    X_m = np.array(X, dtype=float)
    X_m[:3, 3] *= scale
    far = float(np.linalg.norm(X_m[:3, 3]))
    if not far <= MAX_METRES:
        raise InputError(f"X: the camera is {far:.3g} m from its parent frame: no robot "
                         "cell is that large (the lengths in another unit? --unit)", file=path)
    if far > FAR_METRES:
        from kinecal.diagnostics import warn

        warn("camera-mount-far", f"{path}: X puts the camera {far:.4g} m from its parent "
             f"frame (more than {FAR_METRES:g} m): are the result's lengths in mm? give "
             "--unit mm")
    return X_m


def check_frame(name: str, option: str) -> str:
    """`name` when it is a frame (link) name: not empty, no spaces; `InputError` otherwise."""
    if not name.strip() or any(c.isspace() for c in name):
        raise InputError(f"{name!r}: expected a frame name without spaces", option=option)
    return name


def static_transform(X: Array, setup: str, scale: float, parent: str | None = None,
                     child: str | None = None) -> StaticTransform:
    """The static transform of hand-eye result `X` ``(4, 4)`` (lengths times `scale` =
    metres) of `setup` (eye-in-hand or eye-to-hand)."""
    if setup not in _SETUPS:
        raise InputError(f"setup: expected {' or '.join(_SETUPS)}, got {setup!r}")
    X = np.asarray(X, dtype=float)
    if X.shape != (4, 4):
        raise InputError(f"X: expected a 4x4 transform, got shape {X.shape}")
    parent = DEFAULT_PARENT[setup] if parent is None else check_frame(parent, "--parent-frame")
    child = DEFAULT_CHILD if child is None else check_frame(child, "--child-frame")
    if parent == child:
        raise InputError(f"parent and child frame are both {parent!r}", option="--child-frame")
    w, x, y, z = quaternion_from_matrix(X[:3, :3])
    what = "cam2flange" if setup == "eye-in-hand" else "cam2base"
    return StaticTransform(parent, child, tuple(float(v) for v in X[:3, 3] * scale),
                           (float(x), float(y), float(z), float(w)), f"X, {what}")
