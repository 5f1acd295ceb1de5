"""The noise of hand-eye stations: how the camera's and the robot's errors enter a station's
residual, and their sizes estimated from the stations themselves.

Station i's residual (`kinecal.calibration.handeye.refine.camera_residuals`, camera frame)
is ``r_i = (log(R^_i^T R_Ci), t_Ci - t^_i)`` with the predicted board pose
``C^_i = X^-1 G_i^-1 Y``. Two instruments put noise into it:

- the **camera** (board pose ``C_i E_c``, a rotation ``w_c`` and a translation ``v_c`` about
  the board's own frame, where the errors of a planar board's pose stay small): ``dr =
  (J_r^-1(r_rot) w_c, R_C v_c)``;
- the **robot** (flange pose ``flange2base_i E_r``, a rotation ``w_r`` and a translation
  ``v_r`` in the flange frame). A flange rotation swings the board about the flange, so its
  effect on the residual's translation grows with the lever from the flange to the board
  (400 mm away, 0.01 deg is 0.07 mm). With the prediction written ``A E_r^s B``
  (eye-in-hand ``A = X^-1``, ``B = G_i^-1 Y``, ``s = -1``; eye-to-hand ``A = X^-1
  G_i^-1``, ``B = Y``, ``s = +1``): ``dr = (-s J_l^-1(r_rot) R_B^T w_r, s R_A [t_B]x w_r
  - s R_A v_r)``.

Each translation error adds an isotropic covariance to the residual's translation, so the
station covariance has three components,

    Sigma_i = s_cr^2 V_cr,i + s_t^2 V_t + s_rr^2 V_rr,i,

the camera's rotation, the translation (camera and robot together: their shapes are the
same) and the robot's rotation with its lever. `estimate_components` estimates
``(s_cr^2, s_t^2, s_rr^2)`` from the residuals by restricted maximum likelihood (Fisher
scoring on the variance components of the linearised problem: Koch, *Parameter Estimation
and Hypothesis Testing in Linear Models*, 1999, sec. 3.6; the iteration is that of
Harville 1977, J. Amer. Statist. Assoc. 72, 320-338), the way the stacked calibration
estimates the noise of each measurement kind (`kinecal.calibration.blocks.weights`). With
robot poses read exactly the robot component goes to zero and the weighting is the
camera's alone; with the robot's noise dominating, the lever's covariance weights the
stations as the relative-motion closed forms implicitly do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.residuals import _jr_inv
from kinecal.spatial import skew

Array = NDArray[np.float64]

__all__ = ["COMPONENTS", "StationNoise", "covariances", "estimate_components",
           "reml_loglik", "score_and_information", "station_components", "whitening"]

#: the components' names, in the order of ``theta``
COMPONENTS = ("camera_rotation", "translation", "robot_rotation")


@dataclass
class StationNoise:
    """The noise model of the stations (standard deviations per axis).

    Attributes
    ----------
    theta : ndarray, shape (3,)
        Variances ``(s_cr^2 rad^2, s_t^2 length^2, s_rr^2 rad^2)`` (`COMPONENTS`).
    source : str
        ``"estimated"`` (from the station residuals), ``"rotation_weight"`` (the caller's
        fixed weighting, no robot component) or ``"scales"`` (robust scales of the
        residuals, no robot component: too few stations to estimate three).
    """

    theta: Array
    source: str = "estimated"

    @property
    def std(self) -> Array:
        """``(s_cr rad, s_t length, s_rr rad)``."""
        return np.sqrt(np.clip(self.theta, 0.0, None))

    def to_dict(self) -> dict[str, Any]:
        """``{"source", "camera_rotation_deg", "translation", "robot_rotation_deg"}``."""
        s = self.std
        return {"source": self.source, "camera_rotation_deg": float(np.degrees(s[0])),
                "translation": float(s[1]), "robot_rotation_deg": float(np.degrees(s[2]))}

    def describe(self, unit: str = "") -> str:
        """One line: the components and where they came from."""
        s = self.std
        how = {"estimated": "estimated from the station residuals",
               "rotation_weight": "fixed by the rotation weight",
               "scales": "robust scales of the residuals"}[self.source]
        u = f" {unit}" if unit else ""
        return (f"station noise ({how}): camera rotation {np.degrees(s[0]):.3g} deg, "
                f"translation {s[1]:.3g}{u}, robot rotation {np.degrees(s[2]):.3g} deg")


def station_components(G: Array, C: Array, X: Array, Y: Array, rot: Array,
                       eye_in_hand: bool = True) -> Array:
    """The components ``V_k,i`` of every station's residual covariance (module docstring).

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand).
    C : ndarray, shape (n, 4, 4)
        ``target2cam``.
    X, Y : ndarray, shape (4, 4)
        Hand-eye transform and target pose.
    rot : ndarray, shape (n, 3)
        Rotation residuals at X, Y (rad).
    eye_in_hand : bool

    Returns
    -------
    ndarray, shape (3, n, 6, 6)
        Camera rotation (rad^-2 scale), translation, robot rotation.
    """
    n = len(G)
    V = np.zeros((3, n, 6, 6))
    Jl = np.swapaxes(_jr_inv(rot), 1, 2)  # J_l^-1 = J_r^-1 transposed
    V[0, :, :3, :3] = np.swapaxes(Jl, 1, 2) @ Jl  # J_r^-1 J_r^-T
    V[1, :, 3:, 3:] = np.eye(3)
    V[2] = _robot_rotation(G, C, X, Y, Jl, eye_in_hand) @ np.swapaxes(
        _robot_rotation(G, C, X, Y, Jl, eye_in_hand), 1, 2)
    return V


def _robot_rotation(G: Array, C: Array, X: Array, Y: Array, Jl: Array,
                    eye_in_hand: bool) -> Array:
    """``d r / d w_r`` ``(n, 6, 3)``: the residual per flange rotation."""
    RG, tG = G[:, :3, :3], G[:, :3, 3]
    RX = X[:3, :3]
    if eye_in_hand:  # A = X^-1, B = G^-1 Y, s = -1
        s = -1.0
        RB = np.swapaxes(RG, 1, 2) @ Y[:3, :3]
        tB = np.einsum("nji,nj->ni", RG, Y[:3, 3] - tG)
        RA = np.broadcast_to(RX.T, RG.shape)
    else:  # A = X^-1 G^-1, B = Y, s = +1
        s = 1.0
        RB = np.broadcast_to(Y[:3, :3], RG.shape)
        tB = np.broadcast_to(Y[:3, 3], tG.shape)
        RA = RX.T @ np.swapaxes(RG, 1, 2)
    J = np.empty((len(G), 6, 3))
    J[:, :3] = -s * (Jl @ np.swapaxes(RB, 1, 2))
    J[:, 3:] = s * (RA @ skew(tB))
    return J


def covariances(theta: Array, V: Array, floor: Array) -> Array:
    """``Sigma_i = sum_k theta_k V_k,i + diag(floor)`` ``(n, 6, 6)``; `floor` ``(6,)`` keeps
    exact readings (a component at zero) invertible."""
    return np.einsum("k,knij->nij", theta, V) + np.diag(floor)


def whitening(theta: Array, V: Array, floor: Array) -> Array:
    """``L_i^-1`` ``(n, 6, 6)`` with ``L_i L_i^T = Sigma_i``: ``L_i^-1 r_i`` has unit
    covariance."""
    L = np.linalg.cholesky(covariances(theta, V, floor))
    return np.linalg.inv(L)


def estimate_components(y: Array, J: Array, V: Array, theta: Array, floor: Array,
                        fixed: tuple[int, ...] = (), max_iter: int = 30,
                        tol: float = 1e-4) -> Array:
    """Variance components by REML on the linearised problem ``y_i = J_i p + e_i``.

    Parameters
    ----------
    y : ndarray, shape (n, 6)
        Residuals at the current solution (any sign: only their quadratic forms count).
    J : ndarray, shape (n, 6, p)
        Their Jacobian with respect to the ``p`` unknowns (X and Y: 12).
    V : ndarray, shape (k, n, 6, 6)
        Components (`station_components`).
    theta : ndarray, shape (k,)
        Start (positive where the component may be estimated).
    floor : ndarray, shape (6,)
        Diagonal kept in every covariance (`covariances`).
    fixed : tuple of int
        Components held at their start.
    max_iter : int
        Fisher-scoring steps at most.
    tol : float
        Stop when every component changed by less than this fraction of the largest
        variance of its unit (rotation or length).

    Returns
    -------
    ndarray, shape (k,)
        Non-negative variances.
    """
    theta = np.asarray(theta, float).copy()
    k = len(theta)
    free = np.array([j not in fixed for j in range(k)])
    rot_like = np.array([j != 1 for j in range(k)])
    for _ in range(max_iter):
        g, F = score_and_information(y, J, V, theta, floor)
        step = np.zeros(k)
        idx = np.flatnonzero(free)
        Fs = F[np.ix_(idx, idx)]
        d = np.sqrt(np.clip(np.diag(Fs), 1e-300, None))
        if not (np.all(np.isfinite(Fs)) and np.all(np.isfinite(g))):
            return theta  # components gone beyond what the stations can bound: keep the last
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                step[idx] = np.linalg.solve(Fs / np.outer(d, d), g[idx] / d) / d
        except np.linalg.LinAlgError:
            return theta
        new = np.maximum(theta + step, 0.1 * theta)
        if not np.all(np.isfinite(new)):  # a step the information cannot bound: stop here
            return theta
        scale = np.where(rot_like, max(new[rot_like].max(), 1e-300), max(new[1], 1e-300))
        done = np.all(np.abs(new - theta) <= tol * scale)
        theta = new
        if done:
            break
    return theta


def score_and_information(y: Array, J: Array, V: Array, theta: Array, floor: Array
                          ) -> tuple[Array, Array]:
    """The restricted log-likelihood's gradient ``(k,)`` in the components and its Fisher
    information ``(k, k)`` at `theta` (`estimate_components`' arguments): ``g_a = (v^T W
    V_a W v - tr(P V_a)) / 2``, ``F_ab = tr(P V_a P V_b) / 2`` with ``P = W - W J (J^T W
    J)^+ J^T W``, every trace taken station by station."""
    k, q = len(theta), J.shape[2]
    W = np.linalg.inv(covariances(theta, V, floor))
    B = W @ J  # (n, 6, q)
    Ni = _scaled_pinv(J.reshape(-1, q).T @ B.reshape(-1, q))
    p = Ni @ (B.reshape(-1, q).T @ y.ravel())
    v = y - J @ p
    Wv = (W @ v[..., None])[..., 0]
    WV = W[None] @ V  # (k, n, 6, 6)
    BtV = np.swapaxes(B, 1, 2)[None] @ V  # (k, n, q, 6)
    BtVB = (BtV @ B[None]).sum(axis=1)  # (k, q, q)
    NB = Ni[None] @ BtVB  # (k, q, q)
    quad = ((V @ Wv[None, :, :, None])[..., 0] * Wv[None]).sum(axis=(1, 2))
    trPV = np.trace(WV, axis1=2, axis2=3).sum(axis=1) - np.trace(NB, axis1=1, axis2=2)
    g = 0.5 * (quad - trPV)
    t1 = WV.reshape(k, -1) @ np.swapaxes(WV, 2, 3).reshape(k, -1).T
    # tr(N^-1 B^T V_a W V_b B) summed over the stations
    t2 = ((Ni[None, None] @ BtV) @ W[None]).reshape(k, -1) @ BtV.reshape(k, -1).T
    t4 = NB.reshape(k, -1) @ np.swapaxes(NB, 1, 2).reshape(k, -1).T
    return g, 0.5 * (t1 - t2 - t2.T + t4)


def reml_loglik(y: Array, J: Array, V: Array, theta: Array, floor: Array) -> float:
    """The restricted log-likelihood (up to a constant) of the components `theta` on the
    linearised problem of `estimate_components`: ``-0.5 (log|Sigma| + log|J^T Sigma^-1 J|
    + v^T Sigma^-1 v)`` with ``v`` the generalised least-squares residual; twice the
    difference of two values is the likelihood-ratio statistic."""
    S = covariances(theta, V, floor)
    W = np.linalg.inv(S)
    q = J.shape[2]
    B = W @ J
    N = J.reshape(-1, q).T @ B.reshape(-1, q)
    d = np.sqrt(np.clip(np.diag(N), 1e-300, None))
    ev = np.linalg.eigvalsh(N / np.outer(d, d))
    ev = ev[ev > 1e-12 * ev.max()]
    p = _scaled_pinv(N) @ (B.reshape(-1, q).T @ y.ravel())
    v = y - J @ p
    quad = float(np.einsum("ni,ni->", v, (W @ v[..., None])[..., 0]))
    logdet = float(np.sum(np.linalg.slogdet(S)[1]))
    return -0.5 * (logdet + float(np.sum(np.log(ev)) + 2.0 * np.sum(np.log(d))) + quad)


def _scaled_pinv(N: Array) -> Array:
    """Pseudo-inverse of a symmetric ``N`` with its columns scaled to unit diagonal first
    (rotations and lengths in one matrix; a direction the stations do not see, as the
    height of one-axis robots, is left out rather than inverted)."""
    d = np.sqrt(np.clip(np.diag(N), 0.0, None))
    d = 1.0 / np.where(d > 0, d, 1.0)
    return d[:, None] * np.linalg.pinv(d[:, None] * N * d[None, :], rcond=1e-12,
                                       hermitian=True) * d[None, :]
