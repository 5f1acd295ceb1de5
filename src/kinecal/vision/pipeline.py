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

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.images import ReprojectionRefinement, refine_reprojection
from kinecal.errors import InputError
from kinecal.vision import require_cv2
from kinecal.vision.boards import Board
from kinecal.vision.detect import QualityLimits, detect, orientation_ambiguous
from kinecal.vision.image_files import check_image_size
from kinecal.vision.intrinsics import CameraIntrinsics, estimate_intrinsics
from kinecal.vision.pnp import board_pose
from kinecal.vision.results import ImageHandEyeResult, ImageRecord

Array = NDArray[np.float64]

__all__ = ["ImageHandEyeResult", "ImageRecord", "calibrate_handeye_images", "load_gray"]


def load_gray(path: str | Path) -> NDArray[np.uint8] | None:
    """8-bit grey image from a file (None when OpenCV cannot read it).

    Raises `InputError` for an image too large to be a camera's, judged from its header
    before decoding (`kinecal.vision.image_files.check_image_size`).
    """
    cv2 = require_cv2()
    check_image_size(path)
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return None if img is None else np.asarray(img)


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
    robot_noise: tuple[float, float] | None = None,
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
    robot_noise : (float, float), optional
        Robot pose error std, rotation (rad) and translation (length): model it.
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
    F = np.asarray(flange2base, dtype=float)
    if F.ndim != 3 or F.shape[1:] != (4, 4):
        raise InputError(f"flange2base: expected shape (n, 4, 4), got {F.shape}")
    if len(images) != len(F):
        raise InputError(f"{len(images)} images but {len(F)} robot poses: expected one pose "
                         "per image")
    if names is None:
        names = [Path(im).name if isinstance(im, str | Path) else f"image_{i}"
                 for i, im in enumerate(images)]
    with diagnostics.collect() as found:
        if orientation_ambiguous(board):
            _warn_symmetric(board)
        expected = None if intrinsics is None or not intrinsics.size else \
            tuple(intrinsics.size)
        # with the intrinsics given, each image's board pose is taken in its detection
        # worker too (OpenCV's PnP releases the GIL as its detectors do)
        pose_of = None if intrinsics is None else \
            (lambda r: _pose_of(r, board, intrinsics, limits))
        records, size = _detect_all(images, names, board, limits, progress, expected, pose_of)
        intr = _intrinsics(records, board, size, intrinsics)
        if refine_intrinsics is None:
            refine_intrinsics = intrinsics is None
        _poses(records, board, intr, limits)
        used = [k for k, r in enumerate(records) if r.status == "used"]
        if len(used) < 3:
            raise InputError(_too_few(records))
        idx = np.array(used)
        C = np.array([records[k].pose.target2cam for k in used])
        if orientation_ambiguous(board) and _turn_flipped(records, used, board, F[idx], C,
                                                          setup, method):
            C = np.array([records[k].pose.target2cam for k in used])
        obj = [records[k].detection.object_points(board) for k in used]
        pix = [records[k].detection.corners for k in used]
        axis = {"camera_height": camera_height, "board_contact": board_contact}
        seed, ref, one = _seed_and_refine(F[idx], C, obj, pix, intr, setup, method,
                                          refine_intrinsics, robot_noise, robust, axis)
        for j, k in enumerate(used):
            records[k].residuals = ref.residuals[j]
        for j in ref.outliers:
            r = records[used[j]]
            r.status = "outlier"
            r.reason = (f"station inconsistent with the others: corner RMS "
                        f"{ref.station_rms[j]:.2f} px vs median "
                        f"{float(np.median(ref.station_rms)):.2f} px (robot pose or image "
                        "wrong?)")
        if refine_intrinsics:
            intr = CameraIntrinsics(ref.K, ref.dist, intr.size, intr.rms_px,
                                    intr.source + ", refined with X", intr.per_view_rms,
                                    intr.rational)
        _plausibility(ref, records, limits)
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
                     intr: CameraIntrinsics, setup: str, method: str, refine_intrinsics: bool,
                     robot_noise: tuple[float, float] | None, robust: bool,
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
                                   robust=robust, one_axis=one)

    from kinecal.calibration.handeye.scara import detect_one_axis
    from kinecal.spatial import invert_transform

    # one-axis robots (SCARA): Ulrich and Steger's closed form is judged (conditioning)
    # after its pose-level refinement, which is then the seed
    G = F if setup == "eye-in-hand" else invert_transform(F)
    first = "none" if detect_one_axis(G, setup) is None else "lm"
    # the refinement on the pixels judges the outlier stations: the closed form's own
    # flags (a robust pose-level refinement, `robust=True` with refine "none") would be
    # that work twice; its other checks run
    seed = calibrate_handeye(F, C, setup=setup, method=method, refine=first,
                             robust=first == "lm", **axis)
    one = _one_axis(seed, F, setup, axis["camera_height"], axis["board_contact"])
    ref = refine(seed)
    if robust and ref.outliers and first == "none":
        seed = calibrate_handeye(F, C, setup=setup, method=method, refine="lm", **axis)
        ref = refine(seed)
    return seed, ref, one


