"""From a rig's images and joint readings to a calibrated model and rig: what ``kinecal
calibrate MODEL STATIONS.csv --images DIR --camera NAME:LINK ... --board NAME:LINK:SPEC
...`` runs.

1. every image is searched for the boards it may show (the one its ``board`` column names,
   else every board of the rig: ChArUco boards with disjoint marker ids are told apart);
   an image where none is found or trusted is skipped with its reason (warning
   ``station-skipped``);
2. each camera's intrinsics from its file, or estimated from its own images (then refined
   with the rest);
3. the pose of every board found (PnP), for the start;
4. one bundle adjustment of the model, every mount and the free intrinsics on the corner
   pixels (`kinecal.calibration.camera.rig_solve.calibrate_rig`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.camera.rig_frames import LinkFrames
from kinecal.calibration.camera.rig_pixels import RigPixels, RigViews
from kinecal.calibration.camera.rig_result import RigResult
from kinecal.calibration.camera.rig_solve import add_validation, calibrate_rig
from kinecal.errors import InputError
from kinecal.spatial import invert_transform, transform_from
from kinecal.vision.detect import QualityLimits
from kinecal.vision.detection import orientation_ambiguous
from kinecal.vision.intrinsics import CameraIntrinsics
from kinecal.vision.rig import Rig
from kinecal.vision.stages import board_poses, camera_intrinsics, detect_all
from kinecal.vision.turns import align_turns, turn_flipped, warn_symmetric

Array = NDArray[np.float64]

__all__ = ["calibrate_rig_images", "complete_joints", "detect_rig", "searched_boards"]


def searched_boards(rig: Rig, camera: NDArray[np.intp], boards: Sequence[str | None]
              ) -> list[list[int]]:
    """The boards each image is searched for: its named board, else every board when they
    can be told apart (ChArUco boards of their own marker ids), else the one board not on
    its camera's link."""
    names = rig.board_names
    out = []
    for i, b in enumerate(boards):
        if b:
            out.append([names.index(b)])
            continue
        link = rig.cameras[camera[i]].link
        cand = list(range(len(names))) if rig.told_apart() else \
            [k for k, rb in enumerate(rig.boards) if rb.link != link] or list(range(len(names)))
        if len(cand) > 1 and not rig.told_apart():
            raise InputError(f"image {i + 1}: several boards ({', '.join(names[k] for k in cand)})"
                             " could show in it and not all are ChArUco boards with their own "
                             "marker ids: name its board in the STATIONS.csv board column",
                             option="--board")
        out.append(cand)
    return out


def complete_joints(model, rig: Rig, camera: NDArray[np.intp], boards: Sequence[str | None],
                    q: Array, names: Sequence[str]) -> Array:
    """`q` with a system's blank readings (NaN) of the joints an image needs neither for
    its camera nor for its boards set inside their limits; `InputError` naming the image
    and joint when one it needs is blank."""
    q = np.array(q, dtype=float)
    if not np.isnan(q).any():
        return q
    from kinecal.calibration.camera.rig_frames import WORLD

    cams, brds = rig.mounts(model)
    search = searched_boards(rig, np.asarray(camera, np.intp), boards)
    lim = np.asarray(model.joint_limits, float)
    mid = np.clip(0.0, lim[:, 0], lim[:, 1])
    for i in range(len(q)):
        links = [cams[camera[i]].link] + [brds[b].link for b in search[i]]
        need = np.unique(np.concatenate([model.link_joints(ln) for ln in links
                                         if ln != WORLD] or [np.zeros(0, np.intp)]))
        blank = [int(j) for j in need if np.isnan(q[i, j])]
        if blank:
            raise InputError(f"image {names[i]}: joint {model.joint_names[blank[0]]} is blank "
                             "but moves its camera or board")
        q[i] = np.where(np.isnan(q[i]), mid, q[i])
    return q


