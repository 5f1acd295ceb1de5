"""Rendered stations of a perturbed arm with a camera: plan a set-up before building it.

`render_arm_stations` draws a true arm (the nominal model plus random or given parameter
errors), a camera on its flange looking at a fixed board (eye-in-hand) or a fixed camera
looking at a board on its flange (eye-to-hand), and renders the board at stations the true
arm reaches: board views are planned around the board (`kinecal.vision.render.plan_views`:
distance, tilt, roll), the flange pose of each follows from X and the board pose, and the
true arm's inverse kinematics (`kinecal.kinematics.serial.ik.solve_ik`, seeded at the home
configuration) gives the joint readings; views the arm cannot reach (or only near a
singularity) are drawn again. At the home configuration the camera looks straight at the
board's centre from the distance at which the board fills `fill` of the image width.

`write_arm_scene` writes what ``kinecal calibrate MODEL STATIONS.csv --images DIR --board
SPEC`` reads: ``images/*.png``, ``stations.csv`` (``image,q1..qn`` in the model's units),
``camera.yaml`` and ``truth.json`` (the true parameter errors in `read_truth`'s format, X,
the board pose).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import check_camera
from kinecal.calibration.serial.simulate import random_errors
from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import invert_transform, matrix_from_axis_angle, transform_from
from kinecal.vision.boards import Board
from kinecal.vision.imaging import ImageConditions, render_board
from kinecal.vision.render import plan_views

Array = NDArray[np.float64]

__all__ = ["ArmScene", "render_arm_stations", "scene_errors", "write_arm_scene", "write_images",
           "write_scene_truth", "write_stations"]


@dataclass
class ArmScene:
    """Rendered stations of a true arm, with the truth.

    Attributes
    ----------
    model : SerialModel
        The nominal arm.
    true_params : ndarray, shape (n_params,)
        The true arm's parameters (length unit, rad).
    board : Board
    K : ndarray, shape (3, 3)
    dist : ndarray, shape (8,)
    size : (int, int)
    setup : str
    X, target : ndarray, shape (4, 4)
        True camera mount (``cam2flange`` / ``cam2base``) and board pose (``target2base``
        / ``target2flange``).
    q : ndarray, shape (n, n_joints)
        Joint readings of the stations (rad; what the true arm reads there).
    target2cam : ndarray, shape (n, 4, 4)
        True board pose in every image.
    images : list of ndarray
        8-bit grey images.
    names : list of str
    q_home : ndarray, shape (n_joints,)
    """

    model: SerialModel
    true_params: Array
    board: Board
    K: Array
    dist: Array
    size: tuple[int, int]
    setup: str
    X: Array
    target: Array
    q: Array
    target2cam: Array
    images: list = field(default_factory=list)
    names: list = field(default_factory=list)
    q_home: Array | None = None


def scene_errors(model: SerialModel, errors: Any, rng: np.random.Generator) -> Array:
    """The true parameters' errors of a rendered scene: ``zero``, ``random`` (within the
    tolerances), a mapping of names to values, or a whole vector ``(n_params,)``."""
    if isinstance(errors, str):
        if errors == "zero":
            return np.zeros(model.n_params)
        if errors == "random":
            return random_errors(model, rng)
        raise InputError(f"errors: expected zero, random or a vector, got {errors!r}",
                         option="--errors")
    if isinstance(errors, dict):
        e = np.zeros(model.n_params)
        e[model.index(list(errors))] = list(errors.values())
        return e
    e = np.asarray(errors, float)
    if e.shape != (model.n_params,):
        raise InputError(f"errors: expected {model.n_params} values, got {e.shape}")
    return e


def _mounts(setup: str, F_home: Array, board: Board, d0: float, X: Array | None,
            target: Array | None) -> tuple[Array, Array]:
    """Default X and board pose: at home the camera looks at the board's centre from d0."""
    x0, y0, x1, y1 = board.extent()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    C0 = transform_from(np.eye(3), np.array([0.0, 0.0, d0]) - centre)  # target2cam at home
    if setup == "eye-in-hand":
        X = X if X is not None else transform_from(
            matrix_from_axis_angle([0.02, -0.03, np.pi / 2]), [70.0, -20.0, 60.0])
        target = target if target is not None else F_home @ X @ C0
    else:
        if target is None:
            R = matrix_from_axis_angle([0.0, np.pi, 0.2])
            target = transform_from(R, np.array([0.0, 0.0, 80.0]) - R @ centre)
        X = X if X is not None else F_home @ target @ invert_transform(C0)
    return np.asarray(X, float), np.asarray(target, float)


