"""Hand-eye calibration of arms whose flange turns about one axis only (SCARA, 4-axis
palletising arms): Ulrich & Steger (2016), "Hand-eye calibration of SCARA robots using dual
quaternions", Pattern Recognition and Image Analysis 26(1), 231-239, on Daniilidis (1999)
(`kinecal.calibration.handeye.axxb.daniilidis`).

The derivation below is kinecal's, numbered (S1)-(S8) here (not the paper's equation
numbers); Ulrich & Steger's result is (S5), the rank deficiency of Daniilidis's matrix for
one-axis motions and its null space, and the idea of (S8), the height from outside the
data. Daniilidis's own equation numbers are cited as his.

(S1) ``G_i X C_i = Y`` (`kinecal.calibration.handeye`): G_i maps a moving frame m (the flange
    eye-in-hand, the base eye-to-hand) into a fixed frame f (the base, the flange).
(S2) One-axis data: every relative motion ``A = G_j^-1 G_i`` turns about one direction
    ``k_m`` (frame m); then ``R_Gi k_m = k_f`` is the same direction for every station.
(S3) Hence ``G_i T(s k_m) = T(s k_f) G_i``: ``(T(s k_m) X, T(s k_f) Y)`` fits every station
    exactly as ``(X, Y)`` does, for any s. The translation of X along the axis (and of Y along
    it, in step) is unobservable; everything else is determined as long as the motions'
    screw axes do not all coincide (a flange that only turns in place leaves X's rotation
    about the axis unobservable too).
(S4) Each motion gives Daniilidis's six screw equations ``S_k (q, q') = 0`` (his eq. (31)),
    stacked into T (his eq. (33)), q the rotation and ``q' = 1/2 t q`` the dual part of X.
(S5) For one-axis data T has rank 5 instead of 6 (Ulrich & Steger): its null space is
    ``span{(q, q'), (0, q), (0, k q)}``, the third vector being the shift of (3).
(S6) The real parts of the null space are therefore all multiples of q: q is the principal
    direction of the real block of the three right singular vectors of smallest singular
    value.
(S7) With q known, the dual rows of (S4) are linear in t; with t restricted to the plane
    normal to ``k_m`` (the component (3) leaves free is set to zero) they are two unknowns
    solved by least squares.
(S8) The missing component comes from outside the data: a stated camera height
    ``k_m . t_X = h``, or a board contact, a point P (frame f) of the board's printed plane
    touched by the tool: ``n_Y . (P - t_Y - s k_f) = 0`` with ``n_Y`` the board normal gives
    s. Without either, ``k_m . t_X = 0`` (the camera at the flange's height) with the
    ``handeye-one-axis`` warning.

Lengths in the motions' own length per radian, as `axxb.daniilidis` (weighs the rotation
rows of T against the translation rows). The LM refinement of the result
(`kinecal.calibration.handeye.refine.lm`) moves along no null direction, and (8) is imposed
again after it; the covariance of X is taken under the constraint of (8)
(`constrained_uncertainty`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.calibration.handeye._motions import (
    MIN_ANGLE,
    finish,
    motion_pairs,
    motion_quaternions,
    qmat_left,
    qmat_right,
)
from kinecal.errors import InputError
from kinecal.spatial import invert_transform, matrix_from_quaternion

Array = NDArray[np.float64]

__all__ = ["MAX_LENGTH", "ONE_AXIS_DEG", "AxisHeight", "OneAxis", "constrained_uncertainty",
           "detect_one_axis", "solve_one_axis", "ulrich_steger"]

#: robot rotation axes within this angle of one another (deg) count as one axis: the
#: translation along it would be known to no better than the noise / this angle
ONE_AXIS_DEG = 0.05
#: a board plane closer than this to parallel with the axis cannot fix the height (deg)
MIN_CONTACT_DEG = 10.0
#: largest |camera_height| and board_contact coordinate (length unit): 1e9 mm is 1000 km;
#: beyond, the heights overflow the solution (1e308 ended in a LinAlgError)
MAX_LENGTH = 1e9


@dataclass
class OneAxis:
    """The one rotation axis of a data set (S2).

    Attributes
    ----------
    moving : ndarray, shape (3,)
        ``k_m``: unit axis in the moving frame of G (flange eye-in-hand, base eye-to-hand).
    fixed : ndarray, shape (3,)
        ``k_f = R_Gi k_m``: the axis in the fixed frame (base eye-in-hand, flange
        eye-to-hand).
    spread_deg : float
        How far the robot's rotation axes spread (deg; 0 for exact one-axis data).
    setup : str
        ``eye-in-hand`` or ``eye-to-hand``. Both axes are oriented like the base frame's
        axis, whose largest coordinate is positive (+z for an upright SCARA).
    """

    moving: Array
    fixed: Array
    spread_deg: float
    setup: str

    @property
    def base(self) -> Array:
        """The axis in the robot's base frame."""
        return self.fixed if self.setup == "eye-in-hand" else self.moving

    def shift(self, X: Array, Y: Array, s: float) -> tuple[Array, Array]:
        """``(T(s k_m) X, T(s k_f) Y)``: the solution moved along the unobservable
        direction (S3)."""
        X2, Y2 = X.copy(), Y.copy()
        X2[:3, 3] += s * self.moving
        Y2[:3, 3] += s * self.fixed
        return X2, Y2

    def heights(self, X: Array, Y: Array) -> tuple[float, float]:
        """``(k_m . t_X, k_f . t_Y)``: the camera's and the board origin's position along
        the axis (length unit)."""
        return float(self.moving @ X[:3, 3]), float(self.fixed @ Y[:3, 3])


