"""`PixelBlock`: the camera-pixel residual block of an arm calibration.

Station ``i`` has joint readings ``q_i`` and the detected corners of a board. The arm's
forward kinematics ``F_i = F(q_i; theta)`` (the model's end frame in its base frame; the
tool frame when the model has one) places the camera or the board:

- eye-in-hand (camera on the flange, board fixed): a board point ``P`` is seen at
  ``project(K, d, X^-1 F_i^-1 Y P)`` with ``X = cam2flange``, ``Y = target2base``;
- eye-to-hand (camera fixed, board on the flange): at ``project(K, d, X^-1 F_i Y P)`` with
  ``X = cam2base``, ``Y = target2flange``.

``project`` is OpenCV's camera model (`kinecal.calibration.handeye.camera`). The arm's
parameters ``theta`` enter through ``F_i``; their Jacobian is the chain rule through the
serial model's identification Jacobian of the end-frame pose (position, and the small
rotation vector in the base frame: ``dR = [dphi]x R``):

- eye-in-hand, ``z = R_F^T (w - t_F)`` with ``w = Y P``:
  ``dz = R_F^T ([w - t_F]x dphi - dt)``;
- eye-to-hand, ``u = R_F w + t_F``: ``du = -[R_F w]x dphi + dt``;

then ``d uv = J_proj R_X^T d(z or u)``. The block's own (nuisance) parameters are
increments on a start: X's rotation vector (right-multiplied, X frame) and translation, the
board pose's likewise, and optionally the intrinsics ``(fx, fy, cx, cy, k1, k2, p1, p2,
k3[, k4, k5, k6])``, as in `kinecal.calibration.handeye.reprojection`. Every column is
checked against central differences in the tests.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import (
    INTRINSIC_NAMES,
    check_camera,
    intrinsic_vector,
    project_jacobian,
    with_intrinsics,
)
from kinecal.calibration.handeye.refine import _jr
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_axis_angle, transform_from

Array = NDArray[np.float64]

__all__ = ["SETUPS", "PixelBlock", "nuisance_names"]

SETUPS = ("eye-in-hand", "eye-to-hand")


def _jr_of(w: Array) -> Array:
    """The right Jacobian of SO(3) at one rotation vector `w` ``(3,)`` (the increments of
    X and the board pose; `kinecal.calibration.handeye.refine._jr` for stacks): the identity
    at zero, where every fit starts and most evaluations are."""
    w = np.asarray(w, float)
    if not w.any():
        return np.eye(3)
    return _jr(w)


def _cross_rows(V: Array, a: Array) -> Array:
    """``V_c,r x a_c`` ``(M, r, 3)`` for rows `V` ``(M, r, 3)`` and vectors `a` ``(M, 3)``
    (``v^T [a]x = (v x a)^T``), written out: numpy's cross is several times slower here."""
    out = np.empty_like(V)
    a0, a1, a2 = a[:, None, 0], a[:, None, 1], a[:, None, 2]
    out[..., 0] = V[..., 1] * a2 - V[..., 2] * a1
    out[..., 1] = V[..., 2] * a0 - V[..., 0] * a2
    out[..., 2] = V[..., 0] * a1 - V[..., 1] * a0
    return out


