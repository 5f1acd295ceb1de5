"""Hand-eye refinement on the reprojection error of the board corners.

The most accurate published pipelines (Tabb & Ahmad Yousef 2017, "reprojection error"
variants; Koide & Menegatti 2019) refine X on the pixels rather than on the per-image board
poses: a board pose from one image is poorly determined along the line of sight, and a
pose-based cost weighs those errors wrongly. Here the unknowns are

- X (``cam2flange`` eye-in-hand, ``cam2base`` eye-to-hand) and the fixed board pose Y
  (``target2base`` eye-in-hand, ``target2flange`` eye-to-hand), always;
- optionally the camera intrinsics ``(fx, fy, cx, cy, k1, k2, p1, p2, k3[, k4, k5, k6])``;
- a correction ``E_i`` of every reported robot pose (``flange2base_i E_i``, a rotation
  vector and a translation in the flange frame) with a zero-mean Gaussian prior of the
  robot's standard deviations, when the robot's noise matters: stated by the caller, or
  (default) estimated from the stations' consistency (`kinecal.calibration.handeye.
  robot_noise`) and modelled when it is a noticeable share of the camera's; exact robot
  poses are trusted as they are.

The corner model and its Jacobian are in `kinecal.calibration.handeye.reprojection`.
Residuals are predicted minus observed pixels divided by the corner noise sigma (estimated
robustly from the residuals). Robust mode: Huber loss per corner (3 sigma) and iteratively
reweighted stations (Cauchy weights on a station's RMS relative to the median station RMS);
stations whose RMS exceeds both the chi-square bound of pure corner noise and the robust
spread of the station RMS values (and three times their median, and the median + 0.25 px)
are flagged as outliers and left out of a final pass.

Every pass is kinecal's Levenberg-Marquardt (`kinecal.optimize.lm.solve_normal_equations`) on
the structured normal equations of `kinecal.calibration.handeye.bundle` (Huber's loss as
reweighted normal equations; the robot-pose corrections eliminated by the Schur complement)
with the analytic Jacobian (right Jacobians of SO(3); tested against finite differences).
The covariance of the parameters is ``s^2 (J^T J)^-1`` from the final pass (the Jacobian
scaled as scipy scales it for a robust loss: corners beyond Huber's threshold count
``eps``).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtri
from kinecal.calibration.handeye.camera import check_camera
from kinecal.calibration.handeye.images_cov import covariance, station_aware_covariance
from kinecal.calibration.handeye.images_fit import Fit, reweighted_passes
from kinecal.calibration.handeye.refinement import ReprojectionRefinement
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    behind_camera,
    parameter_names,
    predict_corners,
    unpack,
)
from kinecal.calibration.handeye.robot_noise import RobotNoise, estimate_robot_noise
from kinecal.calibration.handeye.scara import AxisHeight, OneAxis
from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = ["predict_corners", "refine_reprojection"]



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
    robot_noise: tuple[float, float] | str | None = "auto",
    robust: bool = True,
    outlier_level: float = 0.999,
    max_outer: int = 8,
    one_axis: tuple[OneAxis, AxisHeight] | None = None,
    intrinsics_estimated: bool = False,
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
    robot_noise : (float, float), "auto" or None
        Standard deviations of the robot poses' error, rotation (rad) and translation (L),
        per axis: model a correction of every robot pose with this Gaussian prior.
        ``"auto"`` (default): estimated from the data and modelled when it matters
        (`kinecal.calibration.handeye.robot_noise`); None: the robot poses are exact.
    robust : bool
        Huber loss, station reweighting and outlier stations (default); False: plain least
        squares over all stations.
    outlier_level : float
        Chi-square probability of the outlier bound.
    max_outer : int
        Reweighting passes.
    one_axis : (OneAxis, AxisHeight), optional
        The robot turns about one axis only (SCARA): the pixels do not see X's translation
        along it either (`kinecal.calibration.handeye.scara`, (S3)); the solution is put
        where the height says, and the covariance is taken under that constraint.
    intrinsics_estimated : bool
        The intrinsics were estimated from the same views and are held (not refined): X's
        covariance includes their uncertainty (`images_cov.station_aware_covariance`).

    Returns
    -------
    ReprojectionRefinement
    """
    t0 = time.perf_counter()
    K, d8, F, counts = _check_inputs(flange2base, points, pixels, K, dist, setup, robot_noise)
    n = len(F)
    sid = np.repeat(np.arange(n), counts).astype(np.intp)
    P = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in points])
    uv = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in pixels])
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    if isinstance(robot_noise, str) and n_int:
        # free intrinsics: the stations' board poses are judged with refined ones (start
        # intrinsics a few pixels off make every station look inconsistent)
        first = refine_reprojection(F, points, pixels, K, dist, X0, Y0, setup=setup,
                                    refine_intrinsics=True, rational=rational,
                                    robot_noise=None, robust=robust,
                                    outlier_level=outlier_level, max_outer=max_outer,
                                    one_axis=one_axis)
        noise = _robot_noise(robot_noise, F, P, uv, sid, counts, first.K, first.dist,
                             first.X, first.Y, setup)
        if not noise.modelled:
            first.robot_noise = noise
            at = ReprojectionProblem(F, P, uv, sid, setup == "eye-in-hand", first.K, first.dist,
                                     first.X, first.Y, n_int, None, strict=False)
            keep = np.ones(n, bool)
            keep[first.outliers] = False
            aware = station_aware_covariance(at, np.zeros(at.n_params), keep,
                                             first.sigma_px, noise, None, n_int)
            if aware is not None and one_axis is None:
                first.cov, first.names = aware
            first.seconds = time.perf_counter() - t0
            return first
        K, d8, X0, Y0 = first.K, first.dist, first.X, first.Y
    else:
        noise = _robot_noise(robot_noise, F, P, uv, sid, counts, K, d8, X0, Y0, setup)
    pr = ReprojectionProblem(F, P, uv, sid, setup == "eye-in-hand", K, d8, np.asarray(X0, float),
                             np.asarray(Y0, float), n_int, noise.prior, strict=False)
    fit = Fit(pr, counts)
    p = np.zeros(pr.n_params)
    history: list[float] = []
    fit.usable = _in_front(pr, p, robust)
    r, srms = fit.residual_stats(p)
    inlier = fit.usable.copy()
    if robust:
        p, r, srms, sigma = reweighted_passes(fit, p, r, max_outer, history)
        inlier = ~_outlier_stations(srms, counts, sigma, outlier_level) & fit.usable
        if inlier.sum() < 3:
            inlier = fit.usable.copy()
        sigma = fit.sigma_of(r, inlier)
    else:
        sigma = max(float(np.sqrt(np.mean(r**2))), 1e-6)
    # final pass: inliers, unit weights; sigma from their residuals
    p, cost, A_cov, raw = fit.solve(p, inlier.astype(float), sigma,
                                    "huber" if robust else "linear", final=True)
    history.append(cost)
    r, srms = fit.residual_stats(p)
    if not robust:
        sigma = max(float(np.sqrt(np.sum(r**2) / max(r.size - pr.n_params, 1))), 1e-12)
    row = None
    if one_axis is not None:  # (S8) of `scara`: move along the null direction, constrain
        p, row = _place_on_axis(pr, p, *one_axis)
        r, srms = fit.residual_stats(p)
    # covariance: the normal matrix of the final pass at the solution, residual variance
    s2 = float(raw @ raw) / max(raw.size - pr.n_params + (row is not None), 1)
    cov, corr_std = covariance(A_cov, s2, row, 12 + pr.n_int)
    names = parameter_names(pr)[:12 + pr.n_int]
    aware = station_aware_covariance(pr, p, inlier, sigma, noise, row,
                                     (12 if rational else 9) if intrinsics_estimated else 0)
    if aware is not None:
        cov, names = aware
    X, Y, Kf, df, E = unpack(pr, p)
    res = np.split(-r, np.cumsum(counts)[:-1])
    outliers = [int(i) for i in np.flatnonzero(~inlier)]
    return ReprojectionRefinement(X, Y, Kf, df, None if E is None else E.copy(), res, srms,
                                  outliers, float(sigma), cov, names, fit.nfev, history,
                                  time.perf_counter() - t0, noise, corr_std)


