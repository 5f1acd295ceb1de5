"""Files of a rendered rig (`kinecal.vision.rig_scene.RigScene`): what ``kinecal calibrate
MODEL STATIONS.csv --images DIR --camera ... --board ...`` reads, and the truth.

- ``DIR/*.png``: the images, ``CAMERA_NNN.png``;
- ``STATIONS.csv``: ``image,camera[,board],<joints>`` (`kinecal.io.rig_stations`; the board
  column when the rig has several boards: the board an image shows, blank when it shows
  several);
- the truth JSON: the model's true errors (`kinecal.calibration.serial.simulate.read_truth`'s
  format), and per camera and board its link, true pose in the link, the camera's
  intrinsics and image size, the board's spec;
- per camera, its intrinsics file ``NAME.yaml`` (ROS camera_calibration format).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.errors import InputError
from kinecal.io.rig_stations import write_rig_stations
from kinecal.vision.rig_scene import RigScene

__all__ = ["read_rig_truth", "rig_truth", "write_rig_cameras", "write_rig_images",
           "write_rig_stations_of", "write_rig_truth"]


def write_rig_images(scene: RigScene, folder: str | Path) -> None:
    """The images as PNG files named `RigScene.names` in `folder` (created), as
    `kinecal.vision.stations.write_images` writes a one-camera scene's."""
    from kinecal.vision.stations import write_images

    write_images(scene, folder)


def write_rig_stations_of(scene: RigScene, path: str | Path) -> None:
    """The scene's STATIONS.csv (module docstring)."""
    boards = None
    if len(scene.boards) > 1:
        boards = [scene.boards[s[0]][0].name if len(s) == 1 else None for s in scene.seen]
    write_rig_stations(path, scene.model, scene.names,
                       [scene.cameras[c].name for c in scene.camera], scene.q, boards)


def rig_truth(scene: RigScene) -> dict[str, Any]:
    """The truth of `scene` as JSON-able data (module docstring)."""
    m = scene.model
    conv = np.where(m.is_angle(), 180.0 / np.pi if m.angle_unit == "deg" else 1.0, 1.0)
    names = list(m.parameter_names)
    return {
        "model": m.name, "length_unit": m.length_unit, "angle_unit": m.angle_unit,
        "errors": dict(zip(names, ((scene.true_params - m.nominal) * conv).tolist(),
                           strict=True)),
        "parameters": dict(zip(names, (scene.true_params * conv).tolist(), strict=True)),
        "q_home": (np.asarray(scene.q_home) / m.joint_scale()).tolist(),
        "cameras": {c.name: {"link": c.link, "pose": X.tolist(), "K": K.tolist(),
                             "dist": d.tolist(), "size": list(s)}
                    for c, X, K, d, s in zip(scene.cameras, scene.X, scene.K, scene.dist,
                                             scene.size, strict=True)},
        "boards": {mb.name: {"link": mb.link, "pose": Y.tolist(), "spec": b.spec}
                   for (mb, b), Y in zip(scene.boards, scene.Y, strict=True)},
    }


def write_rig_truth(scene: RigScene, path: str | Path) -> None:
    """Write `rig_truth` (atomic)."""
    from kinecal._files import write_text_atomic

    write_text_atomic(path, json.dumps(rig_truth(scene), indent=1) + "\n")


def write_rig_cameras(scene: RigScene, folder: str | Path) -> list[Path]:
    """Each camera's intrinsics as ``folder/NAME.yaml``; returns the paths."""
    from kinecal.vision.intrinsics import CameraIntrinsics, write_intrinsics

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for c, K, d, s in zip(scene.cameras, scene.K, scene.dist, scene.size, strict=True):
        p = folder / f"{c.name}.yaml"
        write_intrinsics(p, CameraIntrinsics(K, d, s, source="render"))
        out.append(p)
    return out


def read_rig_truth(path: str | Path) -> dict[str, Any]:
    """A truth file of `write_rig_truth` (poses as arrays)."""
    from kinecal._files import read_json

    doc = read_json(Path(path))
    if not isinstance(doc, dict) or "cameras" not in doc or "boards" not in doc:
        raise InputError("expected a rig truth file (cameras, boards, errors)", file=path)
    for part in ("cameras", "boards"):
        for v in doc[part].values():
            v["pose"] = np.asarray(v["pose"], float)
    return doc