def _detect_all(images: Sequence[Any], names: Sequence[str], board: Board,
                limits: QualityLimits, progress: Callable[..., None] | None,
                expected: tuple[int, int] | None = None,
                pose_of: Callable[[ImageRecord], None] | None = None
                ) -> tuple[list[ImageRecord], tuple[int, int] | None]:
    """Detect the board in every readable image; the session's image size is the size of
    most images (ties: the first image's), or `expected` (the intrinsics' size) when images
    have it, so one odd image, first or not, is the one rejected."""
    def one(item: tuple[str, Any]) -> tuple[ImageRecord, tuple[int, int] | None]:
        name, im = item
        try:
            gray = load_gray(im) if isinstance(im, str | Path) else np.asarray(im)
        except InputError as exc:  # too large to decode: rejected from its header
            return ImageRecord(str(name), "rejected", exc.message), None
        if gray is None or gray.size == 0:
            return ImageRecord(str(name), "rejected", "cannot read the image file"), None
        h, w = gray.shape[:2]
        det = detect(gray, board, limits)
        record = ImageRecord(str(name), "used" if det.ok else "rejected", det.reason, det)
        if pose_of is not None and det.ok:
            pose_of(record)
        return record, (w, h)

    records: list[ImageRecord] = []
    sizes: list[tuple[int, int] | None] = []
    # images in parallel: OpenCV's detectors, blurs and numpy's large-array work release
    # the GIL; results come back in input order
    workers = min(len(images), _cpu_count())
    with ThreadPoolExecutor(max_workers=max(workers, 1)) as pool:
        done = pool.map(one, zip(names, images, strict=True)) if workers > 1 else \
            map(one, zip(names, images, strict=True))
        for record, size in done:
            records.append(record)
            sizes.append(size)
            if progress is not None:
                progress()
    seen = [z for z in sizes if z is not None]
    if not seen:
        return records, None
    if expected is not None and tuple(expected) in seen:
        size = tuple(expected)
    else:
        size = max(dict.fromkeys(seen), key=seen.count)  # most frequent, first on ties
    for r, z in zip(records, sizes, strict=True):
        if z is not None and z != size:
            r.status, r.detection, r.pose = "rejected", None, None
            r.reason = (f"image size {z[0]}x{z[1]} differs from the other images' "
                        f"{size[0]}x{size[1]}")
    return records, size  # type: ignore[return-value]


