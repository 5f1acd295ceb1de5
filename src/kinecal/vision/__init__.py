"""Calibration boards in images: detection, camera intrinsics, board poses, rendering.

The image side of hand-eye calibration from pictures (`kinecal.vision.pipeline`):

- `boards`: chessboard and ChArUco boards and the ``--board`` syntax (`board_base`: the
  interface; `circle_grids`: OpenCV's asymmetric and symmetric circle grids and
  industrial_calibration's modified circle grid);
- `detect`: detection with sub-pixel corners and per-image quality checks with reasons
  (`detection`: what a detection returns; `detect_circles`: the circle grids);
- `intrinsics`: camera intrinsics read from ROS / OpenCV / JSON files or estimated;
- `pnp`: the board pose per image with its covariance;
- `imaging`: a board's image through a known camera (distortion, light, blur, noise);
- `render`: synthetic hand-eye scenes: planned views, rendered images, truth (tests,
  docs, planning);
- `pipeline`: images + robot poses -> X, refined on the reprojection error;
- `results`: what the pipeline returns, per image and as a whole (JSON);
- camera rigs (docs/rigs.md): `rig` (``--camera NAME:LINK[:I.yaml]``, ``--board
  NAME:LINK:SPEC``), `rig_mounts` and `rig_scene` (a rig's default mounts and rendered
  stations of a perturbed arm or system; `scene_views` without rendering), `rig_files`
  (images, STATIONS.csv, truth), `rig_images` (detection per camera and board, ChArUco
  boards told apart by their ids, and `calibrate_rig_images`).

OpenCV (``opencv-python-headless``, the ``vision`` extra) is imported lazily: importing
this package works on the core install, and the first function that needs OpenCV raises
`kinecal.InputError` naming the extra when it is missing.

Same inputs, same bits: OpenCV's own worker threads are off while kinecal's image stages
run (`opencv_one_thread`). ``cv2.calibrateCamera`` on its default threads returns
intrinsics that differ in the last digits from call to call on the same corners (about one
call in three on a 2-CPU machine), and every later number inherits that; the images are
detected in parallel by kinecal's own thread pool instead, each image on one thread, so
the threads decide nothing but the order the work is done in.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

from kinecal.errors import InputError

__all__ = ["opencv_one_thread", "require_cv2"]


def require_cv2() -> ModuleType:
    """The ``cv2`` module, or `InputError` saying how to install it."""
    try:
        import cv2
    except ImportError:
        raise InputError("images need OpenCV: pip install 'kinecal[vision]' "
                         "(opencv-python-headless)") from None
    if not hasattr(cv2, "aruco") or not hasattr(cv2, "solvePnP"):
        raise InputError(f"OpenCV {getattr(cv2, '__version__', '?')} lacks aruco/calib3d; "
                         "pip install 'kinecal[vision]' (opencv-python-headless >= 4.8)")
    return cv2


_THREADS_LOCK = threading.Lock()
_threads_state = {"depth": 0, "saved": 0}


@contextmanager
def opencv_one_thread() -> Iterator[ModuleType]:
    """``cv2`` with its worker threads off (``cv2.setNumThreads(1)``) inside the block, the
    caller's setting restored when the outermost such block ends (blocks nest, also across
    threads). OpenCV's thread setting is the process's: another thread's OpenCV calls run on
    one thread too while a block is open."""
    cv2 = require_cv2()
    with _THREADS_LOCK:
        if _threads_state["depth"] == 0:
            _threads_state["saved"] = cv2.getNumThreads()
            cv2.setNumThreads(1)
        _threads_state["depth"] += 1
    try:
        yield cv2
    finally:
        with _THREADS_LOCK:
            _threads_state["depth"] -= 1
            if _threads_state["depth"] == 0:
                cv2.setNumThreads(_threads_state["saved"])