def _in_front(pr: ReprojectionProblem, p: Array, robust: bool) -> NDArray[np.bool_]:
    """The stations whose board is in front of the camera at the start `p`; robust, the
    others are left out (outliers: a wrong robot pose or image can put its board behind the
    camera for X started from the other stations), else they are an error naming them."""
    bad = behind_camera(pr, p)
    if bad.any() and (not robust or (~bad).sum() < 3):
        names = ", ".join(str(int(i)) for i in np.flatnonzero(bad)[:5])
        raise InputError(f"station(s) {names} (0-based): the board is behind the camera for "
                         "the start of X and the board pose; the robot poses do not fit the "
                         "images (wrong setup or pose convention, or images and robot poses "
                         "of different stations?)")
    return ~bad


def _robot_noise(robot_noise: tuple[float, float] | str | None, F: Array, P: Array,
                 uv: Array, sid: Array, counts: Array, K: Array, d8: Array, X0: Array,
                 Y0: Array, setup: str) -> RobotNoise:
    """The robot-pose noise of the refinement: given, exact, or estimated (``"auto"``)."""
    if robot_noise is None:
        return RobotNoise(0.0, 0.0, "exact")
    if isinstance(robot_noise, str):
        return estimate_robot_noise(F, P, uv, sid, counts, K, d8, np.asarray(X0, float),
                                    np.asarray(Y0, float), setup == "eye-in-hand")
    return RobotNoise(float(robot_noise[0]), float(robot_noise[1]), "given")


