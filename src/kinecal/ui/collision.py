"""Self-collision of a robot's links, from the collision meshes of its URDF.

Two links collide when their meshes intersect (FCL through trimesh). Pairs that always
touch are not collisions: links joined by a joint, and pairs already in contact at the
zero configuration (meshes modelled overlapping at a joint, as URDFs commonly are; MoveIt's
set-up assistant disables the same pairs).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["SelfCollision"]


class SelfCollision:
    """Collision checks of one URDF (yourdfpy, loaded with its collision meshes).

    Raises
    ------
    ImportError
        Without python-fcl (the ``ui`` extra installs it).
    """

    def __init__(self, urdf) -> None:
        import trimesh.collision

        if trimesh.collision.fcl is None:
            raise ImportError("python-fcl is not installed")
        self.urdf = urdf
        scene = urdf.collision_scene
        if scene is None or not scene.graph.nodes_geometry:
            raise ValueError("the URDF has no collision meshes")
        self._manager = trimesh.collision.CollisionManager()
        parents = scene.graph.transforms.parents
        self._link = {}
        for node in scene.graph.nodes_geometry:
            T, geometry = scene.graph[node]
            self._manager.add_object(node, scene.geometry[geometry], T)
            self._link[node] = parents.get(node, node)
        joined = {frozenset((j.parent, j.child)) for j in urdf.joint_map.values()}
        self._allowed = joined | set(self._pairs(np.zeros(len(urdf.actuated_joint_names))))

    def _pairs(self, cfg: NDArray[np.float64]) -> list[frozenset]:
        self.urdf.update_cfg(cfg)
        graph = self.urdf.collision_scene.graph
        for node in self._link:
            self._manager.set_transform(node, graph[node][0])
        _, names = self._manager.in_collision_internal(return_names=True)
        pairs = {frozenset((self._link[a], self._link[b])) for a, b in names}
        return [p for p in pairs if len(p) == 2]

    def collisions(self, cfg: NDArray[np.float64]) -> list[tuple[str, str]]:
        """Pairs of links in collision at the URDF configuration `cfg` (its actuated
        joints, rad / m), apart from the allowed ones (module docstring)."""
        return sorted(tuple(sorted(p)) for p in self._pairs(np.asarray(cfg, dtype=float))
                      if p not in self._allowed)
