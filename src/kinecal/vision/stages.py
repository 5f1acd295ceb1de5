"""The image stages shared by the hand-eye and the arm-from-images pipelines: read and
detect every image (in parallel), the camera intrinsics (given or estimated), and the board
pose of every accepted image; rejected images keep their reason.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.errors import InputError
from kinecal.vision import opencv_one_thread, require_cv2
from kinecal.vision.boards import Board
from kinecal.vision.detect import QualityLimits, Survey, as_gray, detect
from kinecal.vision.image_files import check_image_file
from kinecal.vision.intrinsics import CameraIntrinsics, estimate_intrinsics
from kinecal.vision.pnp import board_pose
from kinecal.vision.results import ImageRecord

__all__ = ["as_rows", "board_poses", "camera_intrinsics", "check_arguments", "cpu_count",
           "detect_all", "load_gray", "rejections", "take_board_pose", "too_few"]


def check_arguments(images: Sequence[Any], names: Sequence[str] | None, board: Any,
                    intrinsics: Any) -> list[str]:
    """The image names (default: file names or ``image_<i>``), after the argument types and
    counts of an image pipeline are checked.

    Raises
    ------
    TypeError
        `board` not a `Board`, `intrinsics` neither None nor `CameraIntrinsics`.
    InputError
        `names` not one per image.
    """
    if not isinstance(board, Board):
        raise TypeError(f"board: expected a Board (kinecal.vision.boards.parse_board), got "
                        f"{type(board).__name__}")
    if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
        raise TypeError(f"intrinsics: expected CameraIntrinsics (kinecal.vision.intrinsics."
                        f"read_intrinsics) or None, got {type(intrinsics).__name__}")
    if names is None:
        return [Path(im).name if isinstance(im, str | Path) else f"image_{i}"
                for i, im in enumerate(images)]
    if len(names) != len(images):
        raise InputError(f"{len(names)} names for {len(images)} images: expected one name per "
                         "image", option="names")
    return [str(n) for n in names]


def as_rows(values: Any, what: str) -> NDArray[np.float64]:
    """`values` as a float array; `InputError` naming `what` when they are not numbers."""
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what}: expected numbers ({exc})") from None


def load_gray(path: str | Path) -> NDArray[np.uint8] | None:
    """8-bit grey image from a file (None when OpenCV cannot read it).

    Raises `InputError` for an image too large to be a camera's, judged from its header
    before decoding, and for a PNG or JPEG file that ends early
    (`kinecal.vision.image_files.check_image_file`).
    """
    check_image_file(path)
    return _decode(path)


def _decode(path: str | Path) -> NDArray[np.uint8] | None:
    cv2 = require_cv2()
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return None if img is None else np.asarray(img)


def _sizes_before_decoding(images: Sequence[Any]) -> list[tuple[int, int] | str | None]:
    """Per image: ``(width, height)`` from a file's header or an array's shape, the reason
    a file is refused unread (too large, truncated), or None (size known once decoded)."""
    out: list[tuple[int, int] | str | None] = []
    for im in images:
        if isinstance(im, str | Path):
            try:
                out.append(check_image_file(im))
            except InputError as exc:
                out.append(exc.message)
        else:
            shape = np.shape(im)
            out.append((int(shape[1]), int(shape[0])) if len(shape) in (2, 3) else None)
    return out


def _session_size(seen: list[tuple[int, int]], expected: tuple[int, int] | None
                  ) -> tuple[int, int] | None:
    """The size of most images (ties: the first's), or `expected` when images have it."""
    if not seen:
        return None
    if expected is not None and tuple(expected) in seen:
        return tuple(expected)  # type: ignore[return-value]
    return max(dict.fromkeys(seen), key=seen.count)


def _odd_size(z: tuple[int, int], size: tuple[int, int]) -> str:
    return f"image size {z[0]}x{z[1]} differs from the other images' {size[0]}x{size[1]}"


def detect_all(images: Sequence[Any], names: Sequence[str], board: Board,
                limits: QualityLimits, progress: Callable[..., None] | None,
                expected: tuple[int, int] | None = None,
                pose_of: Callable[[ImageRecord], None] | None = None
                ) -> tuple[list[ImageRecord], tuple[int, int] | None]:
    """Detect the board in every readable image; the session's image size is the size of
    most images (ties: the first image's), or `expected` (the intrinsics' size) when images
    have it, so one odd image, first or not, is the one rejected. Sizes come from the files'
    headers first: an odd-sized, too large or truncated file is rejected without decoding
    it (`kinecal.vision.image_files.check_image_file`)."""
    pre = _sizes_before_decoding(images)
    size = _session_size([z for z in pre if isinstance(z, tuple)], expected)
    session = Survey()

    def one(item: tuple[str, Any, Any]) -> tuple[ImageRecord, tuple[int, int] | None]:
        name, im, known = item
        if isinstance(known, str):  # refused from its header
            return ImageRecord(str(name), "rejected", known), None
        if known is not None and size is not None and known != size:
            return ImageRecord(str(name), "rejected", _odd_size(known, size)), known
        gray = _decode(im) if isinstance(im, str | Path) else as_gray(im)
        if gray is None or gray.size == 0:
            return ImageRecord(str(name), "rejected", "cannot read the image file"), None
        h, w = gray.shape[:2]
        if size is not None and (w, h) != size:
            return ImageRecord(str(name), "rejected", _odd_size((w, h), size)), (w, h)
        det = detect(gray, board, limits, session)
        record = ImageRecord(str(name), "used" if det.ok else "rejected", det.reason, det)
        if pose_of is not None and det.ok:
            pose_of(record)
        return record, (w, h)

    records: list[ImageRecord] = []
    sizes: list[tuple[int, int] | None] = []
    # images in parallel: OpenCV's detectors, blurs and numpy's large-array work release
    # the GIL; results come back in input order. Each image on one thread (OpenCV's own
    # threads off, `kinecal.vision.opencv_one_thread`): no result depends on the threads
    workers = min(len(images), cpu_count())
    items = zip(names, images, pre, strict=True)
    with opencv_one_thread(), ThreadPoolExecutor(max_workers=max(workers, 1)) as pool:
        done = pool.map(one, items) if workers > 1 else map(one, items)
        for record, z in done:
            records.append(record)
            sizes.append(z)
            if progress is not None:
                progress()
    if size is None:  # no size known before decoding: the decoded images decide
        size = _session_size([z for z in sizes if z is not None], expected)
        for r, z in zip(records, sizes, strict=True):
            if z is not None and size is not None and z != size:
                r.status, r.detection, r.pose = "rejected", None, None
                r.reason = _odd_size(z, size)
    return records, size


def cpu_count() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def camera_intrinsics(records: list[ImageRecord], board: Board, size: tuple[int, int] | None,
                given: CameraIntrinsics | None) -> CameraIntrinsics:
    ok = [r for r in records if r.status == "used"]
    if given is not None:
        if given.size is not None and size is not None and tuple(given.size) != size \
                and given.size != (0, 0):
            diagnostics.warn("intrinsics-size",
                             f"the intrinsics are for {given.size[0]}x{given.size[1]} images "
                             f"but the images are {size[0]}x{size[1]}: wrong camera file or "
                             "resized images")
        return given
    if len(ok) < 3:
        raise InputError(too_few(records) + "; estimating the intrinsics needs at least 3 "
                         "(or pass --intrinsics)")
    intr = estimate_intrinsics([r.detection.object_points(board) for r in ok],
                               [r.detection.corners for r in ok], size)
    if intr.rms_px is not None and intr.rms_px > 1.0:
        diagnostics.warn("intrinsics-rms",
                         f"the camera calibration from the images leaves {intr.rms_px:.2f} px "
                         "RMS: blur, a wrong board size or too few views; pass --intrinsics "
                         "from a dedicated calibration")
    return intr


def board_poses(records: list[ImageRecord], board: Board, intr: CameraIntrinsics,
           limits: QualityLimits) -> None:
    ok = [r for r in records if r.status == "used"]
    for r in ok:
        if r.pose is None:  # not yet taken in the detection worker
            take_board_pose(r, board, intr, limits)
    with_pose = [r for r in ok if r.pose is not None and r.status == "used"]
    if not with_pose:
        return
    med = float(np.median([r.pose.rms_px for r in with_pose]))
    if med > limits.max_pnp_rms:
        diagnostics.warn("pnp-rms", f"the board poses fit the corners to {med:.2f} px RMS "
                         "(median): the intrinsics or the board size are probably wrong")
        return
    for r in with_pose:
        if r.pose.rms_px > max(limits.max_pnp_rms, 5.0 * med):
            r.status = "rejected"
            r.reason = (f"corners do not fit a board pose ({r.pose.rms_px:.2f} px RMS): "
                        "mis-detected or mis-ordered corners")


def take_board_pose(r: ImageRecord, board: Board, intr: CameraIntrinsics,
             limits: QualityLimits) -> None:
    """The board pose of one accepted image; rejected when PnP fails or too oblique."""
    try:
        r.pose = board_pose(r.detection.object_points(board), r.detection.corners,
                            intr.K, intr.dist)
    except InputError as exc:
        r.status, r.reason = "rejected", f"no board pose: {exc.message}"
        return
    if r.pose.tilt_deg > limits.max_tilt_deg:
        r.status = "rejected"
        r.reason = (f"too oblique: board tilted {r.pose.tilt_deg:.0f} deg from facing the "
                    f"camera (> {limits.max_tilt_deg:g} deg)")


def too_few(records: list[ImageRecord]) -> str:
    """Why fewer than 3 images are usable (`rejections`), for hand-eye calibration."""
    used = sum(r.status == "used" for r in records)
    return (f"{used} usable image(s) of {len(records)}: hand-eye calibration needs at least 3"
            + rejections([(r.name, r.reason) for r in records if r.status == "rejected"]))


#: a rejection reason naming the whole chessboard seen (`kinecal.vision.detect`)
_SEEN = re.compile(r"a whole chessboard of (\d+)x(\d+) inner corners is seen, not the "
                   r"(\d+)x(\d+) of the board spec")


def rejections(rejected: list[tuple[str, str]]) -> str:
    """`` (rejected: REASON: COUNT, ...; e.g. NAME: REASON)`` for the (name, reason) pairs
    of the rejected images, led by the board size the images show when most of them name
    one (a wrong ``--board`` spec); empty when none was rejected."""
    if not rejected:
        return ""
    reasons: dict[str, int] = {}
    example: dict[str, tuple[str, str]] = {}
    sizes: dict[str, int] = {}
    for name, reason in rejected:
        key = reason.split(":")[0].split(";")[0].split("(")[0].strip()
        reasons[key] = reasons.get(key, 0) + 1
        example.setdefault(key, (name, reason))
        m = _SEEN.search(reason)
        if m:
            sizes[f"{m[1]}x{m[2]}"] = sizes.get(f"{m[1]}x{m[2]}", 0) + 1
            spec = f"{m[3]}x{m[4]}"
    ranked = sorted(reasons.items(), key=lambda kv: -kv[1])
    name, reason = example[ranked[0][0]]
    lead = ""
    if sizes:
        seen, k = max(sizes.items(), key=lambda kv: kv[1])
        if 2 * k >= len(rejected):
            lead = (f"; the images show a chessboard of {seen} inner corners ({k} of "
                    f"{len(rejected)} rejected), not the {spec} of the board spec: "
                    f"--board chessboard:{seen}:SQUARE")
    return (lead + " (rejected: " + ", ".join(f"{k}: {v}" for k, v in ranked)
            + f"; e.g. {name}: {reason})")
