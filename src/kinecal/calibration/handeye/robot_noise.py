"""The robot poses' noise of a hand-eye calibration from images, estimated from the data.

The refinement on the pixels (`kinecal.calibration.handeye.images.refine_reprojection`)
can model an error of every reported robot pose with a Gaussian prior; its size is
estimated here when the caller does not state it, in two steps that keep the two
instruments apart:

1. every station's board pose alone from its own corners (Gauss-Newton from the pose the
   start predicts), with its covariance ``s_px^2 (J_i^T J_i)^-1`` from the corner noise
   ``s_px`` (the median of the stations' ``RSS_i / (2 N_i - 6)``: within one image the
   robot's error is a common motion, so these residuals hold the corner noise alone);
2. the stations' consistency at the pose level (`kinecal.calibration.handeye.noise`): the
   residual of ``G_i X C_i = Y`` has the covariance of the board pose (step 1, known) plus
   the robot's translation (isotropic) and rotation (with its lever from the flange to the
   board); their variances are estimated by REML with the camera's part held at what the
   pixels say, stations beyond the chi-square(6) 0.999 bound left out and the estimate
   repeated.

The robot's noise is modelled when the data ask for it: the likelihood-ratio test of the
robot's components against none (restricted likelihood, `SIGNIFICANCE`). An estimate of a
variance that is truly zero comes out positive half of the time; on exact robot poses the
test keeps the refinement the one that trusts them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtri
from kinecal.calibration.handeye.camera import project_jacobian
from kinecal.calibration.handeye.noise import (
    estimate_components,
    reml_loglik,
    score_and_information,
    station_components,
)
from kinecal.calibration.handeye.refine import _jr_inv, residuals_and_jacobian
from kinecal.spatial import invert_transform, matrix_from_axis_angle, skew, transform_from

Array = NDArray[np.float64]

__all__ = ["SIGNIFICANCE", "RobotNoise", "estimate_robot_noise"]

#: the robot's noise is modelled when twice the restricted log-likelihood gains more than
#: this over no robot noise (the 0.99 quantile of chi-square(2); at the boundary of the
#: parameter space the test is conservative)
SIGNIFICANCE = 9.21
#: stations needed for an estimate (24 degrees of freedom for 2 components)
MIN_STATIONS = 6
#: an estimate beyond these is no robot's noise but a wrong set-up (board size, pose unit or
#: frame, mixed-up stations), which the exact-pose refinement's checks then name: rotation
#: (rad) and translation as a fraction of the board's distance from the camera
PLAUSIBLE_ROTATION = float(np.radians(0.25))
PLAUSIBLE_TRANSLATION = 0.01


@dataclass
class RobotNoise:
    """The robot-pose noise a refinement used.

    Attributes
    ----------
    rotation, translation : float
        Standard deviations per axis (rad, length unit); 0 when the poses are trusted.
    source : str
        ``"given"`` (the caller's), ``"estimated"`` (from the data, modelled),
        ``"estimated-negligible"`` (the data do not ask for it, `SIGNIFICANCE`: the poses
        are trusted),
        ``"estimated-implausible"`` (estimated beyond a robot's noise: a wrong set-up, the
        poses taken as they are so that the checks name it),
        ``"exact"`` (the caller trusts the poses) or ``"too-few-stations"``.
    share : float or None
        The estimated robot share of the stations' covariance (mean over the stations of
        ``tr(Sigma_camera^-1 Sigma_robot) / 6``).
    statistic : float or None
        The likelihood-ratio statistic of the robot's components (`SIGNIFICANCE`).
    """

    rotation: float
    translation: float
    source: str
    share: float | None = None
    statistic: float | None = None

    @property
    def modelled(self) -> bool:
        """The refinement corrects every robot pose (with this prior)."""
        return self.source in ("given", "estimated")

    @property
    def prior(self) -> tuple[float, float] | None:
        """``(rotation rad, translation)`` for the refinement, or None (exact poses)."""
        return (self.rotation, self.translation) if self.modelled else None

    def to_dict(self) -> dict[str, Any]:
        """``{"source", "modelled", "rotation_deg", "translation", "share", "statistic"}``."""
        return {"source": self.source, "modelled": self.modelled,
                "rotation_deg": float(np.degrees(self.rotation)),
                "translation": float(self.translation), "share": self.share,
                "statistic": self.statistic}

    def describe(self, unit: str = "") -> str:
        """One line for summaries."""
        u = f" {unit}" if unit else ""
        size = f"{np.degrees(self.rotation):.3g} deg / {self.translation:.3g}{u}"
        return {
            "given": f"robot-pose noise {size} (given), modelled",
            "estimated": f"robot-pose noise {size} (estimated from the station consistency), "
                         "modelled",
            "estimated-negligible": f"robot-pose noise estimated at {size}, not "
                                    "significant beside the camera's: robot poses taken as "
                                    "exact",
            "estimated-implausible": f"robot-pose noise estimated at {size}, too large for "
                                     "a robot's noise (a wrong set-up?): robot poses taken "
                                     "as they are",
            "exact": "robot poses taken as exact (as asked)",
            "too-few-stations": f"robot poses taken as exact (fewer than {MIN_STATIONS} "
                                "stations to estimate their noise)",
        }[self.source]


def _station_poses(P: Array, uv: Array, sid: Array, starts: Array, counts: Array,
                   K: Array, d8: Array, T0: Array, iterations: int = 8
                   ) -> tuple[Array, Array, Array]:
    """Each station's board pose from its own corners (right-multiplied increments in the
    board frame), the normal matrices ``(n, 6, 6)`` at the end and the residual sums of
    squares ``(n,)``."""
    T = T0.copy()
    n = len(T)
    SP = skew(P)  # (M, 3, 3), the same every iteration

    def pose_jacobian(R: Array, t: Array) -> tuple[Array, Array]:
        Rs = R[sid]
        pc = np.einsum("mij,mj->mi", Rs, P) + t[sid]
        pred, Jp, _ = project_jacobian(K, d8, pc, intrinsics=False)
        JpR = Jp @ Rs
        Jpose = np.empty((len(P), 2, 6))
        Jpose[:, :, :3] = -JpR @ SP
        Jpose[:, :, 3:] = JpR
        return pred, Jpose

    for _ in range(iterations):
        R, t = T[:, :3, :3], T[:, :3, 3]
        pred, Jpose = pose_jacobian(R, t)
        r = pred - uv
        N = np.add.reduceat(np.einsum("mci,mcj->mij", Jpose, Jpose), starts, axis=0)
        b = np.add.reduceat(np.einsum("mci,mc->mi", Jpose, r), starts, axis=0)
        try:
            h = -np.linalg.solve(N, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        T = T @ transform_from(matrix_from_axis_angle(h[:, :3]), h[:, 3:])
        if np.abs(h).max() < 1e-12 * max(1.0, float(np.abs(t).max())):
            break
    pred, Jpose = pose_jacobian(T[:, :3, :3], T[:, :3, 3])
    N = np.add.reduceat(np.einsum("mci,mcj->mij", Jpose, Jpose), starts, axis=0)
    rss = np.bincount(sid, weights=np.sum((pred - uv) ** 2, axis=1), minlength=n)
    return T, N, rss


def estimate_robot_noise(F: Array, P: Array, uv: Array, sid: Array, counts: Array, K: Array,
                         d8: Array, X: Array, Y: Array, eye_in_hand: bool) -> RobotNoise:
    """The robot poses' noise from the stations (module docstring).

    Parameters
    ----------
    F : ndarray, shape (n, 4, 4)
        Reported ``flange2base`` poses.
    P, uv : ndarray, shape (M, 3), (M, 2)
        Board points and their pixels, every station's corners contiguous.
    sid : ndarray of int, shape (M,)
        Station of each corner.
    counts : ndarray of int, shape (n,)
        Corners per station.
    K, d8
        Camera matrix and 8 distortion coefficients.
    X, Y : ndarray, shape (4, 4)
        Start (a closed form): X and the board pose.
    eye_in_hand : bool

    Returns
    -------
    RobotNoise
    """
    n = len(F)
    if n < MIN_STATIONS or np.any(2 * counts <= 6):
        return RobotNoise(0.0, 0.0, "too-few-stations")
    G = F if eye_in_hand else invert_transform(F)
    T0 = invert_transform(X) @ invert_transform(G) @ Y  # the predicted board poses
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
    C, N, rss = _station_poses(P, uv, sid, starts, counts, K, d8, T0)
    s2 = float(np.median(rss / (2 * counts - 6)))
    if not (np.isfinite(s2) and s2 > 0):
        return RobotNoise(0.0, 0.0, "estimated-negligible", 0.0)
    try:
        cov_pose = s2 * np.linalg.inv(N)  # (n, 6, 6): board rotation, translation
    except np.linalg.LinAlgError:
        return RobotNoise(0.0, 0.0, "too-few-stations")
    rot, tr, J = residuals_and_jacobian(G, C, X, Y, np.zeros(12))
    L = max(float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1)))), 1e-300)
    floor = np.r_[[1e-26] * 3, [(1e-13 * L) ** 2] * 3]
    # the board pose's covariance as the residual sees it: d r = (J_r^-1 w, R_C v)
    Jc = np.zeros((n, 6, 6))
    Jc[:, :3, :3] = _jr_inv(rot)
    Jc[:, 3:, 3:] = C[:, :3, :3]
    V = station_components(G, C, X, Y, rot, eye_in_hand)
    V[0] = Jc @ cov_pose @ np.swapaxes(Jc, 1, 2)
    theta = np.array([1.0, float(np.median(np.diagonal(V[0], axis1=1, axis2=2)[:, 3:])),
                      float(np.median(np.diagonal(V[0], axis1=1, axis2=2)[:, :3]))])
    keep = np.ones(n, bool)
    y = np.concatenate([rot, tr], axis=1)
    # the score test at no robot noise first: on exact robot poses (the usual recording)
    # the likelihood falls when any robot noise is added, and no estimate is needed
    th0 = np.array([1.0, 0.0, 0.0])
    g, Fi = score_and_information(y, J, V, th0, floor)
    try:
        step = np.linalg.solve(Fi[1:, 1:], g[1:])
        score = float(g[1:] @ step)
    except np.linalg.LinAlgError:
        step, score = np.zeros(2), np.inf
    if score < SIGNIFICANCE / 2 or np.all(g[1:] <= 0):
        one = np.sqrt(np.clip(step, 0.0, None))  # one scoring step, for the record
        return RobotNoise(float(one[1]), float(one[0]), "estimated-negligible",
                          0.0, max(score, 0.0) if np.isfinite(score) else None)
    bound = float(chdtri(6, 1e-3))
    for _ in range(3):
        # a percent on a standard deviation is more than its estimate's own precision
        theta = estimate_components(y[keep], J[keep], V[:, keep], theta, floor, fixed=(0,),
                                    max_iter=12, tol=1e-2)
        S = np.einsum("k,knij->nij", theta, V) + np.diag(floor)
        d2 = np.einsum("ni,ni->n", y, np.linalg.solve(S, y[..., None])[..., 0])
        new = d2 <= bound * max(float(np.median(d2)) / 5.35, 1.0)
        if new.sum() < MIN_STATIONS or np.array_equal(new, keep):
            break
        keep = new
    robot = theta[1] * V[1] + theta[2] * V[2]
    share = float(np.mean(np.einsum("nii->n", np.linalg.solve(V[0] + np.diag(floor), robot)))
                  / 6.0)
    rot_sd, tr_sd = float(np.sqrt(theta[2])), float(np.sqrt(theta[1]))
    stat = 2.0 * (reml_loglik(y[keep], J[keep], V[:, keep], theta, floor)
                  - reml_loglik(y[keep], J[keep], V[:, keep], th0, floor))
    source = "estimated" if stat > SIGNIFICANCE else "estimated-negligible"
    if rot_sd > PLAUSIBLE_ROTATION or tr_sd > PLAUSIBLE_TRANSLATION * L:
        source = "estimated-implausible"
    # a prior needs positive standard deviations: a component estimated at zero is held at
    # a thousandth of the other's effect
    if source == "estimated":
        rot_sd = max(rot_sd, 1e-3 * tr_sd / L)
        tr_sd = max(tr_sd, 1e-3 * rot_sd * L)
    return RobotNoise(rot_sd, tr_sd, source, share, float(stat))
