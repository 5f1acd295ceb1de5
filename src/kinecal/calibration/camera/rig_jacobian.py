"""The Jacobian of a rig's corner pixels by parameter block, and the block-sparse normal
equations assembled from it.

A corner's two pixel rows reach the model's columns, its camera's mount (6) and
intrinsics (9 or 12, when free) and its board's mount (6), nothing else. `RigJacobian`
keeps those local blocks; `RigJacobian.normal` sums ``J^T W J`` and ``J^T W r`` block by
block: the model's block from every row, each camera's and board's from its own rows, a
camera-board coupling only where they share images. Nothing of the dense nuisance
Jacobian (rows x every mount) is formed: the normal matrix is block-sparse, each mount's
diagonal block coupled to the model's columns and to the mounts it shares images with.
The formulas are those of `kinecal.calibration.camera.rig_pixels` (its docstring).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.camera.block import _cross_rows as cross_rows
from kinecal.calibration.handeye.refine import _jr
from kinecal.spatial import matrix_from_axis_angle

Array = NDArray[np.float64]
Index = NDArray[np.intp]

__all__ = ["RigJacobian", "rig_jacobian", "rotate_by_view", "times_by_view"]


def times_by_view(px, X: Array, M: Array, views: Index | None = None) -> Array:
    """``X_m M_{view(m)}`` ``(N, r, q)`` for the rows `X` ``(N, r, c)`` of the corners of
    `views` (default all; sorted view indices; the rows in corner order) and one matrix
    per view `M` ``(len(views), c, q)``: one batched product when every view has as many
    corners (a grid board seen whole), one product per view when each view's corners are
    in one run, a gathered product else."""
    views = np.arange(len(px.view_img)) if views is None else np.asarray(views, np.intp)
    N, r, c = X.shape
    q = M.shape[2]
    if px.view_n:
        n = px.view_n
        return (X.reshape(len(views), n * r, c) @ M).reshape(N, r, q)
    if px.view_sorted:
        out = np.empty((N, r, q))
        at = 0
        for j, v in enumerate(views):
            a, b = px.view_bounds[v]
            out[at:at + b - a] = (X[at:at + b - a].reshape(-1, c) @ M[j]).reshape(b - a, r, q)
            at += b - a
        return out
    of = px.vid if len(views) == len(px.view_img) else px.vid[np.isin(px.vid, views)]
    return X @ M[np.searchsorted(views, of)]  # each row its view's matrix (rows in order)


def rotate_by_view(px, P: Array, R: Array, o: Array | None = None) -> Array:
    """``R_v P_m (+ o_v)`` ``(M, 3)`` for every corner `P` ``(M, 3)`` of view v, `R`
    ``(V, 3, 3)`` and `o` ``(V, 3)`` per view."""
    out = times_by_view(px, P[:, None, :], np.swapaxes(R, 1, 2))[:, 0, :]
    if o is not None:
        out += o[px.vid]
    return out


def _per_group(V: Array, M: Array, group: Index, n: int) -> Array:
    """``V_m M_{group(m)}`` ``(N, r, q)`` for rows `V` ``(N, r, 3)`` and one matrix per
    group `M` ``(n, 3, q)``: one matrix product per group."""
    out = np.empty((*V.shape[:2], M.shape[2]))
    for g in range(n):
        sel = group == g
        if sel.any():
            out[sel] = (V[sel].reshape(-1, 3) @ M[g]).reshape(-1, V.shape[1], M.shape[2])
    return out


@dataclass
class RigJacobian:
    """The Jacobian of every corner's two pixel coordinates, by parameter block.

    Attributes
    ----------
    arm : ndarray, shape (M, 2, k)
    camera : ndarray, shape (M, 2, 6)
        Its camera's mount (rotation increment, translation).
    board : ndarray, shape (M, 2, 6)
        Its board's mount.
    intrinsics : list of ndarray or None
        Per camera ``(M_c, 2, n_int_c)`` for the corners of its images (in corner order),
        when free.
    cam_of, board_of : ndarray of int, shape (M,)
    slices : dict
        Where each block sits in the nuisance vector (`RigPixels.slices`).
    """

    arm: Array
    camera: Array
    board: Array
    intrinsics: list
    cam_of: Index
    board_of: Index
    slices: dict = field(default_factory=dict)

    def dense_nuisance(self, n_nu: int) -> Array:
        """``(2M, n_nu)``: the nuisance Jacobian with its zeros."""
        M = len(self.cam_of)
        J = np.zeros((M, 2, n_nu))
        for c in np.unique(self.cam_of):
            sel = self.cam_of == c
            J[sel, :, self.slices["camera"][c]] = self.camera[sel]
            if self.intrinsics[c] is not None and self.intrinsics[c].shape[2]:
                J[sel, :, self.slices["intrinsics"][c]] = self.intrinsics[c]
        for b in np.unique(self.board_of):
            sel = self.board_of == b
            J[sel, :, self.slices["board"][b]] = self.board[sel]
        return J.reshape(2 * M, n_nu)

    def normal(self, w: Array, r: Array, n_nu: int
               ) -> tuple[Array, Array, Array, Array, Array]:
        """``(A_aa, A_an, A_nn, g_a, g_n)``: ``J^T J`` and ``J^T r`` of the rows weighted by
        `w` ``(2M,)`` (`r` ``(2M,)`` already weighted), block by block (module docstring)."""
        M = len(self.cam_of)
        w2 = np.asarray(w, float).reshape(M, 2, 1)
        rr = np.asarray(r, float).reshape(M, 2)
        Ja = (self.arm * w2).reshape(2 * M, -1)
        k = Ja.shape[1]
        Aaa, ga = Ja.T @ Ja, Ja.T @ rr.ravel()
        Aan, Ann, gn = np.zeros((k, n_nu)), np.zeros((n_nu, n_nu)), np.zeros(n_nu)
        cams, brds, intr = self.slices["camera"], self.slices["board"], self.slices["intrinsics"]
        own: dict[tuple[str, int], tuple[Array, slice, Array]] = {}
        for c in np.unique(self.cam_of):
            sel = self.cam_of == c
            own[("camera", c)] = (sel, cams[c], (self.camera[sel] * w2[sel]).reshape(-1, 6))
            if self.intrinsics[c] is not None and self.intrinsics[c].shape[2]:
                ni = self.intrinsics[c].shape[2]
                own[("intr", c)] = (sel, intr[c],
                                    (self.intrinsics[c] * w2[sel]).reshape(-1, ni))
        for b in np.unique(self.board_of):
            sel = self.board_of == b
            own[("board", b)] = (sel, brds[b], (self.board[sel] * w2[sel]).reshape(-1, 6))
        for sel, s, J in own.values():
            rows = np.repeat(sel, 2)
            Aan[:, s] = Ja[rows].T @ J
            gn[s] = J.T @ rr[sel].ravel()
        items = list(own.items())
        for i, ((_, _), (sa, s1, Ja_)) in enumerate(items):
            for (_, _), (sb, s2, Jb_) in items[i:]:
                if s1 == s2:
                    Ann[s1, s1] = Ja_.T @ Ja_
                    continue
                both = sa & sb
                if not both.any():
                    continue
                # the rows both blocks reach, in each block's own row order
                ia = np.repeat(both[sa], 2)
                ib = np.repeat(both[sb], 2)
                G = Ja_[ia].T @ Jb_[ib]
                Ann[s1, s2] = G
                Ann[s2, s1] = G.T
        return Aaa, Aan, Ann, ga, gn


def rig_jacobian(px, nu: Array, poses: dict, cols: Index, Jp: Array, Jint: list,
                 pc: Array, B: Array, Mw: Array, RY: Array, Rb: Array, tb: Array, tc: Array,
                 tY: Array) -> RigJacobian:
    """The `RigJacobian` of `px` (a `RigPixels`) at `nu`, from its prediction's pieces:
    the projection Jacobian `Jp` ``(M, 2, 3)`` and per camera the intrinsic one, camera
    points `pc`, and per view the world-to-camera rotation `B`, board-link-to-camera `Mw`,
    board mount rotation `RY` and translation `tY`, board and camera link poses."""
    v = px.vid
    nc, nb = len(px.cameras), len(px.boards)
    A = times_by_view(px, Jp, B)  # pixels per world vector
    P = px.P
    w = rotate_by_view(px, P, RY, tY)  # board point in its link
    Rw = rotate_by_view(px, w, Rb)  # u - t_b
    arm = np.zeros((len(pc), 2, len(cols)))
    if len(cols):
        u_tc = Rw + tb[v] - tc[v]
        Hb = np.concatenate([A, -cross_rows(A, Rw)], axis=2)
        Hc = np.concatenate([-A, cross_rows(A, u_tc)], axis=2)
        view_cam = px.views.camera[px.view_img]
        for mounts, H, vof in ((px.boards, Hb, px.view_board), (px.cameras, Hc, view_cam)):
            # each view's link pose Jacobian (zero for a static mount's views): one batched
            # product per side, no scatter into the rows of each mount
            G = np.zeros((len(vof), 6, len(cols)))
            moving = False
            for k, m in enumerate(mounts):
                lp = poses[m.link]
                if lp.moves:
                    views = vof == k
                    G[views] = lp.G[px.view_img[views]]
                    moving = True
            if moving:
                arm += times_by_view(px, H, G)
    nu = np.asarray(nu, float)
    ac = np.array([nu[s][:3] for s in px.slices["camera"]])
    RX = np.array([x0[:3, :3] @ matrix_from_axis_angle(a) for x0, a in
                   zip(px.X0, ac, strict=True)])
    cam = np.empty((len(pc), 2, 6))
    cam[:, :, :3] = _per_group(cross_rows(Jp, pc), _jr(ac), px.cam_of, nc)
    cam[:, :, 3:] = _per_group(Jp, -np.swapaxes(RX, 1, 2), px.cam_of, nc)
    ab = np.array([nu[s][:3] for s in px.slices["board"]])
    RYb = np.array([y0[:3, :3] @ matrix_from_axis_angle(a) for y0, a in
                    zip(px.Y0, ab, strict=True)])
    Ab = times_by_view(px, Jp, Mw)
    brd = np.empty((len(pc), 2, 6))
    brd[:, :, :3] = -_per_group(cross_rows(_per_group(Ab, RYb, px.board_of, nb), P),
                                _jr(ab), px.board_of, nb)
    brd[:, :, 3:] = Ab
    return RigJacobian(arm, cam, brd, list(Jint), px.cam_of, px.board_of, px.slices)