def render_arm_stations(
    model: SerialModel,
    board: Board,
    K: Array,
    dist: Array | None,
    size: tuple[int, int],
    n: int,
    *,
    setup: str = "eye-in-hand",
    errors: str | Array | dict = "random",
    q_home: Array | None = None,
    X: Array | None = None,
    target: Array | None = None,
    conditions: ImageConditions | None = None,
    seed: int = 0,
    supersample: int = 3,
    view_options: dict[str, Any] | None = None,
    render: bool = True,
) -> ArmScene:
    """Render `n` stations of a perturbed arm seeing a board (module docstring).

    Parameters
    ----------
    model : SerialModel
        Nominal arm; its length unit is the board's.
    board : Board
    K, dist, size
        The camera (`kinecal.vision.imaging.render_board`).
    n : int
        Stations.
    setup : {"eye-in-hand", "eye-to-hand"}
    errors : {"random", "zero"} or ndarray (n_params,) or dict
        The true arm's deviations from nominal (as in `kinecal.calibration.serial.simulate`;
        random: uniform within the model's tolerances on its calibratable parameters).
    q_home : ndarray, shape (n_joints,), optional
        Home configuration (rad): the camera looks at the board's centre there. Default: the
        middle of the joint limits.
    X, target : ndarray, shape (4, 4), optional
        True camera mount and board pose (defaults: see `_mounts`).
    conditions : ImageConditions, optional
        Blur, noise, light (default: ideal images).
    seed : int
        Seed of the errors, views and image noise.
    supersample : int
    view_options : dict, optional
        Passed to `plan_views` (``fill``, ``tilt_deg``, ``roll_deg``, ``distance_spread``).
    render : bool
        Render the images (False: joints and truth only).

    Returns
    -------
    ArmScene

    Raises
    ------
    InputError
        Fewer than `n` views reachable by the arm (change the home configuration, the
        board pose or the view options).
    """
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="--setup")
    if n < 1:
        raise InputError(f"expected at least 1 station, got {n}", option="--poses")
    K, d8 = check_camera(K, dist)
    rng = np.random.default_rng(seed)
    truth = model.nominal + scene_errors(model, errors, rng)
    lim = np.asarray(model.joint_limits, float)
    home = lim.mean(axis=1) if q_home is None else np.asarray(q_home, float)
    if home.shape != (model.n_joints,):
        raise InputError(f"home configuration: expected {model.n_joints} joints, got "
                         f"{home.shape}", option="--home")
    opts = {"fill": 0.55, **(view_options or {})}
    x0, y0, x1, y1 = board.extent()
    d0 = K[0, 0] * max(x1 - x0, y1 - y0) / (opts["fill"] * size[0])
    Xt, Yt = _mounts(setup, model.fk(home, truth)[0], board, d0, X, target)
    q_out, C_out = _reachable(model, truth, board, K, d8, size, n, setup, Xt, Yt, home, rng,
                              opts)
    images = []
    if render:
        base = conditions or ImageConditions()
        images = [render_board(board, K, d8, C, size, base, supersample=supersample, rng=rng)
                  for C in C_out]
    names = [f"station_{i:03d}.png" for i in range(n)]
    return ArmScene(model, truth, board, K, d8, (int(size[0]), int(size[1])), setup, Xt, Yt,
                    q_out, C_out, images, names, home)


