"""From board images and joint readings to a calibrated arm: what ``kinecal calibrate MODEL
STATIONS.csv --images DIR --board SPEC`` runs.

1. detect the board in every image (`kinecal.vision.detect`, the checks of ``kinecal
   handeye-images``); a station whose board is not found, or not trusted, is skipped with
   its reason (warning ``station-skipped``);
2. intrinsics from the user's file, or estimated from the accepted images (then refined
   with the arm);
3. the board pose of every accepted image by PnP (`kinecal.vision.pnp`), for the start;
4. the bundle adjustment of the arm, X and the board pose on the corner pixels
   (`kinecal.calibration.camera.calibrate_arm_camera`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.camera.result import ArmCameraResult, Stations
from kinecal.calibration.camera.solve import calibrate_arm_camera
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.vision.boards import Board
from kinecal.vision.detect import QualityLimits
from kinecal.vision.intrinsics import CameraIntrinsics
from kinecal.vision.stages import (
    as_rows,
    board_poses,
    camera_intrinsics,
    check_arguments,
    detect_all,
    rejections,
)

Array = NDArray[np.float64]

__all__ = ["calibrate_arm_images", "detect_stations"]


def detect_stations(images: Sequence[Any], q: Array, names: Sequence[str], board: Board,
                    intrinsics: CameraIntrinsics | None, limits: QualityLimits | None = None,
                    progress: Callable[..., None] | None = None, poses: bool = True
                    ) -> tuple[Stations, CameraIntrinsics, list[dict[str, str]]]:
    """Detected stations, the intrinsics, and the skipped images with their reasons.

    Parameters
    ----------
    images : sequence of path or ndarray
    q : ndarray, shape (n, n_joints)
        Joint readings of every image (rad).
    names : sequence of str
    board : Board
    intrinsics : CameraIntrinsics, optional
        Default: estimated from the accepted images.
    limits : QualityLimits, optional
    progress : callable, optional
    poses : bool
        Compute each image's board pose (PnP; rejects too oblique views).

    Returns
    -------
    stations : Stations
        The usable stations.
    intrinsics : CameraIntrinsics
    skipped : list of dict
        ``{"image", "reason"}`` per skipped image.
    """
    limits = limits or QualityLimits()
    expected = None if intrinsics is None or not intrinsics.size else tuple(intrinsics.size)
    records, size = detect_all(images, names, board, limits, progress, expected)
    intr = camera_intrinsics(records, board, size, intrinsics)
    if poses:
        board_poses(records, board, intr, limits)
    used = [k for k, r in enumerate(records) if r.status == "used"]
    skipped = [{"image": r.name, "reason": r.reason} for r in records if r.status != "used"]
    st = Stations(np.asarray(q, float)[used],
                  [records[k].detection.object_points(board) for k in used],
                  [records[k].detection.corners for k in used],
                  np.array([records[k].pose.target2cam for k in used]) if poses and used
                  else None, [records[k].name for k in used])
    return st, intr, skipped


def calibrate_arm_images(
    model: SerialModel,
    images: Sequence[Any],
    q: Array,
    board: Board,
    *,
    names: Sequence[str] | None = None,
    intrinsics: CameraIntrinsics | None = None,
    setup: str = "eye-in-hand",
    free: str | Sequence[str] = "identifiable",
    refine_intrinsics: bool | None = None,
    loss: str = "linear",
    validate: tuple[Sequence[Any], Array, Sequence[str]] | None = None,
    limits: QualityLimits | None = None,
    progress: Callable[..., None] | None = None,
) -> ArmCameraResult:
    """Calibrate an arm from board images and the joint readings of each.

    Parameters
    ----------
    model : SerialModel
        Nominal arm (its length unit is the board's).
    images : sequence of path or ndarray
        One image per station.
    q : ndarray, shape (n, n_joints)
        Joint readings per image (rad; prismatic: length unit).
    board : Board
    names : sequence of str, optional
    intrinsics : CameraIntrinsics, optional
        Default: estimated from the accepted images and refined with the arm.
    setup : {"eye-in-hand", "eye-to-hand"}
    free : {"identifiable", "all"} or sequence of str
    refine_intrinsics : bool, optional
        Default: when the intrinsics are estimated from the same images.
    loss : str
        ``linear`` or a robust loss per corner.
    validate : (images, q, names), optional
        Held-out stations: their reprojection before and after.
    limits : QualityLimits, optional
    progress : callable, optional

    Returns
    -------
    ArmCameraResult

    Raises
    ------
    InputError
        Count mismatch, fewer than 3 usable stations (the reasons summarised).
    """
    if not isinstance(model, SerialModel):
        raise TypeError(f"model: expected a SerialModel (kinecal.load_model), got "
                        f"{type(model).__name__}")
    names = check_arguments(images, names, board, intrinsics)
    q = _joint_rows(images, q, "q")
    if validate is not None:
        vimg, vq, vnames = validate
        validate = (vimg, _joint_rows(vimg, vq, "validate q"),
                    check_arguments(vimg, vnames, board, intrinsics))
    with diagnostics.collect() as found:
        st, intr, skipped = detect_stations(images, q, names, board, intrinsics, limits,
                                            progress)
        if len(st.q) < 3:
            raise InputError(_too_few(len(images), len(st.q), skipped, board))
        if skipped:
            first = skipped[0]
            diagnostics.warn("station-skipped",
                             f"{len(skipped)} of {len(images)} stations skipped (e.g. "
                             f"{first['image']}: {first['reason']})")
        val = None
        if validate is not None:
            vimg, vq, vnames = validate
            val, _, vskip = detect_stations(vimg, vq, vnames, board, intr, limits, poses=False)
            skipped += [{**s, "validation": True} for s in vskip]
        if refine_intrinsics is None:
            refine_intrinsics = intrinsics is None
        res = calibrate_arm_camera(
            model, st, intr.K, intr.dist, setup=setup, free=free,
            refine_intrinsics=refine_intrinsics, rational=intr.rational, loss=loss,
            validate=val, extra={"board": board.spec, "intrinsics_source": intr.source,
                                 "intrinsics_given": intr.given,
                                 "intrinsics_line": intr.describe(refine_intrinsics),
                                 "skipped": skipped, "n_images": len(images),
                                 "n_used": len(st.q)})
        if not intr.given and refine_intrinsics:
            _check_intrinsics(res, intr.size)
    res.val_names = [] if val is None else list(val.names)
    res.warnings = list(found)
    return res


def _check_intrinsics(res: ArmCameraResult, size: tuple[int, int] | None) -> None:
    """``intrinsics-weak`` of intrinsics estimated from the images and refined with the arm:
    the covariance of the camera block's unknowns (X, board, intrinsics), the arm's
    parameters marginalised."""
    from kinecal.calibration.handeye.camera import check_intrinsics_determined

    k = len(res.free)
    cov = res.uncertainty.covariance
    m = len(res.nuisance_names)
    if cov.shape[0] < k + m:
        return
    check_intrinsics_determined(cov[k:k + m, k:k + m], list(res.nuisance_names), res.K, size)


def _joint_rows(images: Sequence[Any], q: Any, what: str) -> Array:
    q = np.atleast_2d(as_rows(q, what))
    if len(images) != len(q):
        raise InputError(f"{len(images)} images but {len(q)} joint rows ({what}): expected "
                         "one row per image")
    return q


def _too_few(n: int, used: int, skipped: list[dict[str, str]], board: Board) -> str:
    return (f"{used} usable station(s) of {n}: the board {board.spec} was not found or not "
            "trusted in the others; calibrating an arm needs at least 3"
            + rejections([(s["image"], s["reason"]) for s in skipped])
            + " (check the --board spec: chessboards count inner corners)")
