"""The image of each dwell and the camera, written as a folder of files.

Per dwell one image is kept: the first whose stamp is at or after the dwell's middle, else
the last one before it (the robot is still throughout a dwell; the middle is furthest from
its ends). Images stream by in the bag's order and at most one not-yet-chosen raw message
per dwell is held, so memory stays bounded by an image or two. An ``Image`` is written as
PNG, a ``CompressedImage`` unchanged (``.png`` or ``.jpg``); the first ``CameraInfo``
becomes ``camera.yaml`` in the ROS ``camera_calibration`` format that ``kinecal
handeye-images --intrinsics`` reads.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinecal._files import write_bytes_atomic, write_text_atomic
from kinecal.errors import InputError
from kinecal.io.ros import messages as msgs

__all__ = ["ImageWriter", "camera_yaml"]


def camera_yaml(camera: dict, name: str = "camera") -> str:
    """ROS ``camera_calibration`` YAML of a camera (`kinecal.io.ros.messages.camera_info`)."""
    def block(rows: int, cols: int, data) -> str:
        values = ", ".join(repr(float(v)) for v in np.ravel(data))
        return f"\n  rows: {rows}\n  cols: {cols}\n  data: [{values}]"

    D = np.ravel(camera["D"])
    return (f"image_width: {camera['width']}\nimage_height: {camera['height']}\n"
            f"camera_name: {name}\ncamera_matrix:{block(3, 3, camera['K'])}\n"
            f"distortion_model: {camera['distortion_model']}\n"
            f"distortion_coefficients:{block(1, len(D), D)}\n")


class ImageWriter:
    """Chooses and writes the image of each dwell into `folder` (module docstring).

    Parameters
    ----------
    folder : Path
        Existing folder the files go to.
    image_topic, info_topic : str
    """

    def __init__(self, folder: Path, image_topic: str, info_topic: str) -> None:
        self.folder = Path(folder)
        self.image_topic, self.info_topic = image_topic, info_topic
        self.camera: dict | None = None
        self._bad_info: str | None = None  # why the last CameraInfo was refused
        self._files: dict[int, str] = {}
        self._pending: dict[int, tuple[str, bytes]] = {}
        self._bag = None
        self._mid = np.zeros(0)
        self._t0 = 0

    def begin(self, bag, starts, ends, t0: int) -> None:
        """Called before the images stream by: the bag and the dwells (s from `t0` ns)."""
        self._bag, self._t0 = bag, t0
        self._mid = 0.5 * (np.asarray(starts) + np.asarray(ends))
        self._width = max(3, len(str(len(self._mid))))

    def name(self, k: int) -> str:
        """The file name of dwell `k`'s image."""
        return self._files[k]

    def _write(self, k: int, kind: str, msg) -> None:
        data, suffix = msgs.image_file(msg, kind, self.image_topic)
        name = f"dwell_{k + 1:0{self._width}d}{suffix}"
        write_bytes_atomic(self.folder / name, data)
        self._files[k] = name

    def __call__(self, topic: str, kind: str, bag_ns: int, raw, dwell_of) -> None:
        msg = self._bag.decode(raw, kind)
        if topic == self.info_topic:
            if self.camera is None:
                camera = msgs.camera_info(msg)
                self._bad_info = msgs.camera_problem(camera)
                self.camera = camera if self._bad_info is None else None
            return
        stamp = msgs.stamp_ns(msg)
        t = ((stamp if stamp > 0 else bag_ns) - self._t0) * 1e-9
        k = dwell_of(t)
        if k is None or k in self._files:
            return
        if t >= self._mid[k]:
            self._pending.pop(k, None)
            self._write(k, kind, msg)
        else:
            self._pending[k] = (kind, bytes(raw))

    def finish(self) -> None:
        """Write the held images of dwells that had none after their middle; write
        ``camera.yaml``. `InputError` when no CameraInfo came."""
        for k, (kind, raw) in sorted(self._pending.items()):
            self._write(k, kind, self._bag.decode(raw, kind))
        self._pending.clear()
        if self.camera is None and self._bad_info is not None:
            raise InputError(f"topic {self.info_topic}: no CameraInfo of a calibrated camera "
                             f"(the last: {self._bad_info})", option="--camera-info")
        if self.camera is None:
            raise InputError(f"topic {self.info_topic} has no message", option="--camera-info")
        write_text_atomic(self.folder / "camera.yaml", camera_yaml(self.camera))

    def problem(self, k: int) -> str | None:
        """Why dwell `k` has no image (None when it has one)."""
        return None if k in self._files else f"no {self.image_topic} image during the dwell"
