"""`ReprojectionRefinement`: what `kinecal.calibration.handeye.images.refine_reprojection`
returns (X and the board pose refined on the corner pixels, their standard deviations and
covariance, per-station RMS, outliers, estimated intrinsics and robot-pose corrections).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

__all__ = ["ReprojectionRefinement"]


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
    cov : ndarray, shape (g, g)
        Covariance of the shared free parameters (order: X rotation, X translation, Y
        rotation, Y translation, intrinsics), the corrections marginalised.
    names : list of str
        Names of those parameters.
    nfev : int
    history : list of float
        Cost after each pass.
    seconds : float
    robot_noise : RobotNoise or None
        The robot-pose noise used: given, estimated (modelled or negligible) or exact
        (`kinecal.calibration.handeye.robot_noise`).
    corrections_std : ndarray, shape (n, 6) or None
        Standard deviations of the corrections (rad, length), when modelled.
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
    robot_noise: Any = None
    corrections_std: Array | None = None

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
