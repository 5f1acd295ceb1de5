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
"""

from __future__ import annotations

from types import ModuleType

from kinecal.errors import InputError

__all__ = ["require_cv2"]


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
