"""Board pose per image by PnP, with its covariance from the corner residuals.

``cv2.solvePnP`` with IPPE (the planar-target solution of Collins & Bartoli 2014) gives the
start, refined by ``cv2.solvePnPRefineLM`` (Levenberg-Marquardt on the reprojection error;
OpenCV's camera model is kinecal's, `kinecal.calibration.handeye.camera`). The covariance of
the pose is ``sigma^2 (J^T J)^-1`` with ``sigma^2 = sum r^2 / (2N - 6)`` from the corner
residuals, in the parametrisation ``R = R0 Exp(omega)`` (rotation vector in the board frame,
rad) and ``t = t0 + v`` (camera frame, length unit): the first three rows/columns belong to
omega.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import check_camera, project_jacobian
from kinecal.errors import InputError
from kinecal.spatial import skew, transform_from
from kinecal.vision import require_cv2

Array = NDArray[np.float64]

__all__ = ["BoardPose", "board_pose", "pose_residuals"]


@dataclass
class BoardPose:
    """Board pose in one image.

    Attributes
    ----------
    target2cam : ndarray, shape (4, 4)
    cov : ndarray, shape (6, 6)
        Covariance of ``(omega (rad), v (length))``, see the module docstring.
    residuals : ndarray, shape (N, 2)
        Observed minus projected corners (px).
    rms_px : float
        RMS corner residual (px, per corner: sqrt(mean |r|^2)).
    tilt_deg : float
        Angle between the board normal and the line of sight to the board's centre.
    """

    target2cam: Array
    cov: Array
    residuals: Array
    rms_px: float
    tilt_deg: float

    @property
    def std(self) -> tuple[Array, Array]:
        """Standard deviations: rotation (deg, 3) and translation (length, 3)."""
        d = np.sqrt(np.clip(np.diag(self.cov), 0.0, None))
        return np.degrees(d[:3]), d[3:]


def pose_residuals(K: Array, dist8: Array, T: Array, obj: Array, img: Array) -> Array:
    """Observed minus projected pixels ``(N, 2)`` of board points `obj` at pose `T`."""
    P = obj @ T[:3, :3].T + T[:3, 3]
    return img - project_jacobian(K, dist8, P, jacobians=False)[0]


def _residuals_jacobian(K: Array, dist8: Array, T: Array, obj: Array, img: Array
                        ) -> tuple[Array, Array]:
    """`pose_residuals` ``(N, 2)`` and their pose Jacobian ``(2N, 6)`` from one projection
    (no intrinsic Jacobian: the intrinsics are held here)."""
    R = T[:3, :3]
    P = obj @ R.T + T[:3, 3]
    uv, Jp, _ = project_jacobian(K, dist8, P, intrinsics=False)
    # P = R Exp(w) X + t + v: dP/dw = -R [X]x, dP/dv = I
    dP = np.concatenate([-R @ skew(obj), np.broadcast_to(np.eye(3), (len(obj), 3, 3))],
                        axis=2)
    return img - uv, (Jp @ dP).reshape(-1, 6)


def board_pose(obj: Array, img: Array, K: Array, dist: Array | None,
               iterations: int = 20) -> BoardPose:
    """Pose of a planar board from its detected corners.

    Parameters
    ----------
    obj : ndarray, shape (N, 3)
        Board coordinates of the corners (z = 0), N >= 4.
    img : ndarray, shape (N, 2)
        Their pixel positions.
    K, dist
        Camera matrix and OpenCV distortion coefficients.
    iterations : int
        Most Levenberg-Marquardt iterations after IPPE.

    Returns
    -------
    BoardPose

    Raises
    ------
    InputError
        Fewer than 4 corners, or OpenCV finds no pose.
    """
    cv2 = require_cv2()
    K, d8 = check_camera(K, dist)
    obj = np.asarray(obj, float)
    img = np.asarray(img, float)
    if len(obj) < 4:
        raise InputError(f"{len(obj)} corners: a board pose needs at least 4")
    ok, rvec, tvec = cv2.solvePnP(obj.astype(np.float64), img.astype(np.float64), K, d8,
                                  flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, d8, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise InputError("no board pose fits the detected corners")
    # OpenCV's Levenberg-Marquardt on the same camera model (C++: a few microseconds per
    # iteration, where the former Python Gauss-Newton loop cost ~0.3 ms)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, iterations, 1e-12)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, d8, rvec, tvec, criteria=crit)
    T = transform_from(cv2.Rodrigues(rvec)[0], tvec.ravel())
    r, J = _residuals_jacobian(K, d8, T, obj, img)
    r = r.ravel()
    cost = float(r @ r)
    dof = max(r.size - 6, 1)
    s2 = float(cost) / dof
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((6, 6), np.inf)
    res = r.reshape(-1, 2)
    centre = T[:3, :3] @ obj.mean(axis=0) + T[:3, 3]
    cosang = abs(T[:3, 2] @ centre) / max(np.linalg.norm(centre), 1e-300)
    tilt = float(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))))
    return BoardPose(T, cov, res, float(np.sqrt(np.mean(np.sum(res**2, axis=1)))), tilt)
