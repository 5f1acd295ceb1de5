"""The ROS messages kinecal reads, as numbers (lengths in metres, as ROS gives them).

Messages come deserialized by ``rosbags`` (ROS 1 and ROS 2 alike: ``header.stamp`` has
``sec`` and ``nanosec``; ROS 1 ``CameraInfo`` names its matrices ``K, D`` where ROS 2 has
``k, d``).
"""

from __future__ import annotations

import struct

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.ros.png import encode_png

__all__ = ["ACCEPTED", "CAPTURE_CONFIG", "EXTRA_TYPES", "camera_info", "camera_problem",
           "image_file", "joint_state", "point", "pose", "stamp_ns", "tf_transforms",
           "value_problem"]

Array = NDArray[np.float64]
#: coordinates beyond this (m) are no measurement of a robot cell
MAX_METRES = 1e4

#: the definitions of message types that no ROS distribution's type store has, registered
#: when a bag is opened: robot_calibration's capture pose (robot_calibration_msgs, its
#: ``msg/CaptureConfig.msg``: the joints to move to and the feature detectors to run)
CAPTURE_CONFIG = "robot_calibration_msgs/msg/CaptureConfig"
EXTRA_TYPES = {CAPTURE_CONFIG: "sensor_msgs/JointState joint_states\nstring[] features\n"}

#: the message types each option takes
ACCEPTED = {
    "--joints": ("sensor_msgs/msg/JointState", CAPTURE_CONFIG),
    "--points": ("geometry_msgs/msg/PointStamped",),
    "--poses": ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TransformStamped"),
    "--tf": ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage"),
    "--images": ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"),
    "--camera-info": ("sensor_msgs/msg/CameraInfo",),
}

#: Image encodings written as PNG: channels, dtype, channel order to write
_ENCODINGS = {
    "mono8": (1, np.uint8, None), "8uc1": (1, np.uint8, None),
    "mono16": (1, np.uint16, None), "16uc1": (1, np.uint16, None),
    "rgb8": (3, np.uint8, None), "bgr8": (3, np.uint8, [2, 1, 0]),
    "8uc3": (3, np.uint8, [2, 1, 0]),
    "rgba8": (4, np.uint8, None), "bgra8": (4, np.uint8, [2, 1, 0, 3]),
    "rgb16": (3, np.uint16, None), "bgr16": (3, np.uint16, [2, 1, 0]),
}


def stamp_ns(msg) -> int:
    """``header.stamp`` in nanoseconds (0 when the publisher left it unset); a
    CaptureConfig's is its JointState's."""
    header = getattr(msg, "header", None)
    s = (header if header is not None else msg.joint_states.header).stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def joint_state(msg) -> tuple[tuple[str, ...], Array]:
    """Joint names and positions (rad; metres for prismatic joints) of a JointState, or of
    the JointState a CaptureConfig carries."""
    msg = getattr(msg, "joint_states", msg)
    return tuple(msg.name), np.asarray(msg.position, dtype=float)


def point(msg) -> Array:
    """``(3,)`` of a PointStamped (m)."""
    p = msg.point
    return np.array([p.x, p.y, p.z], dtype=float)


def _pq(t, r) -> Array:
    return np.array([t.x, t.y, t.z, r.w, r.x, r.y, r.z], dtype=float)


def pose(msg) -> Array:
    """``(7,)`` x, y, z (m), qw, qx, qy, qz of a PoseStamped or TransformStamped."""
    if hasattr(msg, "pose"):
        return _pq(msg.pose.position, msg.pose.orientation)
    return _pq(msg.transform.translation, msg.transform.rotation)


def value_problem(v: Array) -> str | None:
    """Why a point ``(3,)`` or pose ``(7,)`` (x, y, z in m, then qw, qx, qy, qz) is no
    measurement, or None: a value not finite, a coordinate beyond `MAX_METRES`, a
    quaternion whose norm is not about 1 (zero: left unset)."""
    if not np.isfinite(v).all():
        return "values not finite (NaN or inf)"
    if np.abs(v[:3]).max() > MAX_METRES:
        return f"a coordinate of {np.abs(v[:3]).max():.3g} m (beyond {MAX_METRES:g} m)"
    if v.size == 7 and abs(float(np.linalg.norm(v[3:])) - 1.0) > 0.1:
        return f"a quaternion of norm {np.linalg.norm(v[3:]):.3g} (expected 1)"
    return None


