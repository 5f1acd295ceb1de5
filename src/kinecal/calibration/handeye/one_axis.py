"""`calibrate_handeye` for stations whose robot rotations all turn about one axis (SCARA,
4-axis arms): Ulrich & Steger's closed form (`kinecal.calibration.handeye.scara`), the same
refiners as the general case, the missing height from the caller, and the explanation.

Diagnostics (docs/diagnostics.md): ``handeye-one-axis`` (one-axis data and no height given:
X's component along the axis was assumed), ``handeye-height-unused`` (a height was given but
the rotations turn about several axes, which fix X alone), ``handeye-conditioning`` (the
screw axes of the motions lie too close together for the noise: X's rotation about the axis
and its position across it are poorly determined).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.errors import (
    axxb_station_rms,
    mean_target_pose,
    station_residuals,
)
from kinecal.calibration.handeye.scara import (
    AxisHeight,
    OneAxis,
    constrained_uncertainty,
    solve_one_axis,
)
from kinecal.diagnostics import warn

Array = NDArray[np.float64]

__all__ = ["OneAxisSolution", "calibrate_one_axis", "one_axis_summary", "warn_height_unused"]

#: what the heights are measured from, per setup (for messages and JSON)
_FRAMES = {"eye-in-hand": ("the camera's offset from the flange origin",
                           "the board origin's height in the base frame"),
           "eye-to-hand": ("the camera's height in the base frame",
                           "the board origin's offset from the flange origin")}


def _axis_text(axis: OneAxis) -> str:
    a = np.round(axis.base, 3) + 0.0
    return f"({a[0]:+.3f}, {a[1]:+.3f}, {a[2]:+.3f}) in the base frame"


@dataclass
class OneAxisSolution:
    """What `calibrate_one_axis` found (the fields of a `HandEyeResult`).

    Attributes
    ----------
    X, Y : ndarray, shape (4, 4)
    residuals : tuple of 4 ndarray, shape (n,)
        Station rotation (deg) and translation residuals, and their AX = XB rms.
    outliers : list of int
    history : list of float
    nfev : int
    uncertainty : XUncertainty or None
    summary : dict
        `one_axis_summary`.
    """

    X: Array
    Y: Array
    residuals: tuple[Array, Array, Array, Array]
    outliers: list[int]
    history: list[float]
    nfev: int
    uncertainty: Any
    summary: dict[str, Any]


def calibrate_one_axis(F: Array, C: Array, G: Array, setup: str, axis: OneAxis,
                       height: AxisHeight, refine: str, robust: bool,
                       rotation_weight: float | None, seed: Any, pairs: str,
                       options: dict[str, Any]) -> OneAxisSolution:
    """The one-axis branch of `kinecal.calibration.handeye.calibrate_handeye` (same
    arguments, already validated; ``G`` the robot poses in the setup's direction,
    ``options`` the metaheuristic's checked options).
    """
    from kinecal.calibration.diagnostics.handeye_consistency import (
        find_inconsistency,
        warn_inconsistent,
    )
    from kinecal.calibration.handeye.refine import flag_outliers, lm

    X, Y = height.place(axis, *solve_one_axis(G, C, axis))
    history: list[float] = []
    nfev = 0
    outliers: list[int] = []
    if refine == "lm":
        res = lm(G, C, X, Y, robust=robust, rotation_weight=rotation_weight,
                 eye_in_hand=setup == "eye-in-hand")
        X, Y, outliers, history, nfev = res.X, res.Y, res.outliers, res.history, res.nfev
    elif refine in ("igwo", "dlh-gwo-de"):
        from kinecal.calibration.handeye.refine_meta import metaheuristic

        res = metaheuristic(G, C, X, refine, rng=seed, pairs=pairs, **options)
        X, history, nfev = res.X, res.history, res.nfev
        Y = mean_target_pose(G, X, C)
    X, Y = height.place(axis, X, Y)  # (S8) again: the refiners may drift along (S3)
    if refine != "lm" and robust:
        outliers = flag_outliers(G, C, X, Y)
    rot, tr = station_residuals(G, X, C, Y)
    arot, atr = axxb_station_rms(G, C, X)
    inliers = np.setdiff1d(np.arange(len(G)), outliers)
    keep = inliers if len(inliers) >= 3 else None
    unc = constrained_uncertainty(G, C, X, Y, height.constraint(axis, Y), axis, keep)
    _check_conditioning(unc)
    inc = find_inconsistency(F, C, setup, X, Y, "park")
    if inc is not None:
        warn_inconsistent(inc)
    if not height.given:
        warn("handeye-one-axis",
             f"all robot rotations turn about one axis, {_axis_text(axis)} (a SCARA or "
             "4-axis arm): X's translation along it cannot be seen in the poses and was set "
             "to put the camera level with the flange along it; give the camera's height "
             "(--camera-height, camera_height=) or a point of the board touched by the tool "
             "(--board-contact X,Y,Z, board_contact=)")
    return OneAxisSolution(X, Y, (rot, tr, arot, atr), outliers, history, nfev, unc,
                           one_axis_summary(axis, height, X, Y))


def one_axis_summary(axis: OneAxis, height: AxisHeight, X: Array, Y: Array) -> dict[str, Any]:
    """The ``one_axis`` entry of the result JSON: the axis, where the height came from and
    the resulting heights of camera and board along it."""
    cam, board = axis.heights(X, Y)
    cam_what, board_what = _FRAMES[axis.setup]
    return {
        "axis_base": axis.base.tolist(),
        "axis_moving": axis.moving.tolist(),
        "axis_fixed": axis.fixed.tolist(),
        "spread_deg": axis.spread_deg,
        "height_from": height.source,
        "camera_height": cam,
        "camera_height_is": cam_what,
        "board_height": board,
        "board_height_is": board_what,
        "board_contact": None if height.board_contact is None else height.board_contact.tolist(),
        "explanation": ("all robot rotations turn about one axis: AX = XB leaves X's "
                        "translation along it unobservable (Ulrich & Steger 2016); "
                        + {"camera-height": "it is taken from the stated camera height",
                           "board-contact": "it is taken from the stated board contact point",
                           "none": "it was assumed zero (no height given)"}[height.source]),
    }


def warn_height_unused(height: AxisHeight, G: Array) -> None:
    """``handeye-height-unused``: a height was stated for stations that fix X without it."""
    from kinecal.calibration.diagnostics.handeye import axis_spread_deg

    if not height.given:
        return
    what = "camera_height (--camera-height)" if height.camera_height is not None else \
        "board_contact (--board-contact)"
    warn("handeye-height-unused",
         f"{what} was given, but the robot's rotation axes spread over "
         f"{axis_spread_deg(G):.2g} deg (not one axis): the stations determine X's height "
         "themselves and the stated value is not used")


def _check_conditioning(unc: Any) -> None:
    """``handeye-conditioning`` for one-axis data: X across the axis (and its rotation)
    much less certain in one direction than in another."""
    from kinecal.calibration.diagnostics.handeye import ANISOTROPY

    if unc is None or max(unc.anisotropy, unc.rotation_anisotropy) <= ANISOTROPY:
        return
    if unc.rotation_anisotropy > ANISOTROPY:
        what = (f"its rotation is {unc.rotation_anisotropy:.0f} times less certain about its "
                f"weakest axis than about its best (1 sigma {unc.rotation_deg:.3g} deg in all)")
    else:
        what = (f"its translation across the rotation axis is {unc.anisotropy:.0f} times less "
                "certain in its weakest direction than in its best (1 sigma "
                f"{unc.weak_translation:.3g})")
    warn("handeye-conditioning",
         f"X is ill-conditioned: {what}; with rotations about one axis only, X rests on how "
         "far apart the motions' turning lines lie: spread the stations over the workspace "
         "by moving the arm's first joints (a SCARA's shoulder and elbow), not only the last")
