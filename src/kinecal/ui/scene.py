"""Robots in viser's scene: a skeleton of link and joint cylinders (any model: D-H links,
a URDF chain, every chain of a robot system) and, where a URDF gives them, its meshes.

A `RobotFigure` keeps its skeleton at all the poses it may show (`kinecal.ui.geometry`),
so moving to another pose sends three arrays (positions, orientations, scales of the
cylinders) and nothing is computed.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.ui.geometry import (
    Skeleton,
    cylinder_instances,
    scene_scale,
    serial_skeleton,
    system_skeleton,
    unit_cylinder,
)

__all__ = ["RobotFigure", "skeleton_of", "urdf_of"]

Array = NDArray[np.float64]


def skeleton_of(model, q: Array, params: Array | None = None) -> Skeleton:
    """The skeleton of a serial model or a robot system at joint values `q` (rad)."""
    from kinecal.kinematics.tree.system import is_system

    if is_system(model):
        return system_skeleton(model, q, params)
    return serial_skeleton(model, q, params)


def urdf_of(spec: str | None):
    """The URDF (yourdfpy, with its meshes) of a model argument that is a URDF file, else
    None. Mesh files named ``package://...`` are looked for beside the URDF and above."""
    if spec is None or Path(spec).suffix.lower() != ".urdf" or not Path(spec).is_file():
        return None
    import yourdfpy

    handler = functools.partial(yourdfpy.filename_handler_magic,
                                dir=os.path.dirname(os.path.abspath(spec)))
    try:
        return yourdfpy.URDF.load(spec, build_scene_graph=True, load_meshes=True,
                                  build_collision_scene_graph=True,
                                  load_collision_meshes=True, filename_handler=handler)
    except Exception:
        return None


class RobotFigure:
    """One robot drawn in the scene under `name` (module docstring).

    Parameters
    ----------
    server : viser.ViserServer
    name : str
        Scene node path (``/robot``).
    color : tuple of 3 int
        Colour of the links (joints are drawn darker).
    opacity : float
        1 solid; less for a ghost (the Plan view's pose being edited).
    """

    def __init__(self, server, name: str, color=(120, 140, 160), opacity: float = 1.0):
        self.server, self.name, self.color, self.opacity = server, name, color, opacity
        self.skeleton: Skeleton | None = None
        self.urdf = None
        self._urdf_view = None
        self._joint_map: NDArray[np.intp] | None = None
        self._q: Array | None = None
        self._links = self._joints = None
        self.radius = 0.01

    def set_poses(self, model, q: Array, params: Array | None = None, urdf=None) -> None:
        """Prepare the figure to show `model` at the joint values `q` ``(N, n)`` (rad)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        self.skeleton = skeleton_of(model, q, params)
        self.radius = 0.025 * self.skeleton.size
        self._q = q
        self._set_urdf(model, urdf)

    def _set_urdf(self, model, urdf) -> None:
        if urdf is self.urdf:
            return
        if self._urdf_view is not None:
            self._urdf_view.remove()
            self._urdf_view = None
        self.urdf = urdf
        if urdf is None:
            return
        from viser.extras import ViserUrdf

        self._urdf_view = ViserUrdf(self.server, urdf, root_node_name=f"{self.name}/urdf",
                                    mesh_color_override=None if self.opacity >= 1 else
                                    (*[c / 255 for c in self.color], self.opacity))
        names = list(urdf.actuated_joint_names)
        chain = [j.get("name") for j in getattr(model, "joints", ()) if "frame" not in j]
        joint_names = getattr(model, "joint_names", None) or chain
        self._joint_map = np.array([names.index(n) if n in names else -1
                                    for n in joint_names], dtype=np.intp)

    def show(self, index: int) -> None:
        """Draw pose `index` of those given to `set_poses`."""
        s = self.skeleton
        if s is None:
            return
        pts = s.points[index]
        seg = s.segments
        pos, wxyz, scale = cylinder_instances(pts[seg[:, 0]], pts[seg[:, 1]], self.radius)
        jpos = s.joint_origins[index] - s.joint_axes[index] * (1.6 * self.radius)
        jp, jw, js = cylinder_instances(jpos, jpos + s.joint_axes[index] * 3.2 * self.radius,
                                        1.5 * self.radius)
        self._links = self._batch(f"{self.name}/links", self._links, pos, wxyz, scale,
                                  self.color)
        dark = tuple(int(c * 0.55) for c in self.color)
        self._joints = self._batch(f"{self.name}/joints", self._joints, jp, jw, js, dark)
        if self._urdf_view is not None and self._q is not None:
            cfg = np.zeros(len(self.urdf.actuated_joint_names))
            ok = self._joint_map >= 0
            cfg[self._joint_map[ok]] = self._q[index][ok]
            self._urdf_view.update_cfg(cfg)

    def _batch(self, path, handle, pos, wxyz, scale, color):
        if handle is not None and len(handle.batched_positions) == len(pos):
            handle.batched_positions = pos.astype(np.float32)
            handle.batched_wxyzs = wxyz.astype(np.float32)
            handle.batched_scales = scale.astype(np.float32)
            return handle
        if handle is not None:
            handle.remove()
        vertices, faces = unit_cylinder()
        return self.server.scene.add_batched_meshes_simple(
            path, vertices, faces, batched_wxyzs=wxyz.astype(np.float32),
            batched_positions=pos.astype(np.float32), batched_scales=scale.astype(np.float32),
            batched_colors=np.array(color, dtype=np.uint8),
            opacity=None if self.opacity >= 1 else self.opacity, lod="off",
            cast_shadow=False, receive_shadow=False)

    def set_visible(self, visible: bool) -> None:
        for h in (self._links, self._joints):
            if h is not None:
                h.visible = visible
        if self._urdf_view is not None:
            self._urdf_view.show_visual = visible

    def remove(self) -> None:
        for h in (self._links, self._joints):
            if h is not None:
                h.remove()
        self._links = self._joints = None
        if self._urdf_view is not None:
            self._urdf_view.remove()
            self._urdf_view = None
        self.urdf = None
        self.skeleton = None


def model_scale(model) -> float:
    """Scene units per model length unit."""
    return scene_scale(getattr(model, "length_unit", "mm"))