def detect_rig(rig: Rig, images: Sequence[Any], names: Sequence[str],
               camera: NDArray[np.intp], q: Array, boards: Sequence[str | None],
               limits: QualityLimits | None = None,
               intrinsics: Sequence[CameraIntrinsics | None] | None = None,
               progress: Callable[..., None] | None = None, poses: bool = True,
               relative: Callable[[int, int, list[int]], Array] | None = None
               ) -> tuple[RigViews, list[CameraIntrinsics], list[dict[str, str]]]:
    """Detected images of a rig, each camera's intrinsics and the skipped images.

    Parameters
    ----------
    rig : Rig
    images : sequence of path or ndarray
    names : sequence of str
    camera : ndarray of int, shape (n,)
        Camera of every image (index into ``rig.cameras``).
    q : ndarray, shape (n, n_joints)
        Joint readings (rad).
    boards : sequence of str or None
        The board each image shows (None: search every board).
    limits : QualityLimits, optional
    intrinsics : sequence, optional
        Per camera: the intrinsics to use (default: its file, else estimated).
    poses : bool
        Compute each found board's pose (PnP; rejects too oblique views).
    relative : callable, optional
        ``relative(camera, board, images)`` -> the board's link in the camera's link
        ``(n, 4, 4)`` at those images (the nominal model): a board that looks the same
        turned (`kinecal.vision.turns`) is then put back where the images' corners were
        listed turned.

    Returns
    -------
    views : RigViews
        The images with at least one board found.
    intrinsics : list of CameraIntrinsics
    skipped : list of dict
        ``{"image", "reason"}``.
    """
    limits = limits or QualityLimits()
    camera = np.asarray(camera, dtype=np.intp)
    search = searched_boards(rig, camera, boards)
    n, nb = len(names), len(rig.boards)
    found: list[dict[int, Any]] = [{} for _ in range(n)]
    reasons: list[list[str]] = [[] for _ in range(n)]
    given = list(intrinsics) if intrinsics is not None else \
        [c.intrinsics for c in rig.cameras]
    intr_out: list[CameraIntrinsics | None] = [None] * len(rig.cameras)
    per_cam, groups = {}, {}
    for c in range(len(rig.cameras)):
        for b in range(nb):
            rows = [i for i in range(n) if camera[i] == c and b in search[i]]
            if not rows:
                continue
            g = given[c]
            expected = None if g is None or not g.size else tuple(g.size)
            recs, size = detect_all([images[i] for i in rows], [names[i] for i in rows],
                                    rig.boards[b].board, limits, progress, expected)
            per_cam.setdefault(c, []).append((b, rows, recs, size))
    for c, items in per_cam.items():
        b, _, recs, size = max(items, key=lambda it: sum(r.status == "used" for r in it[2]))
        intr_out[c] = camera_intrinsics(recs, rig.boards[b].board, size, given[c])
        for b, rows, recs, _ in items:
            if poses:
                board_poses(recs, rig.boards[b].board, intr_out[c], limits)
                group = _turn_back(recs, rows, rig.boards[b].board, c, b, relative)
                if group is not None:
                    groups.setdefault(b, []).append(group)
            for i, r in zip(rows, recs, strict=True):
                if r.status == "used":
                    found[i][b] = r
                else:
                    reasons[i].append(f"{rig.boards[b].name}: {r.reason}")
    for b, per_camera in groups.items():  # one frame per board over its cameras
        align_turns(per_camera, rig.boards[b].board)
    used = [i for i in range(n) if found[i]]
    skipped = [{"image": names[i], "reason": "; ".join(reasons[i]) or "no board searched"}
               for i in range(n) if not found[i]]
    pts, pix, brd, pp = [], [], [], []
    for i in used:
        keys = sorted(found[i])
        pts.append(np.vstack([found[i][b].detection.object_points(rig.boards[b].board)
                              for b in keys]))
        pix.append(np.vstack([found[i][b].detection.corners for b in keys]))
        brd.append(np.concatenate([np.full(len(found[i][b].detection.corners), b, np.intp)
                                   for b in keys]))
        pp.append({b: found[i][b].pose.target2cam for b in keys} if poses else {})
    views = RigViews([names[i] for i in used], camera[used], np.asarray(q, float)[used], pts,
                     pix, brd, pp if poses else None)
    return views, intr_out, skipped


def _turn_back(recs: list, rows: list[int], board, c: int, b: int,
               relative: Callable[[int, int, list[int]], Array] | None) -> tuple | None:
    """Images of a symmetric board listed turned, put back from the model's motions (one
    camera-board pair: ``C = X^-1 G Y``, `kinecal.vision.turns.turn_flipped` on ``G``);
    the pair's ``(records, used, G)`` for `kinecal.vision.turns.align_turns`."""
    if relative is None or not orientation_ambiguous(board):
        return None
    used = [k for k, r in enumerate(recs) if r.status == "used" and r.pose is not None]
    if len(used) < 3:
        return None
    G = relative(c, b, [rows[k] for k in used])
    C = np.array([recs[k].pose.target2cam for k in used])
    turn_flipped(recs, used, board, G, C, "eye-to-hand")
    return recs, used, G