@dataclass
class AxisHeight:
    """What fixes the unobservable component (S8).

    Attributes
    ----------
    camera_height : float or None
        ``k_m . t_X``: the camera centre's position along the axis in X's parent frame
        (eye-in-hand: its offset from the flange origin; eye-to-hand: its height in the
        base frame), length unit of the poses.
    board_contact : ndarray, shape (3,) or None
        A point of the board's printed plane in the fixed frame (eye-in-hand: base frame,
        e.g. the tool tip's position when it touches the board; eye-to-hand: flange frame).
    """

    camera_height: float | None = None
    board_contact: Array | None = None

    @classmethod
    def from_options(cls, camera_height: float | None,
                     board_contact: ArrayLike | None) -> AxisHeight:
        """Validated from the keyword arguments (at most one of the two)."""
        if camera_height is not None and board_contact is not None:
            raise InputError("give camera_height or board_contact, not both",
                             option="camera_height")
        if camera_height is not None:
            h = float(camera_height)
            if not abs(h) <= MAX_LENGTH:
                raise InputError(f"camera_height {camera_height!r}: expected a finite length "
                                 f"within +-{MAX_LENGTH:g}", option="camera_height")
            return cls(camera_height=h)
        if board_contact is not None:
            try:
                P = np.asarray(board_contact, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                P = np.zeros(0)
            if P.shape != (3,) or not np.all(np.abs(P) <= MAX_LENGTH):
                raise InputError(f"board_contact {board_contact!r}: expected three finite "
                                 f"coordinates x, y, z within +-{MAX_LENGTH:g}",
                                 option="board_contact")
            return cls(board_contact=P)
        return cls()

    @property
    def given(self) -> bool:
        """True when either quantity was stated."""
        return self.camera_height is not None or self.board_contact is not None

    @property
    def source(self) -> str:
        """``camera-height``, ``board-contact`` or ``none``."""
        if self.camera_height is not None:
            return "camera-height"
        return "board-contact" if self.board_contact is not None else "none"

    def place(self, axis: OneAxis, X: Array, Y: Array) -> tuple[Array, Array]:
        """X and Y moved along the axis so that (S8) holds."""
        if self.board_contact is not None:
            n = Y[:3, 2]
            c = float(n @ axis.fixed)
            if abs(c) < np.sin(np.radians(MIN_CONTACT_DEG)):
                raise InputError(
                    f"the board plane is within {np.degrees(np.arcsin(abs(c))):.1f} deg of "
                    "parallel to the robot's rotation axis: a contact point cannot fix the "
                    "height along it; give camera_height (--camera-height) instead",
                    option="board_contact")
            s = float(n @ (self.board_contact - Y[:3, 3])) / c
        else:
            target = 0.0 if self.camera_height is None else self.camera_height
            s = target - float(axis.moving @ X[:3, 3])
        return axis.shift(X, Y, s)

    def constraint(self, axis: OneAxis, Y: Array) -> Array:
        """Row ``(12,)`` of the linearised (S8) in the refinement's parameters
        ``(omega_X, v_X, omega_Y, v_Y)`` (`refine.residual_jacobian`)."""
        c = np.zeros(12)
        if self.board_contact is None:
            c[3:6] = axis.moving
            return c
        d = Y[:3, :3].T @ (self.board_contact - Y[:3, 3])
        c[6:9] = np.cross([0.0, 0.0, 1.0], d)  # n(omega) = R_Y Exp(omega) e3
        c[9:12] = -Y[:3, 2]
        return c


def detect_one_axis(G: Array, setup: str, limit_deg: float = ONE_AXIS_DEG) -> OneAxis | None:
    """The common rotation axis of the robot motions (S2), or None when they turn about
    several axes (or do not turn at all: `_motions.check_motions` reports that).

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand).
    setup : {"eye-in-hand", "eye-to-hand"}
    limit_deg : float
        Largest spread of the rotation axes still counted as one axis.
    """
    A = invert_transform(G[:1]) @ G[1:]
    R = A[:, :3, :3]
    m = len(R)
    M = 2.0 * m * np.eye(3) - (R.sum(axis=0) + R.sum(axis=0).T)
    lam, V = np.linalg.eigh(M)
    if lam[-1] <= m * MIN_ANGLE**2:
        return None
    spread = float(np.degrees(np.arcsin(min(np.sqrt(max(lam[0], 0.0) / lam[-1]), 1.0))))
    if spread > limit_deg:
        return None
    km = V[:, 0]
    kf = (G[:, :3, :3] @ km).mean(axis=0)
    kf /= np.linalg.norm(kf)
    base = kf if setup == "eye-in-hand" else km
    sign = 1.0 if base[np.argmax(np.abs(base))] > 0 else -1.0
    return OneAxis(sign * km, sign * kf, spread, setup)


def _aligned(A: Array, B: Array, k: Array) -> tuple[Array, Array, Array, Array]:
    """Unit quaternions of A and B with matching signs, and their dual parts.

    ``w >= 0`` for both (`motion_quaternions`) agrees except near 180 deg, where noise
    decides the sign of w; with every rotation about k (and about the camera's own axis
    ``k_B``) the vector parts must point the same way along their axes, which fixes it."""
    qa, qb = motion_quaternions(A, B)
    va, vb = qa[:, 1:] @ k, qb[:, 1:]
    kb = np.linalg.eigh(vb.T @ vb)[1][:, -1]
    if np.sum(va * (vb @ kb)) < 0:
        kb = -kb
    flip = np.sign(va) * np.sign(vb @ kb) < 0
    qb = np.where(flip[:, None], -qb, qb)
    ta = np.concatenate([np.zeros((len(A), 1)), A[:, :3, 3]], axis=1)
    tb = np.concatenate([np.zeros((len(B), 1)), B[:, :3, 3]], axis=1)
    da = 0.5 * np.einsum("kij,kj->ki", qmat_left(ta), qa)  # q' = 1/2 t q
    db = 0.5 * np.einsum("kij,kj->ki", qmat_left(tb), qb)
    return qa, qb, da, db


def ulrich_steger(A: Array, B: Array, k: Array) -> Array:
    """X from one-axis motions, its translation along the axis set to zero (eqs. (4)-(7)).

    Parameters
    ----------
    A, B : ndarray, shape (m, 4, 4)
        Motions with ``A_k X = X B_k`` (length unit L), every ``A_k`` turning about `k`.
    k : ndarray, shape (3,)
        The axis ``k_m`` (`detect_one_axis`).

    Returns
    -------
    ndarray, shape (4, 4)
        X with ``k . t_X = 0`` (translation in L).
    """
    from kinecal.calibration.handeye.axxb import _length_per_radian

    L = _length_per_radian(A, B)
    As, Bs = A.copy(), B.copy()
    As[:, :3, 3] /= L
    Bs[:, :3, 3] /= L
    qa, qb, da, db = _aligned(As, Bs, k)
    # (S4): vector parts of a x - x b, rows of Daniilidis's S (his eq. (31)) per motion
    D0 = (qmat_left(qa) - qmat_right(qb))[:, 1:]
    D1 = (qmat_left(da) - qmat_right(db))[:, 1:]
    S = np.zeros((len(A), 6, 8))
    S[:, :3, :4] = D0
    S[:, 3:, :4] = D1
    S[:, 3:, 4:] = D0
    _, _, Vt = np.linalg.svd(S.reshape(-1, 8), full_matrices=False)
    # eqs. (5)-(6): the three-dimensional null space; its real parts span q
    U, _, _ = np.linalg.svd(Vt[5:, :4].T)
    q = U[:, 0] * (1.0 if U[0, 0] >= 0 else -1.0)
    q /= np.linalg.norm(q)
    # (S7): D0 q' = -D1 q with q' = 1/2 (0, t) q = 1/2 R(q) (0, t), t = E c, E normal to k
    E = np.linalg.svd(k.reshape(1, 3))[2][1:].T  # (3, 2) orthonormal basis of k's normal
    dq_dt = 0.5 * qmat_right(q)[:, 1:]  # (4, 3): q' for a unit t
    M = (D0 @ dq_dt @ E).reshape(-1, 2)
    rhs = (-D1 @ q).reshape(-1)
    c = np.linalg.lstsq(M, rhs, rcond=None)[0]
    return finish(matrix_from_quaternion(q), (E @ c) * L)


def solve_one_axis(G: Array, C: Array, axis: OneAxis) -> tuple[Array, Array]:
    """X (``k_m . t_X = 0``) and the target pose Y from one-axis stations (S1).

    Raises
    ------
    InputError
        The motions' screw axes all coincide (the flange only turns in place): X's rotation
        about the axis is unobservable as well.
    """
    from kinecal.calibration.handeye.errors import mean_target_pose

    A, B = motion_pairs(G, C, "all")
    _check_screw_axes(A, axis.moving)
    X = ulrich_steger(A, B, axis.moving)
    return X, mean_target_pose(G, X, C)


def _check_screw_axes(A: Array, k: Array) -> None:
    """`InputError` when every motion is a screw about one line along k ((S3), last
    case): some point p then has ``(I - R) p = t - (t . k) k`` for every motion."""
    R, t = A[:, :3, :3], A[:, :3, 3]
    rhs = (t - np.outer(t @ k, k)).reshape(-1)
    M = (np.eye(3) - R).reshape(-1, 3)
    p = np.linalg.lstsq(M, rhs, rcond=None)[0]
    miss = float(np.sqrt(np.mean((M @ p - rhs) ** 2)))
    if miss > 1e-9 * max(float(np.sqrt(np.mean(t**2))), 1e-300):
        return
    raise InputError("degenerate robot motions: all rotations are about one axis and about "
                     "one line along it (the flange only turns in place), so X's rotation "
                     "about that axis is unobservable as well as its height along it; move "
                     "the arm's other joints between stations (a SCARA's shoulder and elbow)")


def constrained_uncertainty(G: Array, C: Array, X: Array, Y: Array, row: Array,
                            axis: OneAxis, inliers: Array | None = None) -> Any:
    """First-order uncertainty of X under the height constraint (S8).

    As `kinecal.calibration.diagnostics.handeye.handeye_uncertainty`, with the 12 unknowns
    restricted to the hyperplane ``row . p = 0`` (the null direction of (S3) removed).
    The anisotropy and weak direction are those of the translation across the axis.

    Returns
    -------
    XUncertainty or None
        None for noise-free data or too few stations.
    """
    from kinecal.calibration.diagnostics.handeye import UNKNOWNS, XUncertainty
    from kinecal.calibration.handeye.refine import camera_residuals, residual_jacobian

    if inliers is not None:
        G, C = G[inliers], C[inliers]
    n = len(G)
    free = UNKNOWNS - 1
    if 6 * n <= free:
        return None
    rot, tr = camera_residuals(G, C, X, Y)
    sr = float(np.sqrt(np.mean(rot**2)))
    st = float(np.sqrt(np.mean(tr**2)))
    L = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    if not (sr > 1e-12 and st > 1e-12 * max(L, 1e-300)):
        return None
    J = residual_jacobian(G, C, X, Y, np.zeros(UNKNOWNS))
    scale = np.r_[[1.0 / sr] * 3, [1.0 / st] * 3]
    Js = (J * scale[None, :, None]).reshape(-1, UNKNOWNS)
    r = np.concatenate([rot / sr, tr / st], axis=1).ravel()
    N = np.linalg.svd(row.reshape(1, -1))[2][1:].T  # (12, 11): directions keeping row . p = 0
    H = N.T @ Js.T @ Js @ N
    cov = float(r @ r) / (6 * n - free) * N @ np.linalg.inv(H) @ N.T
    wr = np.clip(np.linalg.eigvalsh(cov[:3, :3]), 0.0, None)
    E = np.linalg.svd(axis.moving.reshape(1, 3))[2][1:].T
    wt, vt = np.linalg.eigh(E.T @ cov[3:6, 3:6] @ E)
    wt = np.clip(wt, 0.0, None)

    def ratio(w: Array) -> float:
        return float(np.sqrt(w[-1] / w[0])) if w[0] > 0 else float("inf")

    return XUncertainty(float(np.degrees(np.sqrt(wr.sum()))),
                        float(np.sqrt(max(np.trace(cov[3:6, 3:6]), 0.0))), E @ vt[:, -1],
                        float(np.sqrt(wt[-1])), ratio(wt), ratio(wr))