def _check_inputs(flange2base: Array, points: list[Array], pixels: list[Array], K: Array,
                  dist: Array | None, setup: str, robot_noise: tuple[float, float] | str | None
                  ) -> tuple[Array, Array, Array, NDArray[np.intp]]:
    """Validated camera ``(K, d8)``, robot poses and the corner count per station."""
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
    if isinstance(robot_noise, str):
        if robot_noise != "auto":
            raise InputError(f"robot_noise {robot_noise!r}: expected 'auto', None or two "
                             "standard deviations (rad, length)", option="robot_noise")
    elif robot_noise is not None and not (
            len(robot_noise) == 2 and all(np.isfinite(v) and v > 0 for v in robot_noise)):
        raise InputError(f"robot_noise {robot_noise}: expected two positive standard "
                         "deviations (rad, length)", option="robot_noise")
    counts = np.array([len(p) for p in points])
    if np.any(counts == 0):
        raise InputError(f"station {int(np.argmin(counts))} has no corners")
    return K, d8, F, counts


def _place_on_axis(pr: ReprojectionProblem, p: Array, axis: OneAxis,
                   height: AxisHeight) -> tuple[Array, Array]:
    """Parameters moved along the unobservable direction so that the height holds, and the
    constraint row ``(n_params,)`` of the height at the result (`scara.AxisHeight`)."""
    from kinecal.calibration.handeye.refine import _jr

    X, Y = unpack(pr, p)[:2]
    X2, Y2 = height.place(axis, X, Y)
    q = p.copy()
    q[3:6] += X2[:3, 3] - X[:3, 3]
    q[9:12] += Y2[:3, 3] - Y[:3, 3]
    c = height.constraint(axis, Y2)
    row = np.zeros(pr.n_params)
    row[:12] = c
    # the rotations are R0 Exp(p): a change d of p turns the frame by J_r(p) d
    row[0:3] = _jr(q[0:3]).T @ c[0:3]
    row[6:9] = _jr(q[6:9]).T @ c[6:9]
    return q, row


def _outlier_stations(srms: Array, counts: Array, sigma: float, level: float) -> Array:
    """Stations beyond the chi-square bound of pure corner noise (2 N_i dof), the robust
    spread of the station RMS values (median + 5 x 1.4826 MAD), three times the median
    station RMS and the median + 0.25 px (detection biases of a tenth of a pixel on oblique
    views are not outliers; a wrong robot pose costs pixels)."""
    med = float(np.median(srms))
    mad = 1.4826 * float(np.median(np.abs(srms - med)))
    out = (srms > med + 5.0 * mad) & (srms > max(3.0 * med, med + 0.25))
    if out.any():  # the chi-square bound only where the robust ones already flag
        dof = 2 * np.maximum(counts[out], 1)
        out[out] = srms[out] > np.sqrt(chdtri(dof, 1.0 - level) / dof) * sigma
    return out
