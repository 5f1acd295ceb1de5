"""Synthetic images of a calibration board seen by a known camera at known poses.

Used by the tests and docs, and by users to plan a set-up before building it: which board,
camera distance and tilts give enough stations, and what accuracy of X to expect (render a
scene with `render_handeye_scene`, write it with `write_scene`, run ``kinecal
handeye-images`` on the folder and compare with ``truth.json``).

Images are formed by `kinecal.vision.imaging` (`render_board`, `ImageConditions`,
`undistort_normalized`; re-exported here); this module places the camera and the robot:
view planning (`look_at`, `plan_views`) and whole hand-eye scenes with their truth.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import check_camera, project
from kinecal.errors import InputError
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    pq_from_transform,
    transform_from,
)
from kinecal.vision import require_cv2
from kinecal.vision.boards import Board
from kinecal.vision.imaging import ImageConditions, render_board, undistort_normalized

Array = NDArray[np.float64]

__all__ = [
    "HandEyeScene",
    "ImageConditions",
    "look_at",
    "plan_views",
    "render_board",
    "render_handeye_scene",
    "undistort_normalized",
    "write_scene",
]


def look_at(eye: Array, target: Array, roll: float = 0.0) -> Array:
    """``cam2world`` ``(4, 4)`` of a camera at `eye` whose z axis points at `target`, turned
    by `roll` (rad) about it (x axis horizontal-ish before the roll)."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.column_stack([x, y, z]) @ matrix_from_axis_angle(np.array([0.0, 0.0, roll]))
    return transform_from(R, np.asarray(eye, float))


def plan_views(
    board: Board,
    K: Array,
    dist: Array | None,
    size: tuple[int, int],
    n: int,
    rng: int | np.random.Generator | None = None,
    *,
    fill: float = 0.55,
    tilt_deg: float = 35.0,
    roll_deg: float = 180.0,
    distance_spread: float = 0.25,
    margin_px: float = 12.0,
    max_tries: int = 200,
) -> Array:
    """`n` board poses ``target2cam`` ``(n, 4, 4)`` with the whole board in view.

    The camera looks at a random point of the board from a distance at which the board
    spans about `fill` of the image width, along a direction tilted from the board normal by
    up to `tilt_deg` (uniform on the spherical cap), with a roll uniform in
    ``+-roll_deg``; views whose corners come closer than `margin_px` to the image border are
    drawn again.
    """
    K, d8 = check_camera(K, dist)
    rng = np.random.default_rng(rng)
    x0, y0, x1, y1 = board.extent()
    span = max(x1 - x0, y1 - y0)
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    d0 = K[0, 0] * span / (fill * size[0])
    out = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > max_tries * n:
            raise InputError(f"could not place {n} views with the board fully in the "
                             f"{size[0]}x{size[1]} image; lower fill or tilt")
        cos_max = np.cos(np.radians(tilt_deg))
        c = rng.uniform(cos_max, 1.0)
        phi = rng.uniform(0, 2 * np.pi)
        s = np.sqrt(1 - c * c)
        # the camera on the printed side (-z for OpenCV's boards: board z points away)
        direction = np.array([s * np.cos(phi), s * np.sin(phi), -board.faces * c])
        dist_ = d0 * (1.0 + distance_spread * rng.uniform(-1, 1))
        aim = centre + np.array([rng.uniform(-0.15, 0.15) * (x1 - x0),
                                 rng.uniform(-0.15, 0.15) * (y1 - y0), 0.0])
        cam2target = look_at(aim + dist_ * direction, aim,
                             np.radians(rng.uniform(-roll_deg, roll_deg)))
        T = invert_transform(cam2target)
        P = board.object_points @ T[:3, :3].T + T[:3, 3]
        if np.any(P[:, 2] <= 0):
            continue
        uv = project(K, d8, P)
        if (np.all(np.isfinite(uv)) and uv[:, 0].min() > margin_px and uv[:, 1].min() > margin_px
                and uv[:, 0].max() < size[0] - 1 - margin_px
                and uv[:, 1].max() < size[1] - 1 - margin_px):
            out.append(T)
    return np.array(out)


