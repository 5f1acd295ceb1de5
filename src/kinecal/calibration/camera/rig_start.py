"""The start of a rig's bundle adjustment, without a user guess.

Every image's board poses come from PnP (``target2cam``). For a camera ``c`` and a board
``b`` seen together, the nominal model gives the pose of the board's link in the camera's
link, ``G_i = L_c(q_i)^-1 L_b(q_i)``, and the images satisfy ``C_i = X_c^-1 G_i Y_b``:
the hand-eye equation ``AX = ZB`` of a fixed camera looking at a board on a flange. Hence:

1. **a closed form per camera-board pair** whose ``G_i`` turn about two axes or more
   (`kinecal.calibration.handeye.calibrate_handeye`, ``eye-to-hand`` on ``G_i``, with its
   robust refinement) gives both mounts; a mount several pairs give is their average
   (rotations by the chordal mean, weighted by the images);
2. a pair whose ``G_i`` do not turn (both on one link, or a static camera looking at a
   static board) is a **relation**: it places one mount once the other is known
   (``X_c = G_i Y_b C_i^-1``), propagated until every mount is placed;
3. a mount still unplaced is an error naming it: no image ties it to the others.

Cameras that never see the same board are tied through the robot: each is placed in its
own link's frame by its own pairs. The bundle adjustment then starts from these mounts
(`kinecal.calibration.camera.rig_block.RigBlock`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.camera.rig_pixels import Mount, RigViews
from kinecal.calibration.diagnostics import CODES
from kinecal.errors import InputError
from kinecal.spatial import (
    axis_angle_from_matrix,
    invert_transform,
    project_to_rotation,
    transform_from,
)

Array = NDArray[np.float64]

__all__ = ["MIN_TURN_DEG", "rig_start"]

#: a pair's link motions must turn by this much about a second axis for its closed form
MIN_TURN_DEG = 2.0


def _link_transforms(poses: dict, link: str, rows: Sequence[int]) -> Array:
    lp = poses[link]
    return np.array([transform_from(lp.R[i], lp.t[i]) for i in rows])


def _turns_two_axes(G: Array) -> bool:
    """Whether the relative rotations of `G` ``(n, 4, 4)`` span two axes or more."""
    R0 = G[0, :3, :3]
    w = np.array([axis_angle_from_matrix(R0.T @ g[:3, :3]) for g in G[1:]])
    if len(w) < 2:
        return False
    s = np.linalg.svd(w - 0.0, compute_uv=False)
    return bool(len(s) >= 2 and np.degrees(s[1]) / np.sqrt(len(w)) > MIN_TURN_DEG / 4
                and np.degrees(np.abs(w).max()) > MIN_TURN_DEG)


def _mean_pose(Ts: Sequence[Array], weights: Sequence[float]) -> Array:
    w = np.asarray(weights, float)
    R = project_to_rotation(sum(wi * T[:3, :3] for wi, T in zip(w, Ts, strict=True)))
    t = sum(wi * T[:3, 3] for wi, T in zip(w, Ts, strict=True)) / w.sum()
    return transform_from(R, t)


def _pairs(views: RigViews) -> dict[tuple[int, int], list[int]]:
    """Images of each (camera, board) pair with a PnP pose."""
    out: dict[tuple[int, int], list[int]] = {}
    for i, seen in enumerate(views.poses or []):
        for b in seen:
            out.setdefault((int(views.camera[i]), int(b)), []).append(i)
    return out


def _closed_form(G: Array, C: Array, method: str) -> tuple[Array, Array] | None:
    from kinecal.calibration.handeye import calibrate_handeye

    try:
        # a pair's conditioning is the start's concern: the bundle adjustment judges the
        # data (its own checks name stations that fit no mount)
        with diagnostics.expect(*CODES):
            res = calibrate_handeye(G, C, setup="eye-to-hand", method=method, refine="lm",
                                    robust=True)
    except InputError:
        return None
    return np.asarray(res.X, float), np.asarray(res.target, float)


def rig_start(frames, views: RigViews, cameras: Sequence[Mount], boards: Sequence[Mount],
              params: Array | None, method: str = "park") -> tuple[list[Array], list[Array]]:
    """Camera mounts ``cam2link`` and board mounts ``board2link`` (module docstring).

    Parameters
    ----------
    frames : LinkFrames or FixedFrames
    views : RigViews
        With PnP board poses per image (`RigViews.poses`).
    cameras, boards : sequence of Mount
    params : ndarray, shape (n_params,), optional
        The model's parameters (default nominal).
    method : str
        Hand-eye closed form.

    Returns
    -------
    X : list of ndarray, shape (4, 4)
    Y : list of ndarray, shape (4, 4)

    Raises
    ------
    InputError
        A camera or board no image ties to the others.
    """
    if views.poses is None:
        raise InputError("the rig's start needs the board pose of every image (PnP)")
    p = params if params is not None or frames.model is None else frames.model.nominal
    poses = frames.poses(p)
    est_x: dict[int, list[tuple[Array, float]]] = {}
    est_y: dict[int, list[tuple[Array, float]]] = {}
    relations = []
    for (c, b), rows in sorted(_pairs(views).items()):
        G = invert_transform(_link_transforms(poses, cameras[c].link, rows)) @ \
            _link_transforms(poses, boards[b].link, rows)
        C = np.array([views.poses[i][b] for i in rows])
        sol = _closed_form(G, C, method) if len(rows) >= 3 and _turns_two_axes(G) else None
        if sol is None:
            relations.append((c, b, G, C))
            continue
        est_x.setdefault(c, []).append((sol[0], len(rows)))
        est_y.setdefault(b, []).append((sol[1], len(rows)))
    X = {c: _mean_pose([e[0] for e in v], [e[1] for e in v]) for c, v in est_x.items()}
    Y = {b: _mean_pose([e[0] for e in v], [e[1] for e in v]) for b, v in est_y.items()}
    _propagate(X, Y, relations)
    missing = [f"camera {cameras[c].name}" for c in range(len(cameras)) if c not in X] + \
        [f"board {boards[b].name}" for b in range(len(boards)) if b not in Y]
    if missing:
        raise InputError(f"{', '.join(missing)}: no image ties it to the rest of the rig (a "
                         "camera must see a board whose link moves relative to its own, or a "
                         "board whose mount the others place; a board must be seen by such a "
                         "camera)")
    return [X[c] for c in range(len(cameras))], [Y[b] for b in range(len(boards))]


def _propagate(X: dict, Y: dict, relations: list) -> None:
    """Place the mounts of the relations ``C_i = X_c^-1 G_i Y_b`` from the known ones."""
    changed = True
    while changed:
        changed = False
        for c, b, G, C in relations:
            if c in X and b not in Y:
                Y[b] = _mean_pose([invert_transform(g) @ X[c] @ ci for g, ci in
                                   zip(G, C, strict=True)], np.ones(len(G)))
                changed = True
            elif b in Y and c not in X:
                X[c] = _mean_pose([g @ Y[b] @ invert_transform(ci) for g, ci in
                                   zip(G, C, strict=True)], np.ones(len(G)))
                changed = True
