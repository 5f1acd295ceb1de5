"""The figures of a pose plan, recomputed at each change in the Plan view: rank and
condition number of what the poses identify (the analysis ``kinecal identifiability
--data PLAN.csv`` prints), and the uncertainty a calibration on them would leave, to first
order, for an instrument of stated noise.

Predicted uncertainty: with the identification rows ``J`` (3 per pose) of the identifiable
parameters and an instrument noise ``s`` per coordinate, the parameters' covariance is
``C = s^2 (J^T J)^-1`` and a pose's position uncertainty ``sqrt(trace(J_i C J_i^T))``
(Hollerbach and Wampler's linearised propagation; `kinecal.calibration.uncertainty` does
the same after a fit, with the noise estimated from the residual).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["PlanFigures", "plan_figures"]

Array = NDArray[np.float64]


@dataclass
class PlanFigures:
    """What a plan identifies and how well (module docstring).

    Attributes
    ----------
    n_poses, rank, n_params : int
        Poses, the rank of the identification rows and the parameters examined.
    condition_number : float
        Of the identifiable set (scaled columns, as ``kinecal identifiability``).
    unidentifiable : list of str
        Held at nominal by a calibration on these poses.
    std : dict of str to float
        Predicted 1-sigma of each identifiable parameter (length unit, rad).
    position_sigma : float
        Predicted 1-sigma position error of the calibrated model, rms over the poses.
    angles : set of str
        The parameters of `std` that are angles (rad).
    """

    n_poses: int
    rank: int = 0
    n_params: int = 0
    condition_number: float = float("inf")
    unidentifiable: list[str] = field(default_factory=list)
    std: dict[str, float] = field(default_factory=dict)
    position_sigma: float = float("inf")
    angles: set[str] = field(default_factory=set)


def plan_figures(model, q: Array, noise: float) -> PlanFigures:
    """The `PlanFigures` of joint values `q` ``(N, n_joints)`` (rad) for a serial model
    and an instrument of 1-sigma `noise` per coordinate (length unit)."""
    from kinecal.calibration.serial.api import CALIBRATION_RANK_TOL
    from kinecal.calibration.serial.pose_selection import candidate_measurements
    from kinecal.calibration.serial.problem import (
        analyse_poses,
        candidate_names,
        identification_rows,
    )

    q = np.atleast_2d(np.asarray(q, dtype=float))
    if len(q) == 0:
        return PlanFigures(0)
    meas = candidate_measurements(model, q)
    names = candidate_names(model, "all")
    report = analyse_poses(model, meas, names, tol=CALIBRATION_RANK_TOL)
    out = PlanFigures(len(q), report.rank, len(names), float(report.condition_number),
                      list(report.unidentifiable))
    ident = list(report.identifiable)
    if not ident:
        return out
    J = identification_rows(model, meas, ident)
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Js = J / scale
    try:
        inv = np.linalg.inv(Js.T @ Js)
    except np.linalg.LinAlgError:
        return out
    C = noise ** 2 * inv / np.outer(scale, scale)
    std = np.sqrt(np.clip(np.diag(C), 0.0, None))
    angles = model.is_angle()[model.index(ident)]
    out.std = {n: float(v) for n, v in zip(ident, std, strict=True)}
    out.angles = {n for n, a in zip(ident, angles, strict=True) if a}
    rows = J.reshape(len(q), -1, len(ident))
    per_pose = np.einsum("nik,kl,nil->n", rows, C, rows)
    out.position_sigma = float(np.sqrt(np.clip(per_pose, 0.0, None).mean()))
    return out