def nuisance_names(setup: str, n_int: int) -> list[str]:
    """Names of the block's own parameters: X (``cam2flange`` eye-in-hand, ``cam2base``
    eye-to-hand), the board pose (``target2base``, ``target2flange``), the free intrinsics."""
    if setup not in SETUPS:
        raise InputError(f"unknown setup {setup!r}; expected {' or '.join(SETUPS)}",
                         option="--setup")
    names = [f"X.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    names += [f"board.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    return names + list(INTRINSIC_NAMES[:n_int])


@dataclass
class PixelBlock:
    """Corner pixels of all stations and the fixed parts of their model.

    Parameters
    ----------
    model : SerialModel
        The arm (its `nominal` is not used: the parameter vector is passed in).
    q : ndarray, shape (n, n_joints)
        Joint readings per station (rad; prismatic: length unit).
    points : list of ndarray, shape (N_i, 3)
        Board coordinates of the corners detected in station i (board length unit, which
        must be the model's length unit).
    pixels : list of ndarray, shape (N_i, 2)
        Their detected pixel positions.
    setup : {"eye-in-hand", "eye-to-hand"}
    K, dist
        Camera matrix and OpenCV distortion coefficients (start values when intrinsics
        are free).
    X0, Y0 : ndarray, shape (4, 4)
        Start of X and of the board pose.
    n_int : int
        Free intrinsics: 0, 9, or 12 (rational model).
    """

    model: SerialModel
    q: Array
    points: Sequence[Array]
    pixels: Sequence[Array]
    setup: str
    K: Array
    dist: Array | None
    X0: Array
    Y0: Array
    n_int: int = 0

    def __post_init__(self) -> None:
        if self.setup not in SETUPS:
            raise InputError(f"unknown setup {self.setup!r}; expected {' or '.join(SETUPS)}",
                             option="--setup")
        if self.n_int not in (0, 9, 12):
            raise InputError(f"n_int: expected 0, 9 or 12 free intrinsics, got {self.n_int}")
        self.K, self.d8 = check_camera(self.K, self.dist)
        self.q = np.atleast_2d(np.asarray(self.q, dtype=float))
        n = len(self.q)
        if len(self.points) != n or len(self.pixels) != n:
            raise InputError(f"{n} stations but {len(self.points)} / {len(self.pixels)} "
                             "corner sets")
        counts = np.array([len(p) for p in self.points], dtype=np.intp)
        self.counts = counts
        self.sid = np.repeat(np.arange(n), counts).astype(np.intp)
        self.P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in self.points])
        self.uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in self.pixels])
        self.X0 = np.asarray(self.X0, float)
        self.Y0 = np.asarray(self.Y0, float)
        self.eye_in_hand = self.setup == "eye-in-hand"
        ends = np.cumsum(counts)
        self._bounds = list(zip((ends - counts).tolist(), ends.tolist(), strict=True))
        self._equal = bool(n and np.all(counts == counts[0]))

    # ------------------------------------------------------------------ sizes and names
    @property
    def n_stations(self) -> int:
        """Number of stations."""
        return len(self.q)

    @property
    def n_corners(self) -> int:
        """Number of corners (each gives 2 residual rows)."""
        return len(self.P)

    @property
    def n_nuisance(self) -> int:
        """Length of the block's own parameter vector."""
        return 12 + self.n_int

    @property
    def nuisance_names(self) -> list[str]:
        """Names of the block's own parameters, in vector order."""
        return nuisance_names(self.setup, self.n_int)

    def nuisance_groups(self) -> dict[str, slice]:
        """``{"X": slice, "board": slice, "intrinsics": slice}`` into the nuisance vector."""
        out = {"X": slice(0, 6), "board": slice(6, 12)}
        if self.n_int:
            out["intrinsics"] = slice(12, 12 + self.n_int)
        return out

    # ------------------------------------------------------------------ model
    def unpack(self, nu: Array) -> tuple[Array, Array, Array, Array]:
        """X, Y ``(4, 4)``, K ``(3, 3)`` and the 8 distortion coefficients at `nu`."""
        nu = np.asarray(nu, float)
        X = transform_from(self.X0[:3, :3] @ matrix_from_axis_angle(nu[0:3]),
                           self.X0[:3, 3] + nu[3:6])
        Y = transform_from(self.Y0[:3, :3] @ matrix_from_axis_angle(nu[6:9]),
                           self.Y0[:3, 3] + nu[9:12])
        K, d = self.K, self.d8
        if self.n_int:
            K, d = with_intrinsics(self.K, self.d8, intrinsic_vector(self.K, self.d8,
                                                                      self.n_int == 12)
                                   + nu[12:12 + self.n_int])
        return X, Y, K, d

    def predict(self, params: Array, nu: Array, columns: Array | None = None,
                jac: bool = False, scale_column: bool = False, strict: bool = True
                ) -> tuple[Array, Array | None, Array | None]:
        """Predicted pixels and (optionally) their Jacobians.

        Parameters
        ----------
        params : ndarray, shape (n_params,)
            The arm's full parameter vector (length unit, rad).
        nu : ndarray, shape (n_nuisance,)
            The block's own parameters (increments, see the module docstring).
        columns : ndarray of int, optional
            Arm parameters (indices into `params`) to differentiate (default none).
        jac : bool
            Also return the Jacobians.
        scale_column : bool
            Append to the nuisance Jacobian the column of a uniform scale of the board
            (``P -> (1 + s) P``): the board's size as an unknown.
        strict : bool
            False: a corner behind the camera gives NaN pixels instead of the error (the
            residuals of stations judged after a fit that left them out).

        Returns
        -------
        uv : ndarray, shape (M, 2)
            Predicted pixels of every corner (M = total corners).
        J_arm : ndarray, shape (M, 2, k) or None
            Pixels per unit of the arm's parameters `columns` (px per length unit or rad).
        J_nu : ndarray, shape (M, 2, n_nuisance [+ 1]) or None
            Pixels per unit of the nuisance parameters.

        Raises
        ------
        InputError
            A corner behind the camera (the joints do not fit the images).
        """
        X, Y, K, d = self.unpack(nu)
        cols = np.zeros(0, np.intp) if columns is None else np.asarray(columns, np.intp)
        sw = self.model.sweep(self.q, params)
        RF, tF = sw.rotations, sw.positions
        RY, tY, RX, tX = Y[:3, :3], Y[:3, 3], X[:3, :3], X[:3, 3]
        w = self.P @ RY.T + tY  # board point in the base (in-hand) or flange (to-hand) frame
        # every station's board-to-camera map pc = Mc w + oc (camera frame)
        if self.eye_in_hand:  # pc = R_X^T (R_F^T (w - t_F) - t_X)
            Mc = RX.T @ np.swapaxes(RF, 1, 2)
            oc = -np.einsum("nij,nj->ni", Mc, tF) - RX.T @ tX
        else:  # pc = R_X^T (R_F w + t_F - t_X)
            Mc = RX.T @ RF
            oc = (tF - tX) @ RX
        pc = self._per_station(w, Mc, oc)
        behind = pc[:, 2] <= 0
        if np.any(behind):
            if strict:
                bad = int(self.sid[np.argmax(behind)])
                raise InputError(f"station {bad + 1}: the board is behind the camera for "
                                 "these joints and X: the joints do not fit the images (wrong "
                                 "--setup, joint order or unit?)")
            pc = np.where(behind[:, None], np.nan, pc)
        uv, Jp, Jint = project_jacobian(K, d, pc, rational=self.n_int == 12,
                                        jacobians=jac, intrinsics=self.n_int > 0)
        if not jac:
            return uv, None, None
        A = self._stations_times(Jp, Mc)  # d uv / d w = Jp Mc
        return uv, self._arm_jacobian(sw, cols, Jp, A, w, tF, RX), \
            self._nuisance_jacobian(nu, Jp, Jint, A, pc, RX, RY, scale_column)

    def _per_station(self, v: Array, R: Array, o: Array | None = None) -> Array:
        """``R_s v_c (+ o_s)`` ``(M, 3)`` for every corner c of station s, one matrix
        product per station (faster than gathering ``(M, 3, 3)`` per-corner copies)."""
        if self._equal:  # one batched product (a grid board: every station sees all)
            n = len(self._bounds)
            out = (v.reshape(n, -1, 3) @ np.swapaxes(R, 1, 2))
            if o is not None:
                out += o[:, None, :]
            return out.reshape(-1, 3)
        out = np.empty_like(v)
        for i, (a, b) in enumerate(self._bounds):
            out[a:b] = v[a:b] @ R[i].T
            if o is not None:
                out[a:b] += o[i]
        return out

    def _stations_times(self, H: Array, G: Array) -> Array:
        """``H_c G_s`` ``(M, r, q)`` for the corner blocks `H` ``(M, r, k)`` and the station
        matrices `G` ``(n, k, q)``."""
        M, r, k = H.shape
        if self._equal:
            n = len(self._bounds)
            return (H.reshape(n, -1, k) @ G).reshape(M, r, -1)
        out = np.empty((M, r, G.shape[2]))
        for i, (a, b) in enumerate(self._bounds):
            out[a:b] = (H[a:b].reshape(-1, H.shape[2]) @ G[i]).reshape(b - a, r, -1)
        return out

    def _arm_jacobian(self, sw, cols: Array, Jp: Array, A: Array, w: Array, tF: Array,
                      RX: Array) -> Array:
        """Pixels per unit of the arm's parameters `cols` ``(M, 2, k)``: per corner
        ``d uv / d(t_F, phi_F)`` (module docstring), times each station's pose Jacobian."""
        M = len(w)
        if not cols.size:
            return np.zeros((M, 2, 0))
        H = np.empty((M, 2, 6))
        if self.eye_in_hand:  # d uv = A [w - t_F]x dphi - A dt, A = Jp R_X^T R_F^T
            H[:, :, :3] = -A
            H[:, :, 3:] = _cross_rows(A, w - tF[self.sid])
        else:  # d uv = -JpR [R_F w]x dphi + JpR dt, JpR = Jp R_X^T
            JpR = (Jp.reshape(-1, 3) @ RX.T).reshape(M, 2, 3)
            Rw = self._per_station(w, sw.rotations)
            H[:, :, :3] = JpR
            H[:, :, 3:] = -_cross_rows(JpR, Rw)
        G = np.transpose(sw.jacobian_t("pose", columns=cols), (2, 1, 0))  # (n, 6, k)
        return self._stations_times(H, G)

    def _nuisance_jacobian(self, nu: Array, Jp: Array, Jint: Array | None, A: Array,
                           pc: Array, RX: Array, RY: Array, scale_column: bool) -> Array:
        """Pixels per unit of X, the board pose and the intrinsics (module docstring)."""
        M = len(pc)
        J = np.empty((M, 2, self.n_nuisance + (1 if scale_column else 0)))
        # v^T [a]x = (v x a)^T: the rows of Jp [pc]x are Jp's rows crossed with pc
        J[:, :, 0:3] = (_cross_rows(Jp, pc).reshape(-1, 3)
                        @ _jr_of(nu[0:3])).reshape(M, 2, 3)
        J[:, :, 3:6] = (Jp.reshape(-1, 3) @ -RX.T).reshape(M, 2, 3)
        AR = (A.reshape(-1, 3) @ RY).reshape(M, 2, 3)
        J[:, :, 6:9] = (-_cross_rows(AR, self.P).reshape(-1, 3)
                        @ _jr_of(nu[6:9])).reshape(M, 2, 3)
        J[:, :, 9:12] = A
        if self.n_int:
            J[:, :, 12:12 + self.n_int] = Jint
        if scale_column:
            J[:, :, -1] = np.einsum("mij,mj->mi", A, self.P @ RY.T)
        return J

    def residuals(self, params: Array, nu: Array, strict: bool = True) -> Array:
        """Predicted minus observed pixels ``(M, 2)`` (NaN behind the camera unless
        `strict`)."""
        return self.predict(params, nu, strict=strict)[0] - self.uv

    def station_rms(self, r: Array) -> Array:
        """RMS corner residual ``(n,)`` per station (px) of residuals `r` ``(M, 2)``;
        infinite for a station with a corner behind the camera (NaN residuals)."""
        ss = np.bincount(self.sid, weights=np.sum(r * r, axis=1), minlength=self.n_stations)
        rms = np.sqrt(ss / np.maximum(self.counts, 1))
        return np.where(np.isfinite(rms), rms, np.inf)
