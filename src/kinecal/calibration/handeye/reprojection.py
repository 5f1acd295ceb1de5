"""The reprojection model of hand-eye calibration from images: predicted pixels of the
board corners of every station, and their analytic Jacobian (used by
`kinecal.calibration.handeye.images.refine_reprojection`; the cost follows Tabb & Ahmad
Yousef 2017, "reprojection error" variants, and Koide & Menegatti 2019).

The corner ``P`` of station i is predicted at ``project(K, d, X^-1 F_i^-1 Y P)`` eye-in-hand
and ``project(K, d, X^-1 F_i Y P)`` eye-to-hand (``F_i = flange2base_i``, `camera.project`).

The parameter vector holds increments: X rotation vector (right-multiplied, X frame) and
translation, Y likewise, then the free intrinsics, then the robot-pose corrections
``(rotation vector rad, translation)`` per station. The Jacobian uses the right Jacobians
of SO(3) and is tested against finite differences.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import (
    check_camera,
    intrinsic_vector,
    project_jacobian,
    with_intrinsics,
)
from kinecal.calibration.handeye.refine import _jr
from kinecal.errors import InputError
from kinecal.spatial import matrix_from_axis_angle, skew, transform_from

Array = NDArray[np.float64]

__all__ = ["ReprojectionProblem", "behind_camera", "parameter_names", "predict_blocks",
           "predict_corners", "predict_pixels", "unpack"]


@dataclass
class ReprojectionProblem:
    """Stacked corners of all stations and the fixed parts of the model (the free
    parameters are increments on X0, Y0 and the intrinsics, and robot corrections)."""

    F: Array  # (n, 4, 4) flange2base
    P: Array  # (M, 3) board points
    uv: Array  # (M, 2) observed pixels
    sid: NDArray[np.intp]  # (M,) station of each corner
    eye_in_hand: bool
    K0: Array
    d0: Array
    X0: Array
    Y0: Array
    n_int: int  # free intrinsics (0, 9 or 12)
    robot: tuple[float, float] | None
    #: a corner behind the camera raises; else its pixels are NaN (a refinement's trial step
    #: that swings a board behind the camera is rejected, not fatal)
    strict: bool = True

    @property
    def n(self) -> int:
        """Number of stations."""
        return len(self.F)

    @property
    def n_params(self) -> int:
        """Length of the free parameter vector."""
        return 12 + self.n_int + (6 * self.n if self.robot else 0)


def unpack(pr: ReprojectionProblem, p: Array
           ) -> tuple[Array, Array, Array, Array, Array | None]:
    """X, Y ``(4, 4)``, K ``(3, 3)``, dist ``(8,)`` and the robot-pose corrections ``(n, 6)``
    (None when not modelled) at the parameter vector `p` ``(n_params,)``."""
    X = transform_from(pr.X0[:3, :3] @ matrix_from_axis_angle(p[0:3]), pr.X0[:3, 3] + p[3:6])
    Y = transform_from(pr.Y0[:3, :3] @ matrix_from_axis_angle(p[6:9]), pr.Y0[:3, 3] + p[9:12])
    K, d = pr.K0, pr.d0
    if pr.n_int:
        K, d = with_intrinsics(pr.K0, pr.d0, intrinsic_vector(pr.K0, pr.d0, pr.n_int == 12)
                               + p[12:12 + pr.n_int])
    E = p[12 + pr.n_int:].reshape(-1, 6) if pr.robot else None
    return X, Y, K, d, E


def predict_pixels(pr: ReprojectionProblem, p: Array, jac: bool) -> tuple[Array, Array | None]:
    """Predicted pixels ``(M, 2)`` and (optionally) their Jacobian ``(M, 2, n_params)``.

    The dense Jacobian is put together from `predict_blocks` (for tests and small
    problems; the refinement uses the blocks)."""
    if not jac:
        return _predict(pr, p)[0], None
    uv, Jg, Je = predict_blocks(pr, p)
    if Je is None:
        return uv, Jg
    M, g = len(uv), Jg.shape[2]
    J = np.zeros((M, 2, pr.n_params))
    J[:, :, :g] = Jg
    cols = g + 6 * pr.sid[:, None] + np.arange(6)  # (M, 6): the corner's station columns
    J[np.arange(M)[:, None, None], np.arange(2)[None, :, None], cols[:, None, :]] = Je
    return uv, J


def predict_blocks(pr: ReprojectionProblem, p: Array) -> tuple[Array, Array, Array | None]:
    """Predicted pixels and the Jacobian in blocks (the corners' structure).

    Returns
    -------
    uv : ndarray, shape (M, 2)
    Jg : ndarray, shape (M, 2, 12 + n_int)
        With respect to the shared unknowns (X, Y, intrinsics).
    Je : ndarray, shape (M, 2, 6) or None
        With respect to the corner's own station correction (None when not modelled).
    """
    uv, (X, Y, E, pc, q, w, RE, dq_dw, Jp, Jint) = _predict(pr, p, blocks=True)
    s = pr.sid
    RF = pr.F[:, :3, :3]
    RY, RX = Y[:3, :3], X[:3, :3]
    M = len(pc)
    Jg = np.empty((M, 2, 12 + pr.n_int))

    def times(B: Array, R: Array) -> Array:  # (M, 2, 3) @ (3, 3) as one matrix product
        return (B.reshape(-1, 3) @ R).reshape(M, 2, 3)

    Jg[:, :, 0:3] = times(Jp @ skew(pc), _jr(p[0:3]))
    Jg[:, :, 3:6] = times(Jp, -RX.T)
    JpR = times(Jp, RX.T)  # d uv / d q
    A = JpR @ dq_dw[s]  # d uv / d w
    Jg[:, :, 6:9] = times(times(A, -RY) @ skew(pr.P), _jr(p[6:9]))
    Jg[:, :, 9:12] = A
    if pr.n_int:
        Jg[:, :, 12:12 + pr.n_int] = Jint
    if E is None:
        return uv, Jg, None
    jr = _jr(E[:, :3])  # (n, 3, 3)
    Je = np.empty((M, 2, 6))
    if pr.eye_in_hand:
        Je[:, :, :3] = JpR @ (skew(q) @ jr[s])
        Je[:, :, 3:] = JpR @ (-np.swapaxes(RE, 1, 2)[s])
    else:
        Je[:, :, :3] = JpR @ (-(RF @ RE)[s] @ skew(w) @ jr[s])
        Je[:, :, 3:] = JpR @ RF[s]
    return uv, Jg, Je


def _predict(pr: ReprojectionProblem, p: Array, blocks: bool = False) -> tuple[Array, tuple]:
    """Pixels ``(M, 2)`` and, with `blocks`, the intermediate values their Jacobian uses."""
    X, Y, K, d, E = unpack(pr, p)
    s = pr.sid
    RF, tF = pr.F[:, :3, :3], pr.F[:, :3, 3]
    RY, tY, RX, tX = Y[:3, :3], Y[:3, 3], X[:3, :3], X[:3, 3]
    w = pr.P @ RY.T + tY  # board point in the base (eye-in-hand) or flange frame
    if E is not None:
        RE = matrix_from_axis_angle(E[:, :3])
        tE = E[:, 3:]
    else:
        RE = np.broadcast_to(np.eye(3), (pr.n, 3, 3))
        tE = np.zeros((pr.n, 3))
    if pr.eye_in_hand:  # q = E^-1 F^-1 w
        z = np.einsum("mji,mj->mi", RF[s], w - tF[s])
        q = np.einsum("mji,mj->mi", RE[s], z - tE[s]) if E is not None else z
        dq_dw = np.swapaxes(RE, 1, 2) @ np.swapaxes(RF, 1, 2) if blocks else None
    else:  # q = F E w
        ew = np.einsum("mij,mj->mi", RE[s], w) + tE[s] if E is not None else w
        q = np.einsum("mij,mj->mi", RF[s], ew) + tF[s]
        dq_dw = RF @ RE if blocks else None
    pc = (q - tX) @ RX  # R_X^T (q - t_X)
    behind = pc[:, 2] <= 0
    if np.any(behind):
        if pr.strict:
            bad = np.unique(s[behind])
            raise InputError(f"station(s) {', '.join(str(int(i)) for i in bad[:5])}: board "
                             "behind the camera for the current X; the robot poses do not fit "
                             "the images (wrong setup or pose convention?)")
        pc = np.where(behind[:, None], np.nan, pc)
    if not blocks:
        return project_jacobian(K, d, pc, rational=pr.n_int == 12, jacobians=False)[0], ()
    uv, Jp, Jint = project_jacobian(K, d, pc, rational=pr.n_int == 12,
                                    intrinsics=pr.n_int > 0)  # none when held
    return uv, (X, Y, E, pc, q, w, RE, dq_dw, Jp, Jint)


def behind_camera(pr: ReprojectionProblem, p: Array) -> NDArray[np.bool_]:
    """Stations ``(n,)`` with a corner at or behind the camera at `p`."""
    lax = ReprojectionProblem(**{**pr.__dict__, "strict": False})
    pred = _predict(lax, p)[0]
    bad = ~np.isfinite(pred).all(axis=1)
    return np.bincount(pr.sid, weights=bad, minlength=pr.n) > 0


def predict_corners(flange2base: Array, points: list[Array], K: Array, dist: Array | None,
                    X: Array, Y: Array, setup: str = "eye-in-hand") -> list[Array]:
    """Predicted pixels of every station's board points (see the module docstring).

    Parameters
    ----------
    flange2base : ndarray, shape (n, 4, 4)
    points : list of ndarray, shape (N_i, 3)
        Board coordinates per station.
    K, dist
        Camera.
    X, Y : ndarray, shape (4, 4)
    setup : {"eye-in-hand", "eye-to-hand"}

    Returns
    -------
    list of ndarray, shape (N_i, 2)
    """
    K, d8 = check_camera(K, dist)
    sid = np.concatenate([np.full(len(p), i) for i, p in enumerate(points)]).astype(np.intp)
    P = np.concatenate(points)
    pr = ReprojectionProblem(np.asarray(flange2base, float), P, np.zeros((len(P), 2)), sid,
                  setup == "eye-in-hand", K, d8, X, Y, 0, None)
    uv, _ = predict_pixels(pr, np.zeros(12), False)
    return np.split(uv, np.cumsum([len(p) for p in points])[:-1])


def parameter_names(pr: ReprojectionProblem) -> list[str]:
    """Names of the free parameters, in vector order."""
    names = [f"X.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    names += [f"target.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    names += list(("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
                  [:pr.n_int])
    if pr.robot:
        for i in range(pr.n):
            names += [f"robot{i}.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    return names
