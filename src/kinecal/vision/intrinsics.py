"""Camera intrinsics: read from a file, estimate from board images, write.

Files read by `read_intrinsics` (``--intrinsics``):

- the ROS ``camera_calibration`` YAML (``image_width``, ``image_height``,
  ``camera_matrix: {rows, cols, data}``, ``distortion_model`` = ``plumb_bob`` or
  ``rational_polynomial``, ``distortion_coefficients: {rows, cols, data}``);
- OpenCV FileStorage (YAML ``%YAML:1.0`` or XML) as written by OpenCV's calibration sample:
  a 3x3 matrix named ``camera_matrix``, ``cameraMatrix`` or ``K`` and coefficients named
  ``distortion_coefficients``, ``dist_coeffs``, ``distCoeffs`` or ``D``, optionally
  ``image_width`` / ``image_height``;
- JSON with the same keys as the ROS YAML (matrices as ``{rows, cols, data}`` or nested
  lists).

`estimate_intrinsics` runs ``cv2.calibrateCamera`` on the detections (reprojection RMS in
pixels reported); `write_intrinsics` writes the ROS YAML.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json, read_text, write_text_atomic
from kinecal._yaml import load_yaml
from kinecal.calibration.handeye.camera import check_camera
from kinecal.errors import InputError
from kinecal.vision.image_files import MAX_IMAGE_PIXELS

Array = NDArray[np.float64]

__all__ = ["CameraIntrinsics", "check_focal", "estimate_intrinsics", "read_intrinsics",
           "write_intrinsics"]

#: the distortion models read (ROS camera_calibration's names; OpenCV's 5 and 8 coefficients)
_MODELS = ("plumb_bob", "rational_polynomial")
_K_NAMES = ("camera_matrix", "cameraMatrix", "K", "camera_matrix_K", "intrinsics")
_D_NAMES = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "distortion")


@dataclass
class CameraIntrinsics:
    """A calibrated camera.

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Camera matrix (pixels).
    dist : ndarray, shape (8,)
        ``(k1, k2, p1, p2, k3, k4, k5, k6)`` (zeros where the model has fewer).
    size : (int, int) or None
        Image width and height the calibration is for.
    rms_px : float or None
        Reprojection RMS of the calibration (pixels), when estimated here.
    source : str
        File name, ``"estimated from N images"`` or ``"render"``.
    per_view_rms : list of float
        Reprojection RMS per image of the estimation (pixels).
    rational : bool
        The 8-coefficient rational model is used (else 5 coefficients).
    """

    K: Array
    dist: Array
    size: tuple[int, int] | None = None
    rms_px: float | None = None
    source: str = ""
    per_view_rms: list[float] = field(default_factory=list)
    rational: bool = False

    def __post_init__(self) -> None:
        self.K, self.dist = check_camera(self.K, self.dist)
        if np.any(self.dist[5:] != 0):
            self.rational = True

    @property
    def cv_dist(self) -> Array:
        """Coefficients as OpenCV expects them (5 or 8)."""
        return self.dist if self.rational else self.dist[:5]

    @property
    def given(self) -> bool:
        """Read from a file or passed in (not estimated from the images here)."""
        return self.rms_px is None

    def describe(self, refined: bool) -> str:
        """Whether the intrinsics were given or estimated, and what X's sigma holds."""
        if self.given:
            how = "refined with X" if refined else "held as given"
            held = ("X's sigma includes their uncertainty" if refined else
                    "X's sigma leaves out their uncertainty")
            return f"intrinsics given ({self.source}), {how}: {held}"
        return (f"intrinsics estimated from the images ({self.source}; calibration RMS "
                f"{self.rms_px:.3f} px): X's sigma includes their uncertainty")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (``K``, ``dist``, ``size``, ``rms_px``, ``source``, ``given``)."""
        return {"K": self.K.tolist(), "dist": self.cv_dist.tolist(),
                "size": None if self.size is None else list(self.size),
                "rms_px": self.rms_px, "source": self.source, "given": self.given,
                "model": "rational_polynomial" if self.rational else "plumb_bob"}


def _matrix(node: Any, what: str, path: Path) -> Array:
    """A matrix from ``{rows, cols, data}``, nested lists or a flat list."""
    try:
        if isinstance(node, dict):
            rows, cols = int(node["rows"]), int(node["cols"])
            data = np.asarray(node["data"], dtype=float)
            if data.size != rows * cols:
                raise ValueError
            return data.reshape(rows, cols)
        return np.asarray(node, dtype=float)
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{what}: expected {{rows, cols, data}} or a list of numbers",
                         file=path) from None


def _from_mapping(doc: dict, path: Path) -> CameraIntrinsics:
    kname = next((k for k in _K_NAMES if k in doc), None)
    if kname is None:
        raise InputError("no camera matrix found; expected camera_matrix (ROS "
                         "camera_calibration YAML) or cameraMatrix / K", file=path)
    K = _matrix(doc[kname], kname, path).reshape(-1)
    if K.size != 9:
        raise InputError(f"{kname}: {K.size} values, expected 9 (3x3)", file=path)
    dname = next((k for k in _D_NAMES if k in doc), None)
    d = np.zeros(5) if dname is None else _matrix(doc[dname], dname, path).ravel()
    model = str(doc.get("distortion_model", "plumb_bob") or "plumb_bob").lower()
    if model in ("equidistant", "fisheye", "kannala_brandt"):
        raise InputError(f"distortion_model {model}: fisheye models are not supported; "
                         "expected plumb_bob or rational_polynomial", file=path)
    if model not in _MODELS:
        raise InputError(f"unknown distortion_model {model!r}; expected one of "
                         f"{', '.join(_MODELS)}", file=path)
    if d.size not in (0, 4, 5, 8, 12, 14):
        raise InputError(f"{dname}: {d.size} coefficients, expected 4, 5 or 8", file=path)
    size = _image_size(doc, path)
    try:
        intr = CameraIntrinsics(K.reshape(3, 3), d, size, source=path.name)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    check_focal(intr.K, intr.size, path)
    return intr


#: a focal length beyond these multiples of the image width (field of view below 0.06 deg
#: or above 175 deg) is no camera calibration's; nor fx / fy beyond `ASPECT`
FOCAL_RANGE = (0.02, 1000.0)
ASPECT = 10.0


def check_focal(K: Array, size: tuple[int, int] | None, path: Path | None = None) -> None:
    """Refuse implausible focal lengths (`FOCAL_RANGE` of the image width, the width
    taken as twice the principal point's x when the size is not known): a mistyped or
    overflowing value makes the board poses meaningless ("board behind the camera")."""
    fx, fy = float(K[0, 0]), float(K[1, 1])
    width = float(size[0]) if size and size[0] > 0 else 2.0 * abs(float(K[0, 2]))
    if not width > 0:
        return
    lo, hi = FOCAL_RANGE
    for name, f in (("fx", fx), ("fy", fy)):
        if not lo * width <= f <= hi * width:
            fov = float(np.degrees(2.0 * np.arctan(width / (2.0 * f)))) if f > 0 else 180.0
            raise InputError(f"focal length {name} = {f:.6g} px is implausible for an image "
                             f"{width:.0f} px wide (a field of view of {fov:.3g} deg); "
                             f"expected {lo:g} to {hi:g} times the width", file=path)
    if max(fx, fy) > ASPECT * min(fx, fy):
        raise InputError(f"focal lengths fx = {fx:.6g} and fy = {fy:.6g} px differ by more "
                         f"than {ASPECT:g} times: no camera has such pixels", file=path)


def _image_size(doc: dict, path: Path) -> tuple[int, int] | None:
    """``(image_width, image_height)``; None when absent; ``(0, 0)`` (ROS: unknown) kept."""
    if "image_width" not in doc or "image_height" not in doc:
        return None
    try:
        w, h = float(doc["image_width"]), float(doc["image_height"])
    except (TypeError, ValueError, OverflowError):
        w = h = -1.0
    whole = all(np.isfinite(v) and v == int(v) for v in (w, h))
    if not whole or not (w == h == 0 or (w > 0 and h > 0 and w * h <= MAX_IMAGE_PIXELS)):
        raise InputError(f"image_width / image_height {doc['image_width']!r} x "
                         f"{doc['image_height']!r}: expected two positive integers (a "
                         f"camera image of at most {MAX_IMAGE_PIXELS / 1e6:.0f} MP; 0 x 0 "
                         "when unknown)", file=path)
    return int(w), int(h)


def _read_filestorage(path: Path) -> CameraIntrinsics:
    from kinecal.vision import require_cv2

    cv2 = require_cv2()
    try:
        return _filestorage_mapping(cv2, path)
    except (cv2.error, SystemError) as exc:  # SystemError: cv2's parser on a broken file
        reason = " ".join(str(exc).split())[-200:] if isinstance(exc, cv2.error) else \
            "its parser stopped: broken XML or YAML"
        raise InputError(f"not a readable OpenCV FileStorage file ({reason})",
                         file=path) from None


def _filestorage_mapping(cv2: Any, path: Path) -> CameraIntrinsics:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise InputError("not a readable OpenCV FileStorage file", file=path)
        doc: dict[str, Any] = {}
        root = fs.root()
        for key in root.keys():
            node = fs.getNode(key)
            if node.isMap() or node.isSeq():
                m = node.mat()
                if m is not None:
                    doc[key] = np.asarray(m, dtype=float)
                elif node.isSeq():
                    doc[key] = [node.at(i).real() for i in range(node.size())]
            elif node.isInt() or node.isReal():
                doc[key] = node.real()
            elif node.isString():
                doc[key] = node.string()
        return _from_mapping(doc, path)
    finally:
        fs.release()


def read_intrinsics(path: str | Path) -> CameraIntrinsics:
    """Read camera intrinsics (see the module docstring for the formats).

    Raises
    ------
    InputError
        Missing file, unknown format, missing camera matrix, bad values, fisheye model.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        doc = read_json(path)  # too deep, too long integers refused
        if not isinstance(doc, dict):
            raise InputError("expected a JSON object with camera_matrix", file=path)
        return _from_mapping(doc, path)
    text = read_text(path)
    head = text.lstrip()[:200]
    if suffix == ".xml" or head.startswith("%YAML:1") or "!!opencv-matrix" in text \
            or head.startswith("<?xml"):
        return _read_filestorage(path)
    if suffix not in (".yaml", ".yml"):
        raise InputError(f"unknown intrinsics file type {suffix or '(none)'!r}; expected "
                         ".yaml/.yml (ROS camera_calibration or OpenCV), .xml or .json",
                         file=path)
    doc = load_yaml(text, path)  # safe, alias bombs and deep nesting refused
    if not isinstance(doc, dict):
        raise InputError("expected a mapping with camera_matrix (ROS camera_calibration)",
                         file=path)
    return _from_mapping(doc, path)


def write_intrinsics(path: str | Path, intr: CameraIntrinsics, name: str = "camera") -> None:
    """Write `intr` as ROS ``camera_calibration`` YAML (atomic)."""
    K, d = intr.K, intr.cv_dist
    w, h = intr.size if intr.size is not None else (0, 0)
    P = np.zeros((3, 4))
    P[:, :3] = K

    def block(rows: int, cols: int, data: Array) -> str:
        vals = ", ".join(repr(float(v)) for v in np.ravel(data))
        return f"\n  rows: {rows}\n  cols: {cols}\n  data: [{vals}]"

    text = (f"image_width: {int(w)}\nimage_height: {int(h)}\ncamera_name: {name}\n"
            f"camera_matrix:{block(3, 3, K)}\n"
            f"distortion_model: {'rational_polynomial' if intr.rational else 'plumb_bob'}\n"
            f"distortion_coefficients:{block(1, len(d), d)}\n"
            f"rectification_matrix:{block(3, 3, np.eye(3))}\n"
            f"projection_matrix:{block(3, 4, P)}\n")
    write_text_atomic(path, text)


def estimate_intrinsics(
    object_points: Sequence[Array],
    image_points: Sequence[Array],
    size: tuple[int, int],
    *,
    rational: bool = False,
    fix_k3: bool | None = None,
) -> CameraIntrinsics:
    """Camera intrinsics from board detections by ``cv2.calibrateCamera``.

    Parameters
    ----------
    object_points : sequence of ndarray, shape (N_i, 3)
        Board coordinates of the detected corners of each image.
    image_points : sequence of ndarray, shape (N_i, 2)
        Their pixel positions.
    size : (int, int)
        Image width, height.
    rational : bool
        Estimate the 8-coefficient rational model.
    fix_k3 : bool, optional
        Hold k3 at zero (default: when fewer than 10 images; k3 is poorly determined then).

    Returns
    -------
    CameraIntrinsics
        With ``rms_px`` and ``per_view_rms``.

    Raises
    ------
    InputError
        Fewer than 3 images, or OpenCV fails.
    """
    from kinecal.vision import opencv_one_thread, require_cv2

    cv2 = require_cv2()
    n = len(object_points)
    if n < 3:
        raise InputError(f"{n} usable image(s): estimating the camera intrinsics needs at least "
                         "3 views of the board (or pass --intrinsics)")
    if fix_k3 is None:
        fix_k3 = n < 10
    flags = cv2.CALIB_RATIONAL_MODEL if rational else 0
    if fix_k3 and not rational:
        flags |= cv2.CALIB_FIX_K3
    obj = [np.asarray(p, np.float32).reshape(-1, 1, 3) for p in object_points]
    img = [np.asarray(p, np.float32).reshape(-1, 1, 2) for p in image_points]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    try:  # on one thread: on OpenCV's threads the last digits change from call to call
        with opencv_one_thread():
            out = cv2.calibrateCameraExtended(obj, img, (int(size[0]), int(size[1])), None,
                                              None, flags=flags, criteria=crit)
    except cv2.error as exc:
        raise InputError(f"camera calibration failed: {' '.join(str(exc).split())}") from None
    rms, K, d = out[0], out[1], out[2]
    per_view = np.asarray(out[-1], dtype=float).ravel()
    return CameraIntrinsics(np.asarray(K, float), np.asarray(d, float).ravel(),
                            (int(size[0]), int(size[1])), float(rms),
                            f"estimated from {n} images", [float(v) for v in per_view],
                            rational)
