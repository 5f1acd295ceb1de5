"""What a calibration placed besides the arm, read from its result JSON and drawn in the
See view: the pivots of ballbars, the fixed points (sockets) and planes touched
(``kinds[].unknowns``, docs/measurement-kinds.md), and the cameras and boards of a
calibration from images when they are fixed in the robot's base frame: ``X`` /
``board_pose`` of one camera (``cam2base``, ``target2base``, docs/arm-from-images.md), a
rig's ``cameras`` / ``boards`` mounted on ``world``.

A camera or board carried by a link (`Placed.attached`: ``flange``, the model's end frame
as the camera block places it, or a link of a URDF or robot system) moves with the arm: it
is drawn at the pose the See view shows (`InstrumentsFigure.move`), hidden where the model
has no such link.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["InstrumentsFigure", "Placed", "placed_of"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Placed:
    """One thing a calibration placed (model length unit, base frame).

    Attributes
    ----------
    name : str
        ``pivot P1``, ``point S2``, ``plane table``, ``camera``, ``board``.
    kind : str
        ``point``, ``plane`` or ``frame``.
    attached : str
        ``world`` (the base frame), ``flange`` or the link that carries it.
    pose : ndarray, shape (4, 4)
        Its frame: a point's at the point, a plane's on it (z its normal), a camera's or a
        board's as the result gives it.
    """

    name: str
    kind: str
    attached: str
    pose: Array


def _frame(origin, z=None) -> Array:
    T = np.eye(4)
    T[:3, 3] = np.asarray(origin, dtype=float)
    if z is not None:
        z = np.asarray(z, dtype=float) / np.linalg.norm(z)
        x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
        x /= np.linalg.norm(x)
        T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return T


def placed_of(data: dict) -> list[Placed]:
    """Everything `data` (a result JSON) places (module docstring)."""
    out: list[Placed] = []
    for entry in data.get("kinds") or []:
        for u in entry.get("unknowns") or []:
            for key in ("pivot", "point"):
                if key in u and "xyz" in u:
                    out.append(Placed(f"{key} {u[key]}", "point", "world", _frame(u["xyz"])))
            if "plane" in u and "normal" in u:
                n = np.asarray(u["normal"], dtype=float)
                # the plane n . p = offset: its point nearest the base origin
                out.append(Placed(f"plane {u['plane']}", "plane", "world",
                                  _frame(n * float(u["offset"]) / (n @ n), n)))
    for part, word in (("cameras", "camera"), ("boards", "board")):  # a rig's mounts
        for name, m in (data.get(part) or {}).items():
            link = m.get("link", "world")
            out.append(Placed(f"{word} {name}", "frame", "world" if link == "world" else link,
                              np.asarray(m["pose"], dtype=float)))
    for key, frame_key, name in (("X", "X_frame", "camera"),
                                 ("board_pose", "board_frame", "board")):
        if data.get(key) is not None:
            where = "world" if str(data.get(frame_key, "")).endswith("2base") else "flange"
            out.append(Placed(name, "frame", where, np.asarray(data[key], dtype=float)))
    return out


class InstrumentsFigure:
    """The placed things of one result in viser's scene under ``/placed``."""

    def __init__(self, server) -> None:
        self.server = server
        self.handles: dict[str, object] = {}
        self.carried: list[tuple[Placed, object]] = []  # moved with the arm (`move`)

    def show(self, placed: list[Placed], scale: float, size: float) -> None:
        """Draw `placed` (model units times `scale`: scene units); `size` is the arm's
        extent (scene units), which sizes the markers."""
        from kinecal.ui.geometry import quaternions_z_to

        self.clear()
        for k, p in enumerate(p for p in placed if p.attached != "world"):
            node = f"/carried/{k}"
            h = self.server.scene.add_frame(node, axes_length=0.08 * size,
                                            axes_radius=0.004 * size, visible=False)
            label = self.server.scene.add_label(f"{node}/label", f"{p.name} (on {p.attached})")
            self.handles[node] = (h, label)
            self.carried.append((p, h))
        for k, p in enumerate(p for p in placed if p.attached == "world"):
            at = tuple(float(v) for v in p.pose[:3, 3] * scale)
            node = f"/placed/{k}"
            if p.kind == "point":
                h = self.server.scene.add_icosphere(node, radius=0.015 * size,
                                                    color=(140, 60, 200), position=at)
            elif p.kind == "plane":
                wxyz = quaternions_z_to(p.pose[None, :3, 2])[0]
                h = self.server.scene.add_box(node, color=(120, 170, 220),
                                              dimensions=(0.4 * size, 0.4 * size,
                                                          0.002 * size),
                                              wxyz=tuple(wxyz), position=at, opacity=0.5)
            else:
                h = self.server.scene.add_frame(node, axes_length=0.08 * size,
                                                axes_radius=0.004 * size, position=at,
                                                wxyz=tuple(wxyz_of(p.pose[:3, :3])))
            label = self.server.scene.add_label(f"{node}/label", p.name)
            self.handles[node] = (h, label)

    def move(self, frame_of: Callable[[str], Array | None], scale: float) -> None:
        """Place the carried things at the arm's current pose: ``frame_of(link)`` is the
        link's frame ``(4, 4)`` in the base frame (model units), None where the model has no
        such link (the thing is then hidden); `scale`: scene units per model unit."""
        for p, h in self.carried:
            T = frame_of(p.attached)
            h.visible = T is not None
            if T is None:
                continue
            pose = np.asarray(T, dtype=float) @ p.pose
            h.position = tuple(float(v) for v in pose[:3, 3] * scale)
            h.wxyz = tuple(float(v) for v in wxyz_of(pose[:3, :3]))

    def clear(self) -> None:
        self.server.scene.remove_by_name("/placed")
        self.server.scene.remove_by_name("/carried")
        self.handles.clear()
        self.carried.clear()


def wxyz_of(R: Array) -> Array:
    """The unit quaternion ``(w, x, y, z)`` of a rotation matrix `R` ``(3, 3)``."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])