def _cpu_count() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def _intrinsics(records: list[ImageRecord], board: Board, size: tuple[int, int] | None,
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
        raise InputError(_too_few(records) + "; estimating the intrinsics needs at least 3 "
                         "(or pass --intrinsics)")
    intr = estimate_intrinsics([r.detection.object_points(board) for r in ok],
                               [r.detection.corners for r in ok], size)
    if intr.rms_px is not None and intr.rms_px > 1.0:
        diagnostics.warn("intrinsics-rms",
                         f"the camera calibration from the images leaves {intr.rms_px:.2f} px "
                         "RMS: blur, a wrong board size or too few views; pass --intrinsics "
                         "from a dedicated calibration")
    return intr


def _poses(records: list[ImageRecord], board: Board, intr: CameraIntrinsics,
           limits: QualityLimits) -> None:
    ok = [r for r in records if r.status == "used"]
    for r in ok:
        if r.pose is None:  # not yet taken in the detection worker
            _pose_of(r, board, intr, limits)
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


def _pose_of(r: ImageRecord, board: Board, intr: CameraIntrinsics,
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


def _warn_symmetric(board: Board) -> None:
    turns = sorted({round(float(np.degrees(np.arctan2(T[1, 0], T[0, 0]))) % 360)
                    for T, _ in board.symmetries()})
    what = " and ".join(f"{a} deg" for a in turns)
    advice = ("use a board with one even and one odd count, or ChArUco"
              if board.kind == "chessboard" else
              "use a modcircles board (its origin dot fixes the frame), acircles or ChArUco")
    diagnostics.warn("board-symmetric",
                     f"{board.spec} looks the same turned by {what}: its frame can turn "
                     f"between images and is then put back from the robot poses; {advice}")


def _turn_flipped(records: list[ImageRecord], used: list[int], board: Board, F: Array,
                  C: Array, setup: str, method: str) -> int:
    """Symmetric boards: put back the stations whose corners were listed turned (board
    frame turned by one of `Board.symmetries`, e.g. 180 deg about the board centre), judged
    by the pose the robot and a robust solution (RANSAC start: tolerates about half the
    stations turned) predict. Returns how many were turned."""
    from kinecal.calibration.handeye import robust_solve
    from kinecal.spatial import invert_transform, rotation_angle

    G = F if setup == "eye-in-hand" else invert_transform(F)
    try:
        X, Y = robust_solve(G, C, method)
    except InputError:  # degenerate motions: calibrate_handeye reports them next
        return 0
    pred = invert_transform(X) @ invert_transform(G) @ Y  # target2cam
    sym = board.symmetries()
    step = min(rotation_angle(T[:3, :3]) for T, _ in sym)  # smallest turn (pi or pi / 2)
    turned = 0
    for j, k in enumerate(used):
        r = records[k]
        T = r.pose.target2cam
        errs = [rotation_angle(pred[j, :3, :3].T @ (T @ invert_transform(turn))[:3, :3])
                for turn, _ in sym]
        best = int(np.argmin(errs))
        e0 = rotation_angle(pred[j, :3, :3].T @ T[:3, :3])
        if e0 > step / 2 and errs[best] < step / 4:
            turn, perm = sym[best]
            fixed = np.empty_like(r.detection.corners)
            fixed[perm] = r.detection.corners
            r.detection.corners = fixed
            r.pose.target2cam = T @ invert_transform(turn)
            res = np.empty_like(r.pose.residuals)
            res[perm] = r.pose.residuals
            r.pose.residuals = res
            turned += 1
    if turned:
        diagnostics.warn("board-turned",
                         f"{turned} image(s) of the symmetric board {board.spec} were listed "
                         "turned; their frame was turned back to agree with the robot poses "
                         "(use an asymmetric board to avoid the guess)")
    return turned


def _too_few(records: list[ImageRecord]) -> str:
    used = sum(r.status == "used" for r in records)
    reasons: dict[str, int] = {}
    example: dict[str, ImageRecord] = {}
    for r in records:
        if r.status == "rejected":
            key = r.reason.split(":")[0].split(";")[0].split("(")[0].strip()
            reasons[key] = reasons.get(key, 0) + 1
            example.setdefault(key, r)
    ranked = sorted(reasons.items(), key=lambda kv: -kv[1])
    summary = ", ".join(f"{k}: {v}" for k, v in ranked)
    first = example[ranked[0][0]] if ranked else None
    return (f"{used} usable image(s) of {len(records)}: hand-eye calibration needs at least 3"
            + (f" (rejected: {summary}; e.g. {first.name}: {first.reason})" if first else ""))


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