@dataclass
class HandEyeScene:
    """A rendered hand-eye data set with its truth.

    Attributes
    ----------
    board : Board
    K : ndarray, shape (3, 3)
    dist : ndarray, shape (8,)
    size : (int, int)
        Image width, height.
    setup : str
        ``eye-in-hand`` or ``eye-to-hand``.
    X : ndarray, shape (4, 4)
        True ``cam2flange`` (eye-in-hand) or ``cam2base`` (eye-to-hand).
    target : ndarray, shape (4, 4)
        True ``target2base`` (eye-in-hand) or ``target2flange`` (eye-to-hand).
    flange2base : ndarray, shape (n, 4, 4)
        Robot poses as reported (with the robot noise, if any).
    flange2base_true : ndarray, shape (n, 4, 4)
    target2cam : ndarray, shape (n, 4, 4)
        True board poses in the camera.
    images : list of ndarray
        8-bit grey images.
    names : list of str
        File names used by `write_scene`.
    conditions : list of ImageConditions
    """

    board: Board
    K: Array
    dist: Array
    size: tuple[int, int]
    setup: str
    X: Array
    target: Array
    flange2base: Array
    flange2base_true: Array
    target2cam: Array
    images: list = field(default_factory=list)
    names: list = field(default_factory=list)
    conditions: list = field(default_factory=list)


def render_handeye_scene(
    board: Board,
    K: Array,
    dist: Array | None,
    size: tuple[int, int],
    n: int,
    *,
    setup: str = "eye-in-hand",
    X: Array | None = None,
    target: Array | None = None,
    conditions: ImageConditions | None = None,
    robot_noise: tuple[float, float] = (0.0, 0.0),
    vary_light: float = 0.0,
    seed: int = 0,
    supersample: int = 3,
    view_options: dict[str, Any] | None = None,
    flange2base: Array | None = None,
) -> HandEyeScene:
    """Render `n` stations of a hand-eye set-up with known X and board pose.

    Parameters
    ----------
    board : Board
    K, dist, size
        The camera (see `render_board`).
    n : int
        Stations.
    setup : {"eye-in-hand", "eye-to-hand"}
    X, target : ndarray, shape (4, 4), optional
        The truth; defaults: a camera 60-90 mm off the flange looking along the flange z
        axis (eye-in-hand) or 1.2 m from the robot base (eye-to-hand), a board on a table
        (eye-in-hand) or held 80 mm in front of the flange (eye-to-hand).
    conditions : ImageConditions, optional
        Imaging conditions of every image (blur, noise, light).
    robot_noise : (float, float)
        Std of the reported robot poses' error: rotation (rad per axis) and translation
        (length unit per axis), applied in the flange frame.
    vary_light : float
        Relative random change of gain and gradient per image (0.2 = +-20 %).
    seed : int
        Seed of the views, the robot noise and the image noise.
    supersample : int
        See `render_board`.
    view_options : dict, optional
        Passed to `plan_views` (``fill``, ``tilt_deg``, ``roll_deg``, ...).
    flange2base : ndarray, shape (n, 4, 4), optional
        The robot's true flange poses instead of planned views (e.g. a SCARA's, whose
        rotations turn about one axis); the board must be in view from each (X and `target`
        given).

    Returns
    -------
    HandEyeScene
    """
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="setup")
    K, d8 = check_camera(K, dist)
    rng = np.random.default_rng(seed)
    if flange2base is not None:
        F = np.asarray(flange2base, dtype=float)
        if X is None or target is None or F.shape != (n, 4, 4):
            raise InputError(f"flange2base: expected {n} poses (n, 4, 4) with X and target "
                             "given", option="flange2base")
        C = _views_of(board, K, d8, size, F, X, target, setup)
        return _render(board, K, d8, size, setup, X, target, F, C, conditions, robot_noise,
                       vary_light, rng, supersample)
    C = plan_views(board, K, d8, size, n, rng, **(view_options or {}))  # target2cam
    if setup == "eye-in-hand":
        X = X if X is not None else transform_from(
            matrix_from_axis_angle([0.02, -0.03, np.pi / 2]), [70.0, -20.0, 60.0])
        target = target if target is not None else transform_from(
            matrix_from_axis_angle([np.pi, 0.0, 0.3]), [650.0, -100.0, 50.0])
        F = target @ invert_transform(C) @ invert_transform(X)  # flange2base
    else:
        X = X if X is not None else look_at([1200.0, 300.0, 900.0], [500.0, 0.0, 300.0], 0.4)
        target = target if target is not None else transform_from(
            matrix_from_axis_angle([0.0, np.pi, 0.2]), [10.0, -15.0, 80.0])
        F = X @ C @ invert_transform(target)
    return _render(board, K, d8, size, setup, X, target, F, C, conditions, robot_noise,
                   vary_light, rng, supersample)


