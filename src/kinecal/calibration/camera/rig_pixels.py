"""`RigPixels`: the corner pixels of a camera rig and their model.

A rig has cameras and boards, each mounted on a link (`kinecal.calibration.camera.
rig_frames`). Image ``i`` is taken by camera ``c`` at joint readings ``q_i`` and shows the
corners of one or several boards. A corner ``P`` of board ``b`` is seen at

    ``uv = project(K_c, d_c, X_c^-1 L_c(q_i)^-1 L_b(q_i) Y_b P)``

with ``X_c`` the camera's pose in its link (``cam2link``, OpenCV camera axes), ``Y_b`` the
board's pose in its link (``board2link``) and ``L(q)`` a link's pose in the world frame
(identity for ``world``). A head camera on a pan-tilt looking at a board in another arm's
hand, static cameras around a cell, a stereo pair on a wrist: one formula. The one-camera
block (`kinecal.calibration.camera.block.PixelBlock`) is the case of one camera and one
board, one of them on the flange and the other on the world.

The arm's (or system's) parameters enter through the two link poses; with ``w = Y_b P``,
``u = R_b w + t_b`` (world) and ``A = J_proj R_X^T R_c^T`` (pixels per world vector):

- board link: ``d uv = A (dt_b - [R_b w]x dphi_b)``;
- camera link: ``d uv = A (-dt_c + [u - t_c]x dphi_c)``;

each times the link's pose Jacobian. The mounts are increments on references (a rotation
vector right-multiplied, a translation), the intrinsics ``(fx, fy, cx, cy, k1, k2, p1, p2,
k3[, k4, k5, k6])`` per camera, as in `PixelBlock`. Every column is checked against central
differences in the tests.

The Jacobian of a corner reaches the arm's columns, its camera's mount and intrinsics and
its board's mount only: `kinecal.calibration.camera.rig_jacobian.RigJacobian` keeps these
local blocks, from which the block-sparse normal equations are assembled without the dense
nuisance Jacobian.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.camera.rig_jacobian import RigJacobian, rig_jacobian, rotate_by_view
from kinecal.calibration.handeye.camera import (
    INTRINSIC_NAMES,
    check_camera,
    intrinsic_vector,
    project_jacobian,
    with_intrinsics,
)
from kinecal.errors import InputError
from kinecal.spatial import matrix_from_axis_angle, transform_from

Array = NDArray[np.float64]
Index = NDArray[np.intp]

__all__ = ["Mount", "RigJacobian", "RigPixels", "RigViews", "mount_names"]

POSE = ("rx", "ry", "rz", "x", "y", "z")


@dataclass(frozen=True)
class Mount:
    """A camera or board: its name and the (resolved) link it hangs from."""

    name: str
    link: str


@dataclass
class RigViews:
    """The detected corners of every image of a rig.

    Attributes
    ----------
    names : list of str
        Image names.
    camera : ndarray of int, shape (n,)
        Camera (index into the rig's cameras) of each image.
    q : ndarray, shape (n, n_joints)
        Joint readings (rad; prismatic: length unit).
    points : list of ndarray, shape (N_i, 3)
        Board coordinates of the corners found in image i (length unit of the model).
    pixels : list of ndarray, shape (N_i, 2)
        Their pixel positions.
    board : list of ndarray of int, shape (N_i,)
        Board (index into the rig's boards) of each corner.
    poses : list of dict, optional
        Per image, ``{board index: target2cam (4, 4)}`` from PnP (for the start).
    """

    names: list[str]
    camera: Index
    q: Array
    points: list[Array]
    pixels: list[Array]
    board: list[Index]
    poses: list[dict[int, Array]] | None = None

    def __post_init__(self) -> None:
        self.camera = np.asarray(self.camera, dtype=np.intp)
        self.q = np.atleast_2d(np.asarray(self.q, dtype=float))
        n = len(self.names)
        sizes = {len(self.camera), len(self.q), len(self.points), len(self.pixels),
                 len(self.board)}
        if sizes != {n}:
            raise InputError(f"{n} images but {sorted(sizes)} cameras / joints / corner sets")

    def subset(self, rows: Sequence[int]) -> RigViews:
        """The images `rows` only."""
        rows = [int(i) for i in rows]
        return RigViews([self.names[i] for i in rows], self.camera[rows], self.q[rows],
                        [self.points[i] for i in rows], [self.pixels[i] for i in rows],
                        [self.board[i] for i in rows],
                        None if self.poses is None else [self.poses[i] for i in rows])


def mount_names(cameras: Sequence[Mount], boards: Sequence[Mount], n_int: Sequence[int]
                ) -> list[str]:
    """Names of the rig's own unknowns: ``camera.NAME.rx .. z`` per camera, ``board.NAME.rx
    .. z`` per board, then ``NAME.fx ..`` for each camera's free intrinsics."""
    out = [f"camera.{c.name}.{p}" for c in cameras for p in POSE]
    out += [f"board.{b.name}.{p}" for b in boards for p in POSE]
    for c, k in zip(cameras, n_int, strict=True):
        out += [f"{c.name}.{n}" for n in INTRINSIC_NAMES[:k]]
    return out


class RigPixels:
    """Corner pixels of a rig's images and their model (module docstring).

    Parameters
    ----------
    frames : LinkFrames or FixedFrames
        The mounting links' poses per image.
    views : RigViews
    cameras, boards : sequence of Mount
    K, dist : sequence
        Per camera: camera matrix and OpenCV distortion (start values when free).
    X0, Y0 : sequence of ndarray, shape (4, 4)
        References of the camera mounts (``cam2link``) and board mounts (``board2link``).
    n_int : sequence of int
        Free intrinsics per camera: 0, 9 or 12.
    """

    def __init__(self, frames, views: RigViews, cameras: Sequence[Mount],
                 boards: Sequence[Mount], K: Sequence[Array], dist: Sequence[Array | None],
                 X0: Sequence[Array], Y0: Sequence[Array], n_int: Sequence[int]) -> None:
        self.frames, self.views = frames, views
        self.cameras, self.boards = list(cameras), list(boards)
        nc, nb = len(self.cameras), len(self.boards)
        if not (len(K) == len(dist) == len(X0) == len(n_int) == nc) or len(Y0) != nb:
            raise InputError(f"{nc} cameras and {nb} boards: expected one K, distortion, "
                             "mount and intrinsics count per camera and a mount per board")
        cams = [check_camera(k, d) for k, d in zip(K, dist, strict=True)]
        self.K = [c[0] for c in cams]
        self.d8 = [c[1] for c in cams]
        self.X0 = [np.asarray(x, float) for x in X0]
        self.Y0 = [np.asarray(y, float) for y in Y0]
        self.n_int = [int(k) for k in n_int]
        if any(k not in (0, 9, 12) for k in self.n_int):
            raise InputError(f"free intrinsics per camera: expected 0, 9 or 12, got {n_int}")
        v = views
        counts = np.array([len(p) for p in v.points], dtype=np.intp)
        self.counts = counts
        self.img = np.repeat(np.arange(len(counts)), counts).astype(np.intp)
        self.P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in v.points]) \
            if len(counts) else np.zeros((0, 3))
        self.uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in v.pixels]) \
            if len(counts) else np.zeros((0, 2))
        self.board_of = np.concatenate([np.asarray(b, np.intp) for b in v.board]) \
            if len(counts) else np.zeros(0, np.intp)
        self.cam_of = v.camera[self.img]
        if self.board_of.size and (self.board_of.min() < 0 or self.board_of.max() >= nb):
            raise InputError(f"corner board index outside 0..{nb - 1}")
        if len(v.camera) and (v.camera.min() < 0 or v.camera.max() >= nc):
            raise InputError(f"image camera index outside 0..{nc - 1}")
        # the (image, board) views: every corner's view, and each view's image and board
        key = self.img * max(nb, 1) + self.board_of
        vkeys, self.vid = np.unique(key, return_inverse=True)
        self.view_img = (vkeys // max(nb, 1)).astype(np.intp)
        self.view_board = (vkeys % max(nb, 1)).astype(np.intp)
        # corners of one view in one run (the usual layout): per-view matrix products
        vcount = np.bincount(self.vid, minlength=len(vkeys))
        self.view_sorted = bool(np.all(np.diff(self.vid) >= 0))
        self.view_n = int(vcount[0]) if self.view_sorted and len(vcount) and np.all(
            vcount == vcount[0]) else 0
        ends = np.cumsum(vcount)
        self.view_bounds = list(zip((ends - vcount).tolist(), ends.tolist(), strict=True))
        self.slices = self._slices()

    # ------------------------------------------------------------------ layout
    def _slices(self) -> dict[str, list[slice]]:
        nc, nb = len(self.cameras), len(self.boards)
        cam = [slice(6 * c, 6 * c + 6) for c in range(nc)]
        brd = [slice(6 * (nc + b), 6 * (nc + b) + 6) for b in range(nb)]
        start = 6 * (nc + nb)
        intr = []
        for k in self.n_int:
            intr.append(slice(start, start + k))
            start += k
        return {"camera": cam, "board": brd, "intrinsics": intr}

    @property
    def n_nuisance(self) -> int:
        """Length of the rig's own parameter vector."""
        return 6 * (len(self.cameras) + len(self.boards)) + sum(self.n_int)

    @property
    def nuisance_names(self) -> list[str]:
        return mount_names(self.cameras, self.boards, self.n_int)

    @property
    def n_corners(self) -> int:
        return len(self.P)

    @property
    def n_images(self) -> int:
        return len(self.counts)

    def nuisance_groups(self) -> dict[str, slice]:
        """``{"camera NAME": slice, "board NAME": slice, "NAME intrinsics": slice}``."""
        out = {f"camera {c.name}": s for c, s in zip(self.cameras, self.slices["camera"],
                                                      strict=True)}
        out.update({f"board {b.name}": s for b, s in zip(self.boards, self.slices["board"],
                                                          strict=True)})
        out.update({f"{c.name} intrinsics": s for c, s, k in
                    zip(self.cameras, self.slices["intrinsics"], self.n_int, strict=True) if k})
        return out

    # ------------------------------------------------------------------ model
    def unpack(self, nu: Array) -> tuple[list[Array], list[Array], list[Array], list[Array]]:
        """Camera mounts, board mounts ``(4, 4)``, K and 8 distortion coefficients per
        camera at `nu`."""
        nu = np.asarray(nu, dtype=float)
        X = [transform_from(x0[:3, :3] @ matrix_from_axis_angle(nu[s][:3]),
                            x0[:3, 3] + nu[s][3:])
             for x0, s in zip(self.X0, self.slices["camera"], strict=True)]
        Y = [transform_from(y0[:3, :3] @ matrix_from_axis_angle(nu[s][:3]),
                            y0[:3, 3] + nu[s][3:])
             for y0, s in zip(self.Y0, self.slices["board"], strict=True)]
        Ks, ds = [], []
        for K, d, k, s in zip(self.K, self.d8, self.n_int, self.slices["intrinsics"],
                              strict=True):
            if k:
                K, d = with_intrinsics(K, d, intrinsic_vector(K, d, k == 12) + nu[s])
            Ks.append(K)
            ds.append(d)
        return X, Y, Ks, ds

    def _link_pose(self, poses: dict, links: list[str], which: Index, rows: Index
                   ) -> tuple[Array, Array]:
        """Rotation ``(r, 3, 3)`` and origin ``(r, 3)`` of the link ``links[which[j]]`` at
        image ``rows[j]``."""
        R = np.empty((len(rows), 3, 3))
        t = np.empty((len(rows), 3))
        for k, link in enumerate(links):
            sel = which == k
            if sel.any():
                R[sel] = poses[link].R[rows[sel]]
                t[sel] = poses[link].t[rows[sel]]
        return R, t

    def predict(self, params: Array, nu: Array, columns: Index | None = None,
                jac: bool = False, strict: bool = True
                ) -> tuple[Array, RigJacobian | None]:
        """Predicted pixels ``(M, 2)`` of every corner and (`jac`) their `RigJacobian`
        for the arm's parameter indices `columns`.

        Raises
        ------
        InputError
            A corner behind its camera (`strict`; else its pixels are NaN).
        """
        X, Y, Ks, ds = self.unpack(nu)
        cols = None if not jac else (np.zeros(0, np.intp) if columns is None
                                     else np.asarray(columns, np.intp))
        poses = self.frames.poses(params, cols)
        cam_links = [c.link for c in self.cameras]
        brd_links = [b.link for b in self.boards]
        vi, vb = self.view_img, self.view_board
        vc = self.views.camera[vi]
        Rc, tc = self._link_pose(poses, cam_links, vc, vi)
        Rb, tb = self._link_pose(poses, brd_links, vb, vi)
        RX = np.array([x[:3, :3] for x in X])[vc]
        tX = np.array([x[:3, 3] for x in X])[vc]
        RY = np.array([y[:3, :3] for y in Y])[vb]
        tY = np.array([y[:3, 3] for y in Y])[vb]
        B = np.swapaxes(RX, 1, 2) @ np.swapaxes(Rc, 1, 2)  # world -> camera, per view
        Mw = B @ Rb  # board link -> camera
        Mv = Mw @ RY  # board -> camera
        ov = np.einsum("vij,vj->vi", B, np.einsum("vij,vj->vi", Rb, tY) + tb - tc) \
            - np.einsum("vji,vj->vi", RX, tX)
        pc = rotate_by_view(self, self.P, Mv, ov)
        behind = pc[:, 2] <= 0
        if np.any(behind):
            if strict:
                i = int(self.img[np.argmax(behind)])
                raise InputError(f"image {self.views.names[i]}: a board is behind its camera "
                                 "for these joints and mounts: the joints do not fit the "
                                 "images (wrong camera or board column, link, joint order or "
                                 "unit?)")
            pc = np.where(behind[:, None], np.nan, pc)
        M = len(pc)
        uv = np.empty((M, 2))
        Jp = np.empty((M, 2, 3)) if jac else None
        Jint: list[Array | None] = [None] * len(self.cameras)
        for c in range(len(self.cameras)):
            sel = self.cam_of == c
            if not sel.any():
                continue
            u, jp, ji = project_jacobian(Ks[c], ds[c], pc[sel], self.n_int[c] == 12, jac,
                                         intrinsics=self.n_int[c] > 0)
            uv[sel] = u
            if jac:
                Jp[sel] = jp
                Jint[c] = ji[:, :, :self.n_int[c]] if self.n_int[c] else None
        if not jac:
            return uv, None
        return uv, rig_jacobian(self, nu, poses, cols, Jp, Jint, pc, B, Mw, RY, Rb, tb, tc,
                                tY)

    def residuals(self, params: Array, nu: Array, strict: bool = True) -> Array:
        """Predicted minus detected pixels ``(M, 2)``."""
        return self.predict(params, nu, strict=strict)[0] - self.uv

    def image_rms(self, r: Array) -> Array:
        """RMS corner error ``(n,)`` per image (px) of residuals `r` ``(M, 2)``; infinite
        for an image with a corner behind its camera (NaN residuals)."""
        n = self.n_images
        ss = np.bincount(self.img, weights=np.sum(r * r, axis=1), minlength=n)
        rms = np.sqrt(ss / np.maximum(self.counts, 1))
        return np.where(np.isfinite(rms), rms, np.inf)