def _frame(name: str) -> str:
    return name.strip().lstrip("/")


def tf_transforms(msg) -> list[tuple[str, str, int, Array]]:
    """``(parent, child, stamp_ns, pq)`` of each transform of a TFMessage (leading ``/``
    of ROS 1 frame names removed)."""
    return [(_frame(t.header.frame_id), _frame(t.child_frame_id), stamp_ns(t),
             _pq(t.transform.translation, t.transform.rotation)) for t in msg.transforms]


def _field(msg, *names):
    for n in names:
        if hasattr(msg, n):
            return getattr(msg, n)
    raise AttributeError(names[0])


def camera_info(msg) -> dict:
    """The camera of a CameraInfo: ``width, height, K (3, 3), D, distortion_model``."""
    K = np.asarray(_field(msg, "k", "K"), dtype=float).reshape(3, 3)
    D = np.asarray(_field(msg, "d", "D"), dtype=float)
    return {"width": int(msg.width), "height": int(msg.height), "K": K, "D": D,
            "distortion_model": str(msg.distortion_model or "plumb_bob")}


def camera_problem(camera: dict) -> str | None:
    """Why a `camera_info` is no calibrated camera, or None: no image size, a camera matrix
    K that is not ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with finite ``fx, fy > 0`` (ROS
    leaves K zero for an uncalibrated camera), distortion not finite."""
    K, D = camera["K"], camera["D"]
    if camera["width"] <= 0 or camera["height"] <= 0:
        return f"image size {camera['width']} x {camera['height']}"
    if not np.isfinite(K).all() or not (K[0, 0] > 0 and K[1, 1] > 0) or \
            not np.allclose(K[2], (0.0, 0.0, 1.0)) or K[1, 0] != 0:
        return (f"camera matrix K {np.array2string(K.ravel(), precision=4)} is not a "
                "calibrated camera's (fx, fy > 0, last row 0 0 1; all zero: uncalibrated)")
    if not np.isfinite(D).all():
        return "distortion coefficients not finite"
    return None


def _raw_image(msg, topic: str) -> NDArray:
    enc = str(msg.encoding).lower()
    if enc not in _ENCODINGS:
        raise InputError(f"{topic}: image encoding {msg.encoding!r} is not supported; expected "
                         f"one of {', '.join(_ENCODINGS)} (or a CompressedImage)",
                         option="--images")
    c, dtype, order = _ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    item = np.dtype(dtype).itemsize
    if h <= 0 or w <= 0:
        raise InputError(f"{topic}: image of {w} x {h} pixels: expected a width and height "
                         "of at least 1", option="--images")
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * c * item or data.size < h * step:
        raise InputError(f"{topic}: image data of {data.size} bytes does not hold {h} rows of "
                         f"step {step} ({w} x {c} x {item} bytes)", option="--images")
    rows = data[: h * step].reshape(h, step)[:, : w * c * item]
    big = bool(msg.is_bigendian)
    pixels = rows.copy().view((">" if big else "<") + ("u2" if item == 2 else "u1"))
    pixels = pixels.reshape(h, w, c).astype(dtype)
    return pixels[:, :, order] if order is not None else pixels


def _png_header_ok(data: bytes) -> bool:
    """The PNG signature, then an IHDR chunk giving a width and height of at least 1."""
    if len(data) < 33 or data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        return False
    w, h = struct.unpack(">II", data[16:24])
    return w > 0 and h > 0


def image_file(msg, msgtype: str, topic: str) -> tuple[bytes, str]:
    """The bytes of an image file and its suffix: an Image as PNG, a CompressedImage as
    it is (``.png`` or ``.jpg`` from its content)."""
    if msgtype.endswith("CompressedImage"):
        data = bytes(np.asarray(msg.data, dtype=np.uint8).tobytes())
        if data.startswith(b"\x89PNG"):
            if not _png_header_ok(data):
                raise InputError(f"{topic}: a CompressedImage of {len(data)} bytes starts "
                                 "like a PNG but has no image header (IHDR with a size)",
                                 option="--images")
            return data, ".png"
        if data.startswith(b"\xff\xd8\xff"):
            return data, ".jpg"
        raise InputError(f"{topic}: compressed image format {msg.format!r} is neither PNG nor "
                         "JPEG", option="--images")
    return encode_png(_raw_image(msg, topic)), ".png"