def _views_of(board: Board, K: Array, d8: Array, size: tuple[int, int], F: Array, X: Array,
              target: Array, setup: str) -> Array:
    """``target2cam`` of given flange poses; `InputError` when a view misses the board."""
    if setup == "eye-in-hand":
        C = invert_transform(X) @ invert_transform(F) @ target
    else:
        C = invert_transform(X) @ F @ target
    for i, T in enumerate(C):
        P = board.object_points @ T[:3, :3].T + T[:3, 3]
        uv = project(K, d8, P) if np.all(P[:, 2] > 0) else np.full((1, 2), -1.0)
        if not (np.all(np.isfinite(uv)) and uv.min() >= 0 and uv[:, 0].max() <= size[0] - 1
                and uv[:, 1].max() <= size[1] - 1):
            raise InputError(f"flange pose {i}: the board is not wholly in view",
                             option="flange2base")
    return C


def _render(board: Board, K: Array, d8: Array, size: tuple[int, int], setup: str, X: Array,
            target: Array, F: Array, C: Array, conditions: ImageConditions | None,
            robot_noise: tuple[float, float], vary_light: float, rng: np.random.Generator,
            supersample: int) -> HandEyeScene:
    """Images of the views C with the reported (noisy) robot poses."""
    n = len(C)
    F_rep = F
    if robot_noise[0] > 0 or robot_noise[1] > 0:
        E = transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * robot_noise[0]),
                           rng.normal(size=(n, 3)) * robot_noise[1])
        F_rep = F @ E
    base = conditions or ImageConditions()
    images, conds = [], []
    for i in range(n):
        cond = base
        if vary_light:
            g = base.gain * (1.0 + vary_light * rng.uniform(-1, 1))
            grad = (base.gradient[0] + vary_light * rng.uniform(-1, 1),
                    base.gradient[1] + vary_light * rng.uniform(-1, 1))
            cond = ImageConditions(**{**base.__dict__, "gain": g, "gradient": grad})
        images.append(render_board(board, K, d8, C[i], size, cond, supersample=supersample,
                                   rng=rng))
        conds.append(cond)
    names = [f"station_{i:03d}.png" for i in range(n)]
    return HandEyeScene(board, K, d8, (int(size[0]), int(size[1])), setup, X, target, F_rep, F,
                        C, images, names, conds)


def write_scene(scene: HandEyeScene, folder: str | Path) -> Path:
    """Write a scene: ``images/*.png``, ``robot_poses.csv`` (the ``kinecal handeye-images``
    input), ``camera.yaml`` (ROS camera_calibration format) and ``truth.json``.

    Returns
    -------
    Path
        The folder.
    """
    cv2 = require_cv2()
    from kinecal._files import write_bytes_atomic, write_text_atomic
    from kinecal.vision.intrinsics import CameraIntrinsics, write_intrinsics

    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    for name, img in zip(scene.names, scene.images, strict=True):
        ok, buf = cv2.imencode(".png", img)
        if not ok:  # pragma: no cover - OpenCV always encodes uint8 PNG
            raise InputError("PNG encoding failed", file=folder / "images" / name)
        write_bytes_atomic(folder / "images" / name, buf.tobytes())
    pq = pq_from_transform(scene.flange2base)
    lines = ["image,flange_x,flange_y,flange_z,flange_qw,flange_qx,flange_qy,flange_qz"]
    lines += [name + "," + ",".join(repr(float(v)) for v in row)
              for name, row in zip(scene.names, pq, strict=True)]
    write_text_atomic(folder / "robot_poses.csv", "\n".join(lines) + "\n")
    write_intrinsics(folder / "camera.yaml",
                     CameraIntrinsics(scene.K, scene.dist, scene.size, source="render"))
    truth = {"setup": scene.setup, "board": scene.board.spec, "X": scene.X.tolist(),
             "target": scene.target.tolist(), "K": scene.K.tolist(),
             "dist": scene.dist.tolist(), "size": list(scene.size),
             "target2cam": scene.target2cam.tolist(),
             "flange2base_true": scene.flange2base_true.tolist(),
             "conditions": [c.to_dict() for c in scene.conditions]}
    write_text_atomic(folder / "truth.json", json.dumps(truth, indent=1) + "\n")
    return folder
