"""From images and robot poses to X: detection, intrinsics, PnP, closed form, refinement.

`calibrate_handeye_images` is what ``kinecal handeye-images`` runs:

1. detect the board in every image (`kinecal.vision.detect`), the images in parallel on a
   thread pool sized to the CPUs; rejected images keep their reason and are never used;
2. camera intrinsics from the user's file, or estimated from the accepted images
   (``cv2.calibrateCamera``, reprojection RMS reported);
3. the board pose of every accepted image by PnP with its covariance
   (`kinecal.vision.pnp`); views tilted beyond the limit are rejected as too oblique;
4. a closed form on the poses and its plausibility checks
   (`kinecal.calibration.handeye.calibrate_handeye`), the seed;
5. the refinement on the reprojection error of every corner
   (`kinecal.calibration.handeye.images.refine_reprojection`): X and the board pose
   jointly, intrinsics and robot-pose errors optionally, robust, outlier stations flagged;
   when it flags stations, it runs again from the robust pose-level solution (RANSAC
   start, reweighted LM), which the outliers cannot pull.

The result types (`ImageRecord`, `ImageHandEyeResult`, re-exported here) are in
`kinecal.vision.results`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.board_scale import warn_board_scale
from kinecal.calibration.handeye.images import refine_reprojection
from kinecal.calibration.handeye.refinement import ReprojectionRefinement
from kinecal.errors import InputError
from kinecal.vision.boards import Board
from kinecal.vision.detect import QualityLimits, orientation_ambiguous
from kinecal.vision.intrinsics import CameraIntrinsics
from kinecal.vision.results import ImageHandEyeResult, ImageRecord
from kinecal.vision.stages import (
    as_rows,
    board_poses,
    camera_intrinsics,
    check_arguments,
    detect_all,
    take_board_pose,
    too_few,
)
from kinecal.vision.turns import turn_flipped, warn_symmetric

Array = NDArray[np.float64]

__all__ = ["ImageHandEyeResult", "ImageRecord", "calibrate_handeye_images"]


def calibrate_handeye_images(
    images: Sequence[Any],
    flange2base: Array,
    board: Board,
    *,
    names: Sequence[str] | None = None,
    intrinsics: CameraIntrinsics | None = None,
    setup: str = "eye-in-hand",
    method: str = "park",
    refine_intrinsics: bool | None = None,
    robot_noise: tuple[float, float] | str | None = "auto",
    robust: bool = True,
    limits: QualityLimits | None = None,
    progress: Callable[..., None] | None = None,
    camera_height: float | None = None,
    board_contact: Any = None,
) -> ImageHandEyeResult:
    """Hand-eye calibration from board images and robot poses.

    Parameters
    ----------
    images : sequence of ndarray or path
        One image per station (8-bit grey or BGR arrays, or files OpenCV reads).
    flange2base : ndarray, shape (n, 4, 4)
        Robot flange pose of every image, in the board's length unit.
    board : Board
        From `kinecal.vision.boards.parse_board`.
    names : sequence of str, optional
        Image names for the result (default: file names or ``image_<i>``).
    intrinsics : CameraIntrinsics, optional
        Camera; default: estimated from the accepted images.
    setup : {"eye-in-hand", "eye-to-hand"}
    method : str
        Closed form of the seed (`kinecal.calibration.handeye.METHODS`).
    refine_intrinsics : bool, optional
        Refine the intrinsics jointly with X. Default: yes when they are estimated from the
        same images (the hand-eye constraint ties the views together: on the rendered
        walkthrough scene X's translation error falls from 0.10 to 0.007 mm), no when they
        are given (a dedicated camera calibration is usually better conditioned).
    robot_noise : (float, float), "auto" or None
        Robot pose error std, rotation (rad) and translation (length): model it. ``"auto"``
        (default): estimated from the stations' consistency and modelled when it matters
        (`kinecal.calibration.handeye.robot_noise`); None: the robot poses are exact.
    robust : bool
        Robust refinement with outlier stations (default).
    limits : QualityLimits, optional
        Per-image quality thresholds.
    progress : callable, optional
        Called as ``progress()`` after each image is detected.
    camera_height, board_contact : optional
        Robots that turn about one axis only (SCARA): X's height along the axis, or a point
        of the board plane touched by the tool (`kinecal.calibration.handeye.calibrate_handeye`).

    Returns
    -------
    ImageHandEyeResult

    Raises
    ------
    InputError
        Count mismatch, fewer than 3 usable images (the reasons summarised), degenerate
        robot motions, bad intrinsics.
    """
    t0 = time.perf_counter()
    limits = limits or QualityLimits()
    names = check_arguments(images, names, board, intrinsics)
    F = as_rows(flange2base, "flange2base")
    if F.ndim != 3 or F.shape[1:] != (4, 4):
        raise InputError(f"flange2base: expected shape (n, 4, 4), got {F.shape}")
    if len(images) != len(F):
        raise InputError(f"{len(images)} images but {len(F)} robot poses: expected one pose "
                         "per image")
    with diagnostics.collect() as found:
        if orientation_ambiguous(board):
            warn_symmetric(board)
        expected = None if intrinsics is None or not intrinsics.size else \
            tuple(intrinsics.size)
        # with the intrinsics given, each image's board pose is taken in its detection
        # worker too (OpenCV's PnP releases the GIL as its detectors do)
        pose_of = None if intrinsics is None else \
            (lambda r: take_board_pose(r, board, intrinsics, limits))
        records, size = detect_all(images, names, board, limits, progress, expected, pose_of)
        intr = camera_intrinsics(records, board, size, intrinsics)
        if refine_intrinsics is None:
            refine_intrinsics = intrinsics is None
        board_poses(records, board, intr, limits)
        used = [k for k, r in enumerate(records) if r.status == "used"]
        if len(used) < 3:
            raise InputError(too_few(records))
        idx = np.array(used)
        C = np.array([records[k].pose.target2cam for k in used])
        if orientation_ambiguous(board) and turn_flipped(records, used, board, F[idx], C,
                                                          setup, method):
            C = np.array([records[k].pose.target2cam for k in used])
        obj = [records[k].detection.object_points(board) for k in used]
        pix = [records[k].detection.corners for k in used]
        axis = {"camera_height": camera_height, "board_contact": board_contact}
        seed, ref, one = _seed_and_refine(F[idx], C, obj, pix, intr, setup, method, board,
                                          refine_intrinsics, robot_noise, robust, axis)
        for j, k in enumerate(used):
            records[k].residuals = ref.residuals[j]
        for j in ref.outliers:
            r = records[used[j]]
            r.status = "outlier"
            med = float(np.median(ref.station_rms))
            r.reason = ("station inconsistent with the others: " + (
                f"corner RMS {ref.station_rms[j]:.2f} px vs median {med:.2f} px"
                if np.isfinite(ref.station_rms[j]) else "its board would be behind the camera")
                + " (robot pose or image wrong?)")
        if refine_intrinsics:
            intr = CameraIntrinsics(ref.K, ref.dist, intr.size, intr.rms_px,
                                    intr.source + ", refined with X", intr.per_view_rms,
                                    intr.rational)
        _plausibility(ref, records, limits)
        if intrinsics is None:
            from kinecal.calibration.handeye.camera import check_intrinsics_determined

            check_intrinsics_determined(ref.cov, ref.names, ref.K, size)
    warnings = [d.to_dict() for d in found]
    res = ImageHandEyeResult(ref.X, ref.Y, setup, seed.method, board, intr, refine_intrinsics,
                             records, ref, seed, warnings, time.perf_counter() - t0)
    if one is not None:
        from kinecal.calibration.handeye.one_axis import one_axis_summary

        res.one_axis = one_axis_summary(*one, ref.X, ref.Y)
    return res


def _one_axis(seed: Any, F: Array, setup: str, camera_height: float | None,
              board_contact: Any) -> Any:
    """(axis, height) when the seed found one-axis stations (SCARA), else None."""
    if seed.one_axis is None:
        return None
    from kinecal.calibration.handeye.scara import AxisHeight, detect_one_axis
    from kinecal.spatial import invert_transform

    G = F if setup == "eye-in-hand" else invert_transform(F)
    return detect_one_axis(G, setup), AxisHeight.from_options(camera_height, board_contact)


def _seed_and_refine(F: Array, C: Array, obj: list[Array], pix: list[Array],
                     intr: CameraIntrinsics, setup: str, method: str, board: Board,
                     refine_intrinsics: bool,
                     robot_noise: tuple[float, float] | str | None, robust: bool,
                     axis: dict[str, Any]) -> tuple[Any, ReprojectionRefinement, Any]:
    """The closed form (with the pose-level checks) seeds the refinement on the pixels,
    which is robust itself. When that refinement flags stations, it runs again from the
    robust pose-level solution (RANSAC start, reweighted LM), which outlier stations
    cannot pull, and that run is the result. `axis`: ``camera_height`` and
    ``board_contact`` for one-axis robots; also returns their (axis, height) or None."""
    def refine(seed: Any) -> ReprojectionRefinement:
        return refine_reprojection(F, obj, pix, intr.K, intr.dist, seed.X, seed.target,
                                   setup=setup, refine_intrinsics=refine_intrinsics,
                                   rational=intr.rational, robot_noise=robot_noise,
                                   robust=robust, one_axis=one,
                                   intrinsics_estimated=intr.rms_px is not None)

    from kinecal.calibration.handeye.scara import detect_one_axis
    from kinecal.spatial import invert_transform

    # one-axis robots (SCARA): Ulrich and Steger's closed form is judged (conditioning)
    # after its pose-level refinement, which is then the seed
    G = F if setup == "eye-in-hand" else invert_transform(F)
    first = "none" if detect_one_axis(G, setup) is None else "lm"
    # the refinement on the pixels judges the outlier stations: the closed form's own
    # flags (a robust pose-level refinement, `robust=True` with refine "none") would be
    # that work twice; its other checks run
    with diagnostics.expect("scale-mismatch") as scale:  # said below with the board's size
        seed = calibrate_handeye(F, C, setup=setup, method=method, refine=first,
                                 robust=first == "lm", **axis)
    if scale:
        warn_board_scale(board.spec, board.pitch, G, C, seed.X, scale[0].message)
    one = _one_axis(seed, F, setup, axis["camera_height"], axis["board_contact"])
    try:
        ref = refine(seed)
    except InputError:  # a seed pulled by wrong stations puts boards behind the camera
        if not robust or first != "none":
            raise
        ref = None
    if robust and first == "none" and (ref is None or ref.outliers):
        with diagnostics.expect("scale-mismatch"):  # the first seed's check said it
            seed = calibrate_handeye(F, C, setup=setup, method=method, refine="lm", **axis)
        ref = refine(seed)
    return seed, ref, one


def _plausibility(ref: ReprojectionRefinement, records: list[ImageRecord],
                  limits: QualityLimits) -> None:
    n = len(records)
    rej = sum(r.status == "rejected" for r in records)
    if n and rej > n / 2:
        diagnostics.warn("images-rejected",
                         f"{rej} of {n} images rejected: check the --board spec (inner "
                         "corners for chessboards) and the image quality")
    if ref.rms_px > 2.0:
        diagnostics.warn("reprojection-rms",
                         f"the hand-eye solution reprojects the corners to {ref.rms_px:.2f} px "
                         "RMS: the robot poses, their unit or frame, the --setup, the "
                         "board's square size (--board) or the intrinsics are probably wrong")
    if ref.outliers and len(ref.outliers) > 0.3 * len(ref.station_rms):
        diagnostics.warn("many-outliers",
                         f"{len(ref.outliers)} of {len(ref.station_rms)} stations flagged as "
                         "outliers: the robot poses may be in another unit, frame or order "
                         "than the images")