def _reachable(model, truth, board, K, d8, size, n, setup, X, Y, home, rng, opts):
    """Joints and board poses of `n` views the true arm reaches (drawn in rounds)."""
    q_out, C_out = [], []
    for _ in range(6):
        need = n - len(q_out)
        if need <= 0:
            break
        C = plan_views(board, K, d8, size, 2 * need + 4, rng, **opts)
        if setup == "eye-in-hand":
            F = Y @ invert_transform(C) @ invert_transform(X)
        else:
            F = X @ C @ invert_transform(Y)
        ik = solve_ik(model, F, np.broadcast_to(home, (len(F), model.n_joints)), params=truth)
        ok = np.flatnonzero(ik.status == "converged")
        for k in ok[:need]:
            q_out.append(ik.q[k])
            C_out.append(C[k])
    if len(q_out) < n:
        raise InputError(f"the arm reaches only {len(q_out)} of {n} planned views: move the "
                         "home configuration (--home) or the board, or lower the tilt")
    return np.array(q_out), np.array(C_out)


def write_arm_scene(scene: ArmScene, folder: str | Path) -> Path:
    """Write `scene` into `folder`: ``images/*.png``, ``stations.csv`` (``image,q1..qn``,
    model units), ``camera.yaml`` and ``truth.json``. Returns the folder."""
    from kinecal.vision.intrinsics import CameraIntrinsics, write_intrinsics

    folder = Path(folder)
    write_images(scene, folder / "images")
    write_stations(scene, folder / "stations.csv")
    write_intrinsics(folder / "camera.yaml",
                     CameraIntrinsics(scene.K, scene.dist, scene.size, source="render"))
    write_scene_truth(scene, folder / "truth.json")
    return folder


def write_images(scene: ArmScene, folder: str | Path) -> None:
    """The images as PNG files named `ArmScene.names` in `folder` (created)."""
    from kinecal._files import write_bytes_atomic
    from kinecal.vision import require_cv2

    cv2 = require_cv2()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, img in zip(scene.names, scene.images, strict=True):
        ok, buf = cv2.imencode(".png", img)
        if not ok:  # pragma: no cover - OpenCV always encodes uint8 PNG
            raise InputError("PNG encoding failed", file=folder / name)
        write_bytes_atomic(folder / name, buf.tobytes())


def write_stations(scene: ArmScene, path: str | Path) -> None:
    """STATIONS.csv: ``image,q1..qn`` (revolute joints in the model's angle unit)."""
    from kinecal._files import write_text_atomic

    m = scene.model
    q = scene.q / m.joint_scale()
    lines = ["image," + ",".join(f"q{i + 1}" for i in range(m.n_joints))]
    lines += [name + "," + ",".join(repr(float(v)) for v in row)
              for name, row in zip(scene.names, q, strict=True)]
    write_text_atomic(path, "\n".join(lines) + "\n")


def write_scene_truth(scene: ArmScene, path: str | Path) -> None:
    """The truth JSON: the arm's true errors and values (`read_truth`'s format, model
    units), the set-up, board, X, board pose, camera and home configuration."""
    from kinecal._files import write_text_atomic

    m = scene.model
    conv = np.where(m.is_angle(), 180.0 / np.pi if m.angle_unit == "deg" else 1.0, 1.0)
    truth = {"model": m.name, "length_unit": m.length_unit, "angle_unit": m.angle_unit,
             "errors": dict(zip(m.parameter_names, ((scene.true_params - m.nominal) * conv)
                                .tolist(), strict=True)),
             "parameters": dict(zip(m.parameter_names, (scene.true_params * conv).tolist(),
                                    strict=True)),
             "setup": scene.setup, "board": scene.board.spec, "X": scene.X.tolist(),
             "target": scene.target.tolist(), "K": scene.K.tolist(),
             "dist": scene.dist.tolist(), "size": list(scene.size),
             "q_home": (np.asarray(scene.q_home) / m.joint_scale()).tolist()}
    write_text_atomic(path, json.dumps(truth, indent=1) + "\n")
