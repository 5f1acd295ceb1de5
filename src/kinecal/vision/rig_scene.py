"""Rendered stations of a camera rig on a perturbed arm or robot system: plan a rig before
building it.

`render_rig_stations` draws a true model (the nominal plus random or given parameter
errors), mounts the rig's cameras and boards (`kinecal.vision.rig_mounts`, or mounts
given), and plans stations: at each, one camera-board pair is the *primary* (taken in
turn), a view of that board is planned around the camera (`kinecal.vision.render.
plan_views`: distance, tilt, roll), the other chains' joints are drawn around the home
configuration, and the inverse kinematics of the chain that carries the board (or the
camera, when the board is static) gives its joints; views the true model cannot reach are
drawn again. Every camera then takes an image at the station when it sees a board whole,
from its printed side and at most `max_angle_deg` off the board's normal (a board seen too
obliquely, or from behind, is occluded). Each camera has its own intrinsics and image
size; an image shows every board in its view (the nearer hides the farther).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.camera.rig_frames import WORLD, LinkFrames
from kinecal.calibration.camera.rig_pixels import Mount, RigViews
from kinecal.calibration.handeye.camera import check_camera, project
from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.kinematics.tree.system import is_system
from kinecal.spatial import invert_transform, transform_from
from kinecal.vision.boards import Board
from kinecal.vision.imaging import ImageConditions, render_boards
from kinecal.vision.render import plan_views
from kinecal.vision.rig_mounts import default_mounts
from kinecal.vision.stations import scene_errors

Array = NDArray[np.float64]

__all__ = ["RigScene", "render_rig_stations", "scene_views"]


@dataclass
class RigScene:
    """Rendered images of a rig with the truth.

    Attributes
    ----------
    model, true_params, q_home
        The nominal model, the true parameters, the home configuration (rad).
    cameras : list of Mount
    boards : list of (Mount, Board)
    K, dist, size : list
        Per camera.
    X, Y : list of ndarray, shape (4, 4)
        True camera mounts (``cam2link``) and board mounts (``board2link``).
    q : ndarray, shape (n, n_joints)
        Joint readings of every image.
    camera : ndarray of int, shape (n,)
    station : ndarray of int, shape (n,)
    seen : list of list of int
        Per image, the boards seen whole.
    target2cam : list of dict
        Per image, the true pose of every board it shows.
    names : list of str
    images : list of ndarray
    """

    model: Any
    true_params: Array
    q_home: Array
    cameras: list[Mount]
    boards: list[tuple[Mount, Board]]
    K: list[Array]
    dist: list[Array]
    size: list[tuple[int, int]]
    X: list[Array]
    Y: list[Array]
    q: Array
    camera: NDArray[np.intp]
    station: NDArray[np.intp]
    seen: list[list[int]]
    target2cam: list[dict[int, Array]]
    names: list[str] = field(default_factory=list)
    images: list = field(default_factory=list)


class _Chains:
    """The chain each mounting link moves with, and its inverse kinematics."""

    def __init__(self, model, truth: Array, home: Array) -> None:
        self.model, self.truth, self.home = model, truth, home
        self._ik: dict[str, tuple] = {}

    def solver(self, link: str):
        """``(serial model, joint indices, link-to-tool offset)`` of the chain that ends at
        `link`, or None (an intermediate link, or the world)."""
        if link == WORLD:
            return None
        if link not in self._ik:
            m = self.model
            if not is_system(m):
                self._ik[link] = (m, np.arange(m.n_joints), np.eye(4))
            else:
                tip = next((t for t in m.tips if m.tip_link(t) == link), None)
                if tip is None:
                    self._ik[link] = None
                else:
                    sm = m.tip_model(tip, self.truth)
                    idx = np.array([m.joint_names.index(e["name"]) for e in sm.joints])
                    Lh = m.link_poses(self.home[None], link, self.truth)[0]
                    off = invert_transform(Lh) @ sm.fk(self.home[idx], sm.nominal)[0]
                    self._ik[link] = (sm, idx, off)
        return self._ik[link]

    def moved_by(self, link: str) -> NDArray[np.intp]:
        if link == WORLD:
            return np.zeros(0, np.intp)
        if not is_system(self.model):
            return np.arange(self.model.n_joints)
        return self.model.link_joints(link)


def _visible(board: Board, K: Array, d8: Array, size: tuple[int, int], C: Array,
             max_angle: float, margin: float = 12.0) -> bool:
    """The whole board in view from its printed side, at most `max_angle` (rad) off its
    normal."""
    P = board.object_points @ C[:3, :3].T + C[:3, 3]
    if np.any(P[:, 2] <= 0):
        return False
    cam = -C[:3, :3].T @ C[:3, 3]  # the camera in the board frame
    if board.faces * cam[2] >= 0 or abs(cam[2]) < np.cos(max_angle) * np.linalg.norm(cam):
        return False
    uv = project(K, d8, P)
    return bool(np.all(np.isfinite(uv)) and uv[:, 0].min() > margin
                and uv[:, 1].min() > margin and uv[:, 0].max() < size[0] - 1 - margin
                and uv[:, 1].max() < size[1] - 1 - margin)


def render_rig_stations(model, cameras: Sequence[Mount], boards: Sequence[tuple[Mount, Board]],
                        cams: Sequence[tuple[Array, Array | None, tuple[int, int]]], n: int, *,
                        errors: str | Array = "random", q_home: Array | None = None,
                        mounts: Mapping[str, Array] | None = None,
                        conditions: ImageConditions | None = None, seed: int = 0,
                        supersample: int = 2, spread_deg: float = 20.0,
                        max_angle_deg: float = 40.0, view_options: dict | None = None,
                        render: bool = True) -> RigScene:
    """Render `n` stations of a rig (module docstring).

    Parameters
    ----------
    model : SerialModel or SystemModel
        Nominal model (its length unit is the boards').
    cameras : sequence of Mount
    boards : sequence of (Mount, Board)
    cams : sequence of (K, dist, size)
        Each camera's true intrinsics and image size.
    n : int
        Stations.
    errors : {"random", "zero"} or ndarray
    q_home : ndarray, shape (n_joints,), optional
        Default: the middle of the joint limits.
    mounts : mapping, optional
        ``{"camera NAME" / "board NAME": (4, 4)}``: true mounts to use.
    conditions, seed, supersample
        As `kinecal.vision.stations.render_arm_stations`.
    spread_deg : float
        Joints not solved by inverse kinematics are drawn uniformly within +-spread_deg
        (prismatic: +-spread_deg mm) of home.
    max_angle_deg : float
        A board seen further off its normal is not in the image.
    view_options : dict, optional
        Passed to `plan_views`.
    render : bool
        False: joints and truth only.
    """
    if n < 1:
        raise InputError(f"expected at least 1 station, got {n}", option="--poses")
    rng = np.random.default_rng(seed)
    truth = model.nominal + scene_errors(model, errors, rng)
    lim = np.asarray(model.joint_limits, float)
    home = lim.mean(axis=1) if q_home is None else np.asarray(q_home, float)
    if home.shape != (model.n_joints,):
        raise InputError(f"home configuration: expected {model.n_joints} joints, got "
                         f"{home.shape}", option="--home")
    cam8 = [(*check_camera(K, d), tuple(int(v) for v in s)) for K, d, s in cams]
    opts = {"fill": 0.5, "tilt_deg": 30.0, **(view_options or {})}
    X, Y = default_mounts(model, truth, home, cameras, boards,
                          [(c[0], c[2]) for c in cam8], fill=opts["fill"], given=mounts)
    plan = _Planner(model, truth, home, cameras, boards, cam8, X, Y, rng, opts,
                    np.radians(spread_deg), np.radians(max_angle_deg))
    q, camera, station, seen, poses = plan.stations(n)
    names = [f"{cameras[c].name}_{s:03d}.png" for c, s in zip(camera, station, strict=True)]
    scene = RigScene(model, truth, home, list(cameras), list(boards), [c[0] for c in cam8],
                     [c[1] for c in cam8], [c[2] for c in cam8], X, Y, q, camera, station,
                     seen, poses, names)
    if render:
        base = conditions or ImageConditions()
        for i, c in enumerate(camera):
            shown = sorted(poses[i])
            scene.images.append(render_boards([boards[b][1] for b in shown], cam8[c][0],
                                              cam8[c][1], [poses[i][b] for b in shown],
                                              cam8[c][2], base, supersample=supersample,
                                              rng=rng))
    return scene


class _Planner:
    """The stations of `render_rig_stations`."""

    def __init__(self, model, truth, home, cameras, boards, cams, X, Y, rng, opts, spread,
                 max_angle) -> None:
        self.model, self.truth, self.home = model, truth, home
        self.cameras, self.boards, self.cams = cameras, boards, cams
        self.X, self.Y, self.rng, self.opts = X, Y, rng, opts
        self.spread, self.max_angle = spread, max_angle
        self.chains = _Chains(model, truth, home)
        self.links = [c.link for c in cameras] + [m.link for m, _ in boards]
        self.pairs = [(c, b) for c in range(len(cameras)) for b in range(len(boards))
                      if cameras[c].link != boards[b][0].link]

    def _draw(self) -> Array:
        q = self.home.copy()
        step = np.where(self.model.is_prismatic(), np.degrees(self.spread), self.spread)
        q += self.rng.uniform(-1.0, 1.0, q.shape) * step
        lim = np.asarray(self.model.joint_limits, float)
        return np.clip(q, lim[:, 0], lim[:, 1])

    def _solve(self, c: int, b: int, q: Array) -> Array | None:
        """`q` with the chain of board `b` (or of camera `c`) solved to a planned view."""
        K, d8, size = self.cams[c]
        mb, board = self.boards[b]
        C = plan_views(board, K, d8, size, 1, self.rng, **self.opts)[0]
        frames = LinkFrames(self.model, q[None], [self.cameras[c].link, mb.link])
        poses = frames.poses(self.truth)
        Lc = transform_from(poses[self.cameras[c].link].R[0], poses[self.cameras[c].link].t[0])
        Lb = transform_from(poses[mb.link].R[0], poses[mb.link].t[0])
        board_chain = self.chains.solver(mb.link)
        if board_chain is not None and not np.intersect1d(
                self.chains.moved_by(self.cameras[c].link), board_chain[1]).size:
            want = Lc @ self.X[c] @ C @ invert_transform(self.Y[b])
            return self._ik(board_chain, want, q)
        cam_chain = self.chains.solver(self.cameras[c].link)
        if cam_chain is not None and not np.intersect1d(
                self.chains.moved_by(mb.link), cam_chain[1]).size:
            want = Lb @ self.Y[b] @ invert_transform(C) @ invert_transform(self.X[c])
            return self._ik(cam_chain, want, q)
        return q  # no chain to solve: the drawn joints as they are

    def _ik(self, chain, want: Array, q: Array) -> Array | None:
        sm, idx, off = chain
        res = solve_ik(sm, (want @ off)[None], self.home[idx][None], params=sm.nominal
                       if sm is not self.model else self.truth)
        if res.status[0] != "converged":
            return None
        out = q.copy()
        out[idx] = res.q[0]
        return out

    def _views(self, q: Array) -> tuple[list[int], list[list[int]], list[dict]]:
        """The cameras that see a board whole at `q`, the boards each sees and the poses of
        the boards in front of it."""
        poses = LinkFrames(self.model, q[None], self.links).poses(self.truth)

        def L(link):
            return transform_from(poses[link].R[0], poses[link].t[0])

        cams, seen, shown = [], [], []
        for c, m in enumerate(self.cameras):
            K, d8, size = self.cams[c]
            Tc = invert_transform(L(m.link) @ self.X[c])
            s, p = [], {}
            for b, (mb, board) in enumerate(self.boards):
                if mb.link == m.link:
                    continue
                C = Tc @ L(mb.link) @ self.Y[b]
                if _visible(board, K, d8, size, C, self.max_angle):
                    s.append(b)
                if C[2, 3] > 0:
                    p[b] = C
            if s:
                cams.append(c)
                seen.append(s)
                shown.append({b: p[b] for b in p})
        return cams, seen, shown

    def stations(self, n: int):
        q_out, cam_out, st_out, seen_out, pose_out = [], [], [], [], []
        k, tries = 0, 0
        while k < n:
            tries += 1
            if tries > 40 * n + 40:
                raise InputError(f"the rig's cameras see a board at only {k} of {n} planned "
                                 "stations: move the home configuration (--home), the mounts "
                                 "or the cameras")
            c, b = self.pairs[tries % len(self.pairs)]
            q = self._solve(c, b, self._draw())
            if q is None:
                continue
            cams, seen, shown = self._views(q)
            if c not in cams or b not in seen[cams.index(c)]:
                continue
            for cc, s, p in zip(cams, seen, shown, strict=True):
                q_out.append(q)
                cam_out.append(cc)
                st_out.append(k)
                seen_out.append(s)
                pose_out.append(p)
            k += 1
        return (np.array(q_out), np.array(cam_out, np.intp), np.array(st_out, np.intp),
                seen_out, pose_out)


def scene_views(scene: RigScene, noise: float = 0.0, seed: int = 0,
                rows: Sequence[int] | None = None) -> RigViews:
    """The images of `scene` as detections without rendering: every corner of every board
    an image sees whole, projected through its camera, plus Gaussian noise of `noise` px
    per coordinate, with each board's PnP pose from those corners (what to expect of a
    rig before building it, and the tests' exact data).

    Parameters
    ----------
    scene : RigScene
        Rendered or not (``render=False``).
    noise : float
        Corner noise per coordinate (px).
    seed : int
    rows : sequence of int, optional
        The images to take (default all).
    """
    from kinecal.vision.pnp import board_pose

    rng = np.random.default_rng(seed)
    rows = range(len(scene.names)) if rows is None else list(rows)
    pts, pix, brd, poses = [], [], [], []
    for i in rows:
        c = scene.camera[i]
        K, d = scene.K[c], scene.dist[c]
        P_all, uv_all, b_all, pp = [], [], [], {}
        for b in scene.seen[i]:
            board = scene.boards[b][1]
            C = scene.target2cam[i][b]
            P = board.object_points
            uv = project(K, d, P @ C[:3, :3].T + C[:3, 3])
            uv = uv + rng.normal(size=uv.shape) * noise
            P_all.append(P)
            uv_all.append(uv)
            b_all.append(np.full(len(P), b, np.intp))
            pp[b] = board_pose(P, uv, K, d).target2cam
        pts.append(np.vstack(P_all))
        pix.append(np.vstack(uv_all))
        brd.append(np.concatenate(b_all))
        poses.append(pp)
    return RigViews([scene.names[i] for i in rows], scene.camera[list(rows)],
                    scene.q[list(rows)], pts, pix, brd, poses)