def calibrate_rig_images(model, rig: Rig, images: Sequence[Any], names: Sequence[str],
                         camera: NDArray[np.intp], q: Array, boards: Sequence[str | None], *,
                         free: str | Sequence[str] = "identifiable", loss: str = "linear",
                         rational: bool = False,
                         validate: tuple | None = None, limits: QualityLimits | None = None,
                         progress: Callable[..., None] | None = None, others: Sequence = (),
                         sigma: Sequence[float | None] | None = None) -> RigResult:
    """Calibrate a model and its rig from images (module docstring).

    Parameters
    ----------
    model : SerialModel or SystemModel
    rig : Rig
    images, names, camera, q, boards
        One entry per image (see `detect_rig`).
    free, loss
        As `kinecal.calibrate`.
    rational : bool
        12 intrinsics where estimated.
    validate : (images, names, camera, q, boards), optional
        Held-out images of any camera.
    limits, progress
        Detection limits and a progress callback.
    others, sigma
        Further measurement sets (tracker, gauges) and their stated noise: one problem
        (`kinecal.calibration.camera.rig_solve.calibrate_rig`).
    """
    cams, brds = rig.mounts(model)

    def relative(c: int, b: int, rows: list[int]) -> Array:
        links = [cams[c].link, brds[b].link]
        lp = LinkFrames(model, np.asarray(q, float)[rows], links).poses(model.nominal)
        Lc = [transform_from(R, t) for R, t in zip(lp[links[0]].R, lp[links[0]].t, strict=True)]
        Lb = [transform_from(R, t) for R, t in zip(lp[links[1]].R, lp[links[1]].t, strict=True)]
        return invert_transform(np.array(Lc)) @ np.array(Lb)

    with diagnostics.collect() as found:
        for rb in rig.boards:
            if orientation_ambiguous(rb.board):
                warn_symmetric(rb.board)
        views, intr, skipped = detect_rig(rig, images, names, camera, q, boards, limits,
                                          progress=progress, relative=relative)
        if len(views.q) < 3:
            eg = f"; e.g. {skipped[0]['image']}: {skipped[0]['reason']}" if skipped else ""
            raise InputError(f"{len(views.q)} usable image(s) of {len(names)}: the boards were "
                             f"not found or not trusted in the others{eg}")
        if skipped:
            diagnostics.warn("station-skipped",
                             f"{len(skipped)} of {len(names)} images skipped (e.g. "
                             f"{skipped[0]['image']}: {skipped[0]['reason']})")
        missing = [c.name for c, i in zip(rig.cameras, intr, strict=True) if i is None]
        if missing:
            raise InputError(f"camera(s) {', '.join(missing)}: no image of theirs in STATIONS.csv "
                             "(every --camera needs images)", option="--camera")
        val = None
        if validate is not None:
            vimg, vnames, vcam, vq, vboards = validate
            val, _, vskip = detect_rig(rig, vimg, vnames, vcam, vq, vboards, limits, intr,
                                       poses=False)
            skipped += [{**s, "validation": True} for s in vskip]
        res = calibrate_rig(
            model, views, cams, brds, [i.K for i in intr], [i.dist for i in intr],
            refine_intrinsics=[c.intrinsics is None for c in rig.cameras],
            rational=rational or any(i.rational for i in intr), free=free, loss=loss,
            board_specs=[b.board.spec for b in rig.boards], others=others, sigma=sigma,
            extra={"skipped": skipped, "n_images": len(names), "n_used": len(views.q),
                   "intrinsics_given": {c.name: c.intrinsics is not None
                                        for c in rig.cameras}})
        if val is not None:
            add_validation(res, _orient(val, rig, res, model))
    res.warnings = list(found)
    return res


def _orient(views: RigViews, rig: Rig, res: RigResult, model) -> RigViews:
    """Held-out images of a symmetric board with their corners in the order the
    calibrated rig predicts (a board listed turned put back: its corners permuted by the
    turn that fits best)."""
    if not any(orientation_ambiguous(b.board) for b in rig.boards) or not len(views.q):
        return views
    frames = LinkFrames(model, views.q, [m.link for m in res.cameras + res.boards])
    px = RigPixels(frames, views, res.cameras, res.boards, res.K, res.dist,
                   res.camera_poses, res.board_poses, [0] * len(res.cameras))
    pred = px.predict(res.params, np.zeros(px.n_nuisance), strict=False)[0]
    start = np.r_[0, np.cumsum(px.counts)]
    pixels = [p.copy() for p in views.pixels]
    for i in range(len(views.names)):
        for b in np.unique(views.board[i]):
            board = rig.boards[b].board
            if not orientation_ambiguous(board):
                continue
            sel = np.flatnonzero(views.board[i] == b)
            ids = _ids(views.points[i][sel], board)
            if ids is None:
                continue
            want = pred[start[i] + sel]
            best, err = pixels[i][sel], np.nansum((pixels[i][sel] - want) ** 2)
            for _, perm in board.symmetries():
                moved = np.full((board.n_corners, 2), np.nan)
                moved[perm[ids]] = pixels[i][sel]
                cand = moved[ids]
                e = np.nansum((cand - want) ** 2)
                if np.isfinite(cand).all() and e < err:
                    best, err = cand, e
            pixels[i][sel] = best
    return RigViews(views.names, views.camera, views.q, views.points, pixels, views.board,
                    views.poses)


def _ids(P: Array, board) -> NDArray[np.intp] | None:
    """The corner ids of board points `P` ``(N, 3)``."""
    d = np.linalg.norm(P[:, None, :] - board.object_points[None], axis=2)
    ids = np.argmin(d, axis=1)
    return ids if np.allclose(d[np.arange(len(P)), ids], 0.0, atol=1e-9) else None
