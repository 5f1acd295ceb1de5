"""Hand-eye refinement on the reprojection error of the board corners.

The most accurate published pipelines (Tabb & Ahmad Yousef 2017, "reprojection error"
variants; Koide & Menegatti 2019) refine X on the pixels rather than on the per-image board
poses: a board pose from one image is poorly determined along the line of sight, and a
pose-based cost weighs those errors wrongly. Here the unknowns are

- X (``cam2flange`` eye-in-hand, ``cam2base`` eye-to-hand) and the fixed board pose Y
  (``target2base`` eye-in-hand, ``target2flange`` eye-to-hand), always;
- optionally the camera intrinsics ``(fx, fy, cx, cy, k1, k2, p1, p2, k3[, k4, k5, k6])``;
- optionally a correction ``E_i`` of every reported robot pose (``flange2base_i E_i``, a
  rotation vector and a translation in the flange frame) with a zero-mean Gaussian prior of
  the given standard deviations (robot-pose noise modelled instead of ignored).

The corner ``P`` of station i is predicted at ``project(K, d, X^-1 F_i^-1 Y P)`` eye-in-hand
and ``project(K, d, X^-1 F_i Y P)`` eye-to-hand (``F_i = flange2base_i``, `camera.project`).
Residuals are predicted minus observed pixels divided by the corner noise sigma (estimated
robustly from the residuals). Robust mode: Huber loss per corner (3 sigma) and iteratively
reweighted stations (Cauchy weights on a station's RMS relative to the median station RMS);
stations whose RMS exceeds both the chi-square bound of pure corner noise and the robust
spread of the station RMS values (and three times their median, and the median + 0.25 px)
are flagged as outliers and left out of a final pass.

Every pass is scipy's trust-region least squares with the analytic Jacobian (right
Jacobians of SO(3); tested against finite differences). The covariance of the parameters
is ``s^2 (J^T J)^-1`` from the final pass.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.special import chdtri

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

__all__ = ["ReprojectionRefinement", "predict_corners", "refine_reprojection"]

_HUBER = 3.0
_CAUCHY = 2.5


@dataclass
class ReprojectionRefinement:
    """Result of `refine_reprojection`.

    Attributes
    ----------
    X, Y : ndarray, shape (4, 4)
        Refined hand-eye transform and board pose.
    K : ndarray, shape (3, 3)
    dist : ndarray, shape (8,)
        Intrinsics (refined when asked).
    corrections : ndarray, shape (n, 6) or None
        Estimated robot-pose corrections ``(rotation vector rad, translation)`` per station
        (flange frame), when robot noise was modelled.
    residuals : list of ndarray, shape (N_i, 2)
        Observed minus predicted corners per station (px), every station.
    station_rms : ndarray, shape (n,)
        RMS corner residual per station (px).
    outliers : list of int
        Stations left out of the final pass.
    sigma_px : float
        Corner noise (px per axis), robust estimate.
    cov : ndarray, shape (p, p)
        Covariance of the free parameters (order: X rotation, X translation, Y rotation,
        Y translation, intrinsics, corrections).
    names : list of str
        Names of the free parameters.
    nfev : int
    history : list of float
        Cost after each pass.
    seconds : float
    """

    X: Array
    Y: Array
    K: Array
    dist: Array
    corrections: Array | None
    residuals: list[Array]
    station_rms: Array
    outliers: list[int]
    sigma_px: float
    cov: Array
    names: list[str]
    nfev: int = 0
    history: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def X_cov(self) -> Array:
        """Covariance ``(6, 6)`` of X: rotation vector (rad, X frame), translation."""
        return self.cov[:6, :6]

    @property
    def X_std(self) -> tuple[Array, Array]:
        """Standard deviations of X: rotation (deg, about X's own axes) and translation."""
        d = np.sqrt(np.clip(np.diag(self.X_cov), 0.0, None))
        return np.degrees(d[:3]), d[3:]

    @property
    def Y_std(self) -> tuple[Array, Array]:
        """Standard deviations of the board pose: rotation (deg) and translation."""
        d = np.sqrt(np.clip(np.diag(self.cov[6:12, 6:12]), 0.0, None))
        return np.degrees(d[:3]), d[3:]

    @property
    def rms_px(self) -> float:
        """RMS corner residual over the inlier stations (px)."""
        keep = [r for i, r in enumerate(self.residuals) if i not in set(self.outliers)]
        allr = np.concatenate(keep) if keep else np.zeros((0, 2))
        return float(np.sqrt(np.mean(np.sum(allr**2, axis=1)))) if allr.size else 0.0


@dataclass
class _Problem:
    """Stacked corners of all stations and the fixed parts of the model."""

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

    @property
    def n(self) -> int:
        return len(self.F)

    @property
    def n_params(self) -> int:
        return 12 + self.n_int + (6 * self.n if self.robot else 0)


def _unpack(pr: _Problem, p: Array) -> tuple[Array, Array, Array, Array, Array | None]:
    X = transform_from(pr.X0[:3, :3] @ matrix_from_axis_angle(p[0:3]), pr.X0[:3, 3] + p[3:6])
    Y = transform_from(pr.Y0[:3, :3] @ matrix_from_axis_angle(p[6:9]), pr.Y0[:3, 3] + p[9:12])
    K, d = pr.K0, pr.d0
    if pr.n_int:
        K, d = with_intrinsics(pr.K0, pr.d0, intrinsic_vector(pr.K0, pr.d0, pr.n_int == 12)
                               + p[12:12 + pr.n_int])
    E = p[12 + pr.n_int:].reshape(-1, 6) if pr.robot else None
    return X, Y, K, d, E


def _model(pr: _Problem, p: Array, jac: bool) -> tuple[Array, Array | None]:
    """Predicted pixels ``(M, 2)`` and (optionally) their Jacobian ``(M, 2, n_params)``."""
    X, Y, K, d, E = _unpack(pr, p)
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
        q = np.einsum("mji,mj->mi", RE[s], z - tE[s])
        dq_dw = np.swapaxes(RE, 1, 2) @ np.swapaxes(RF, 1, 2)  # per station
    else:  # q = F E w
        ew = np.einsum("mij,mj->mi", RE[s], w) + tE[s]
        q = np.einsum("mij,mj->mi", RF[s], ew) + tF[s]
        dq_dw = RF @ RE
    pc = (q - tX) @ RX  # R_X^T (q - t_X)
    if np.any(pc[:, 2] <= 0):
        bad = int(s[np.argmax(pc[:, 2] <= 0)])
        raise InputError(f"station {bad}: board behind the camera for the current X; the "
                         "robot poses do not fit the images (wrong setup or pose convention?)")
    uv, Jp, Jint = project_jacobian(K, d, pc, rational=pr.n_int == 12)
    if not jac:
        return uv, None
    M = len(pc)
    J = np.zeros((M, 2, pr.n_params))
    J[:, :, 0:3] = Jp @ (skew(pc) @ _jr(p[0:3]))
    J[:, :, 3:6] = Jp @ (-RX.T)
    JpR = Jp @ RX.T  # d uv / d q
    A = JpR @ dq_dw[s]  # d uv / d w
    J[:, :, 6:9] = A @ (-RY @ skew(pr.P) @ _jr(p[6:9]))
    J[:, :, 9:12] = A
    if pr.n_int:
        J[:, :, 12:12 + pr.n_int] = Jint
    if E is not None:
        c0 = 12 + pr.n_int
        jr = _jr(E[:, :3])  # (n, 3, 3)
        if pr.eye_in_hand:
            dq_de = -np.swapaxes(RE, 1, 2)[s]
            dq_deps = skew(q) @ jr[s]
        else:
            dq_de = RF[s]
            dq_deps = -(RF @ RE)[s] @ skew(w) @ jr[s]
        blk_rot = JpR @ dq_deps  # (M, 2, 3)
        blk_tr = JpR @ dq_de
        rows = np.arange(M)
        for k in range(3):
            J[rows, :, c0 + 6 * s + k] = blk_rot[:, :, k]
            J[rows, :, c0 + 6 * s + 3 + k] = blk_tr[:, :, k]
    return uv, J


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
    pr = _Problem(np.asarray(flange2base, float), P, np.zeros((len(P), 2)), sid,
                  setup == "eye-in-hand", K, d8, X, Y, 0, None)
    uv, _ = _model(pr, np.zeros(12), False)
    return np.split(uv, np.cumsum([len(p) for p in points])[:-1])


def _param_names(pr: _Problem) -> list[str]:
    names = [f"X.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    names += [f"target.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    names += list(("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
                  [:pr.n_int])
    if pr.robot:
        for i in range(pr.n):
            names += [f"robot{i}.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]
    return names


def refine_reprojection(
    flange2base: Array,
    points: list[Array],
    pixels: list[Array],
    K: Array,
    dist: Array | None,
    X0: Array,
    Y0: Array,
    *,
    setup: str = "eye-in-hand",
    refine_intrinsics: bool = False,
    rational: bool = False,
    robot_noise: tuple[float, float] | None = None,
    robust: bool = True,
    outlier_level: float = 0.999,
    max_outer: int = 8,
) -> ReprojectionRefinement:
    """Refine X, the board pose (and optionally intrinsics, robot poses) on the pixels.

    Parameters
    ----------
    flange2base : ndarray, shape (n, 4, 4)
        Reported robot poses (length unit L of the board), n >= 3.
    points : list of ndarray, shape (N_i, 3)
        Board coordinates of the corners detected in image i.
    pixels : list of ndarray, shape (N_i, 2)
        Their detected pixel positions.
    K, dist
        Camera matrix and OpenCV distortion coefficients.
    X0, Y0 : ndarray, shape (4, 4)
        Start (a closed form): X and the board pose (``target2base`` eye-in-hand,
        ``target2flange`` eye-to-hand).
    setup : {"eye-in-hand", "eye-to-hand"}
    refine_intrinsics : bool
        Free ``fx, fy, cx, cy, k1, k2, p1, p2, k3`` (and ``k4..k6`` with `rational`).
    rational : bool
        The camera uses the 8-coefficient rational model.
    robot_noise : (float, float), optional
        Standard deviations of the robot poses' error, rotation (rad) and translation (L),
        per axis: model a correction of every robot pose with this Gaussian prior.
    robust : bool
        Huber loss, station reweighting and outlier stations (default); False: plain least
        squares over all stations.
    outlier_level : float
        Chi-square probability of the outlier bound.
    max_outer : int
        Reweighting passes.

    Returns
    -------
    ReprojectionRefinement
    """
    t0 = time.perf_counter()
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="setup")
    K, d8 = check_camera(K, dist)
    F = np.asarray(flange2base, float)
    n = len(F)
    if len(points) != n or len(pixels) != n:
        raise InputError(f"{n} robot poses but {len(points)} / {len(pixels)} corner sets")
    if n < 3:
        raise InputError(f"{n} stations: hand-eye calibration needs at least 3")
    if robot_noise is not None and not (robot_noise[0] > 0 and robot_noise[1] > 0):
        raise InputError(f"robot_noise {robot_noise}: expected two positive standard "
                         "deviations (rad, length)", option="robot_noise")
    counts = np.array([len(p) for p in points])
    sid = np.repeat(np.arange(n), counts).astype(np.intp)
    P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in points])
    uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in pixels])
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    pr = _Problem(F, P, uv, sid, setup == "eye-in-hand", K, d8, np.asarray(X0, float),
                  np.asarray(Y0, float), n_int, robot_noise)
    p = np.zeros(pr.n_params)
    nfev = 0
    history: list[float] = []

    def residual_stats(p: Array) -> tuple[Array, Array]:
        pred, _ = _model(pr, p, False)
        r = pred - uv
        ss = np.bincount(sid, weights=np.sum(r * r, axis=1), minlength=n)
        return r, np.sqrt(ss / np.maximum(counts, 1))

    def sigma_of(r: Array, mask: Array) -> float:
        sel = r[mask[sid]].ravel()
        s = 1.4826 * float(np.median(np.abs(sel))) if sel.size else 1.0
        return max(s, 1e-6)

    def solve(p: Array, w: Array, sigma: float, loss: str) -> tuple[Array, float, Any]:
        nonlocal nfev
        keep = w[sid] > 0
        sw = np.sqrt(w[sid][keep])[:, None]
        npix = 2 * int(keep.sum())
        prior = (np.r_[[1.0 / robot_noise[0]] * 3, [1.0 / robot_noise[1]] * 3]
                 if robot_noise else None)

        def fun(q: Array) -> Array:
            pred, _ = _model(pr, q, False)
            r = (sw * (pred[keep] - uv[keep]) / sigma).ravel()
            if prior is not None:
                r = np.concatenate([r, (q[12 + n_int:].reshape(-1, 6) * prior).ravel()])
            return r

        def jacobian(q: Array) -> Array:
            _, J = _model(pr, q, True)
            Jk = (J[keep] * (sw[:, :, None] / sigma)).reshape(npix, -1)
            if prior is not None:
                Jp = np.zeros((6 * n, pr.n_params))
                Jp[:, 12 + n_int:] = np.diag(np.tile(prior, n))
                Jk = np.vstack([Jk, Jp])
            return Jk

        sol = least_squares(fun, p, jac=jacobian, method="trf", loss=loss,
                            f_scale=_HUBER, x_scale="jac", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12, max_nfev=200)
        nfev += int(sol.nfev)
        return sol.x, float(2.0 * sol.cost), sol

    w = np.ones(n)
    r, srms = residual_stats(p)
    inlier = np.ones(n, bool)
    if robust:
        sigma = sigma_of(r, np.ones(n, bool))
        for _ in range(max_outer):
            p, cost, _ = solve(p, w, sigma, "huber")
            history.append(cost)
            r, srms = residual_stats(p)
            sigma = sigma_of(r, w > 0.5)
            med = float(np.median(srms))
            w_new = 1.0 / (1.0 + (srms / (_CAUCHY * max(med, sigma))) ** 2)
            done = np.max(np.abs(w_new - w)) < 1e-3
            w = w_new
            if done:
                break
        inlier = ~_outlier_stations(srms, counts, sigma, outlier_level)
        if inlier.sum() < 3:
            inlier = np.ones(n, bool)
    else:
        sigma = max(float(np.sqrt(np.mean(r**2))), 1e-6)
    # final pass: inliers, unit weights; sigma from their residuals
    sigma = sigma_of(r, inlier) if robust else sigma
    p, cost, sol = solve(p, inlier.astype(float), sigma, "huber" if robust else "linear")
    history.append(cost)
    r, srms = residual_stats(p)
    if not robust:
        sigma = max(float(np.sqrt(np.sum(r**2) / max(r.size - pr.n_params, 1))), 1e-12)
    # covariance: the Jacobian of the final pass at the solution, residual variance
    J = sol.jac
    m = J.shape[0]
    s2 = float(np.sum(sol.fun**2)) / max(m - pr.n_params, 1)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((pr.n_params, pr.n_params), np.inf)
    X, Y, Kf, df, E = _unpack(pr, p)
    res = np.split(-r, np.cumsum(counts)[:-1])
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    return ReprojectionRefinement(X, Y, Kf, df, None if E is None else E.copy(), res, srms,
                                  outliers, float(sigma), cov, _param_names(pr), nfev,
                                  history, time.perf_counter() - t0)


def _outlier_stations(srms: Array, counts: Array, sigma: float, level: float) -> Array:
    """Stations beyond the chi-square bound of pure corner noise (2 N_i dof), the robust
    spread of the station RMS values (median + 5 x 1.4826 MAD), three times the median
    station RMS and the median + 0.25 px (detection biases of a tenth of a pixel on oblique
    views are not outliers; a wrong robot pose costs pixels)."""
    dof = 2 * np.maximum(counts, 1)
    chi = np.sqrt(chdtri(dof, 1.0 - level) / dof) * sigma
    med = float(np.median(srms))
    mad = 1.4826 * float(np.median(np.abs(srms - med)))
    return (srms > chi) & (srms > med + 5.0 * mad) & (srms > max(3.0 * med, med + 0.25))
