"""Plausibility checks of a hand-eye calibration (``G_i X C_i = Y``, AX = XB).

Codes (docs/diagnostics.md): ``too-few-poses`` (an `InputError`), ``few-poses``,
``duplicate-poses`` (stations), ``scale-mismatch`` (robot and target translations in
different units), ``handeye-conditioning`` (motions whose rotation axes are nearly
parallel, or too small, for the noise: X is poorly determined along one direction).

The uncertainty of X comes from the joint refinement's residuals (`handeye_uncertainty`):
first-order covariance of the 12 unknowns of ``G_i X C_i = Y`` (X and the target pose),
each station's six residuals scaled by the RMS rotation and translation residual.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics._common import repeat_groups, unit_factor_name
from kinecal.calibration.diagnostics.counts import check_pose_count
from kinecal.calibration.diagnostics.handeye_consistency import TRANSLATION_LIMIT
from kinecal.diagnostics import warn
from kinecal.spatial import invert_transform, skew

__all__ = [
    "ANISOTROPY",
    "UNKNOWNS",
    "XUncertainty",
    "check_handeye_conditioning",
    "check_handeye_stations",
    "check_handeye_units",
    "handeye_uncertainty",
]

Array = NDArray[np.float64]

#: unknowns of G_i X C_i = Y (X and the target pose Y, 6 each); a station gives 6 equations
UNKNOWNS = 12
#: X is ill-conditioned when its weakest direction is determined this many times worse than
#: its best (the standard deviations along the principal axes of its covariance): the
#: signature of rotation axes that are nearly parallel
ANISOTROPY = 10.0
#: a unit factor must lie this many standard deviations away from 1
SIGMAS = 5.0
#: the scale column must stick out of the other columns' span by this fraction to be seen
OBSERVABLE = 1e-2
#: two stations closer than this in every matrix entry (rotation, length unit) are one
STATION_RESOLUTION = 1e-9


@dataclass
class XUncertainty:
    """First-order uncertainty of the hand-eye transform X.

    Attributes
    ----------
    rotation_deg : float
        RMS error of X's rotation, ``sqrt(trace)`` of its covariance (deg, 1 sigma).
    translation : float
        RMS error of X's translation, ``sqrt(trace)`` of its covariance (length unit).
    weak_direction : ndarray, shape (3,)
        The direction in which the translation is least certain (unit vector).
    weak_translation : float
        Standard deviation of the translation along it (length unit).
    anisotropy : float
        Worst over best standard deviation of the translation (1 when isotropic).
    rotation_anisotropy : float
        The same for the rotation.
    """

    rotation_deg: float
    translation: float
    weak_direction: Array
    weak_translation: float
    anisotropy: float
    rotation_anisotropy: float

    def to_dict(self) -> dict:
        """``{rotation_deg, translation, anisotropy, rotation_anisotropy}`` (JSON)."""
        return {"rotation_deg": float(self.rotation_deg), "translation": float(self.translation),
                "anisotropy": float(self.anisotropy),
                "rotation_anisotropy": float(self.rotation_anisotropy)}


def check_handeye_stations(F: Array, C: Array) -> int:
    """``duplicate-poses``, ``too-few-poses`` (fewer than 3 distinct stations) and
    ``few-poses`` (fewer than 3 equations per unknown). Returns the distinct count."""
    n = len(F)
    _, distinct = repeat_groups(np.asarray(F).reshape(n, -1), np.asarray(C).reshape(n, -1),
                                resolution=STATION_RESOLUTION)
    check_pose_count(n, distinct, 6, UNKNOWNS, what="stations", repeats="flange and target poses")
    return distinct


@dataclass
class TranslationScale:
    """The scale ``s`` between the robot's lengths and the target's in ``G X C = Y``
    (`translation_scale`): ``s`` target lengths are one robot length."""

    s: float
    var: float  # its variance
    rms_s: float  # residual rms with s free
    rms_1: float  # and with s = 1
    distance: float  # camera-target distance in the robot's unit (rms)

    @property
    def unit_factor(self) -> bool:
        """Far from 1, many standard deviations from it, and explaining the data (with it
        the stations fit; quaternions in another order, degrees read as radians or inverted
        poses also pull s away from 1 but leave a residual no scale removes)."""
        s = self.s
        return bool(s > 0 and abs(np.log(s)) > np.log(2.0)
                    and (s - 1.0) ** 2 > SIGMAS**2 * self.var
                    and np.sqrt(3.0) * self.rms_s <= TRANSLATION_LIMIT * self.distance)


def translation_scale(G: Array, C: Array, X: Array) -> TranslationScale | None:
    """The scale between robot and target translations (`check_handeye_units`); None when
    the stations do not see it (every motion turns about the target)."""
    n = len(G)
    if n < 4:
        return None
    RG = G[:, :3, :3]
    RGX = RG @ X[:3, :3]
    tc = C[:, :3, 3]
    rows = np.zeros((n, 3, 10))
    rows[:, :, 0] = np.einsum("nij,nj->ni", RGX, tc)  # R_G R_X t_C: the scaled lever
    rows[:, :, 1:4] = -RGX @ skew(tc)  # a small correction dw of R_X: R_G R_X (dw x t_C)
    rows[:, :, 4:7] = RG
    rows[:, :, 7:10] = -np.eye(3)
    M = rows.reshape(-1, 10)
    rhs = -G[:, :3, 3].reshape(-1)
    # the scale's column beyond the span of the others: nearly zero when every motion turns
    # about the target (paper 001's star scheme, look-at poses), which leaves the camera
    # distance unseen; then only the spreads of the two position sets can tell
    rest = M[:, 1:]
    part = M[:, 0] - rest @ np.linalg.lstsq(rest, M[:, 0], rcond=None)[0]
    if np.linalg.norm(part) <= OBSERVABLE * np.linalg.norm(M[:, 0]):
        return None
    sol, *_ = np.linalg.lstsq(M, rhs, rcond=None)
    s = float(sol[0])
    rss = float(np.sum((M @ sol - rhs) ** 2))
    fixed, *_ = np.linalg.lstsq(M[:, 1:], rhs - M[:, 0], rcond=None)
    return TranslationScale(
        s, rss / (M.shape[0] - 10) / float(part @ part), float(np.sqrt(rss / M.shape[0])),
        float(np.sqrt(np.mean((M[:, 1:] @ fixed + M[:, 0] - rhs) ** 2))),
        s * float(np.sqrt(np.mean(np.sum(tc**2, axis=1)))))


def check_handeye_units(G: Array, C: Array, X: Array, what: str = "stations") -> bool:
    """``scale-mismatch``: robot and target translations in different length units.

    With the rotation of X known (a closed form's rotation does not depend on lengths),
    the translation part of ``G_i X C_i = Y``,
    ``R_Gi R_X (s t_Ci) + R_Gi t_X - t_Y = -t_Gi``, is linear in ``t_X``, ``t_Y`` and a
    scale ``s`` between the two instruments' units; the camera-to-target distances pin
    ``s`` down (unless every motion turns about one axis). A scale outside [0.5, 2] and
    more than `SIGMAS` standard deviations from 1 is a unit mismatch. Returns True when it
    warned.
    """
    if len(G) < 4:
        return False
    sc = translation_scale(G, C, X)
    if sc is None:
        return _spread_units(G, C, what)
    if not sc.unit_factor:
        return False
    warn("scale-mismatch",
         f"the robot's translations are {sc.s:.4g} times the target's in G X C = Y over the "
         f"{what} ({_units(1.0 / sc.s)}; "
         f"residual {sc.rms_s:.3g} instead of {sc.rms_1:.3g}): give the flange and target "
         "poses in one length unit")
    return True


_PLURAL = {"metre": "metres", "millimetre": "millimetres", "centimetre": "centimetres",
           "inch": "inches"}


def _units(ratio: float) -> str:
    """``looks like robot poses in metres and target poses in millimetres`` for a target /
    robot length ratio (the serial check's "B in an A model" says which file is which)."""
    name = unit_factor_name(ratio)
    if " in a" not in name:
        return f"looks like {name}"
    target, robot = name.split(" in a", 1)
    robot = robot.removeprefix("n").strip().removesuffix(" model")
    return (f"looks like robot poses in {_PLURAL.get(robot, robot)} and target poses in "
            f"{target}")


def _spread(P: Array) -> float:
    return float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))


def _spread_units(G: Array, C: Array, what: str) -> bool:
    """Unit check for pose sets whose scale the equations do not see: the spread of the
    robot's positions (``G_i``) over the spread of the camera's positions in the target
    frame (``C_i^-1``) is a unit factor (within 2.5 times of 1000, 25.4 or their inverses).
    The two sets move together up to the hand-eye lever, which turns the spread by a factor
    of about 1-2 (look-at poses turning about the optical axis); it does not produce a
    factor beyond 10 that lands near a unit factor by chance."""
    cam = invert_transform(C)[:, :3, 3]
    a, b = _spread(G[:, :3, 3]), _spread(cam)
    if not (a > 0 and b > 0):
        return False
    r = a / b
    if abs(np.log(r)) < np.log(10.0):
        return False
    factor = min((1e3, 1e-3, 25.4, 1 / 25.4), key=lambda f: abs(np.log(r / f)))
    if abs(np.log(r / factor)) > np.log(2.5):
        return False
    warn("scale-mismatch",
         f"the robot's positions over the {what} spread {r:.4g} times more than the camera's "
         f"positions relative to the target ({_units(1.0 / factor)}): give the flange and "
         "target poses in one length unit")
    return True


def handeye_uncertainty(G: Array, C: Array, X: Array, Y: Array,
                        inliers: Array | None = None,
                        residuals: tuple[Array, Array, Array] | None = None,
                        noise: tuple[Any, bool] | None = None) -> XUncertainty | None:
    """First-order uncertainty of X at the solution (see the module docstring).

    `residuals`: ``residuals_and_jacobian(G, C, X, Y, 0)`` of all stations
    (`kinecal.calibration.handeye.refine`), when the caller has them (no `inliers` then).
    `noise`: the stations' estimated noise model and whether the set-up is eye-in-hand
    (`kinecal.calibration.handeye.noise.StationNoise`): the residuals are whitened by it
    instead of two scales. None when it cannot be estimated (noise-free data, no degrees of
    freedom).
    """
    from kinecal.calibration.handeye.refine import residuals_and_jacobian

    if inliers is not None:
        G, C = G[inliers], C[inliers]
    n = len(G)
    if 6 * n <= UNKNOWNS:
        return None
    rot, tr, J = residuals_and_jacobian(G, C, X, Y, np.zeros(UNKNOWNS)) if residuals is None \
        else residuals
    sr = float(np.sqrt(np.mean(rot**2)))
    st = float(np.sqrt(np.mean(tr**2)))
    L = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    if not (sr > 1e-12 and st > 1e-12 * max(L, 1e-300)):
        return None
    if noise is not None:
        from kinecal.calibration.handeye.noise import station_components, whitening

        floor = np.r_[[1e-26] * 3, [(1e-13 * L) ** 2] * 3]
        Li = whitening(noise[0].theta, station_components(G, C, X, Y, rot, noise[1]), floor)
        Js = (Li @ J).reshape(-1, UNKNOWNS)
        r = np.einsum("nij,nj->ni", Li, np.concatenate([rot, tr], axis=1)).ravel()
    else:
        scale = np.r_[[1.0 / sr] * 3, [1.0 / st] * 3]
        Js = (J * scale[None, :, None]).reshape(-1, UNKNOWNS)
        r = np.concatenate([rot / sr, tr / st], axis=1).ravel()
    # columns scaled to unit norm before the pseudo-inverse: rotation rows weighted by
    # 1 / s_R (1e11 for exact rotations read from a file) otherwise put the translation's
    # information below pinv's cut-off, and X's translation came out 1e-26 "certain"
    N = Js.T @ Js
    d = np.sqrt(np.diag(N))
    d = 1.0 / np.where(d > 0, d, 1.0)
    cov = float(r @ r) / (6 * n - UNKNOWNS) * (d[:, None] * np.linalg.pinv(
        d[:, None] * N * d[None, :], hermitian=True) * d[None, :])
    wr = np.clip(np.linalg.eigvalsh(cov[:3, :3]), 0.0, None)
    wt, vt = np.linalg.eigh(cov[3:6, 3:6])
    wt = np.clip(wt, 0.0, None)

    def ratio(w: Array) -> float:
        return float(np.sqrt(w[-1] / w[0])) if w[0] > 0 else float("inf")

    return XUncertainty(float(np.degrees(np.sqrt(wr.sum()))), float(np.sqrt(wt.sum())),
                        vt[:, -1], float(np.sqrt(wt[-1])), ratio(wt), ratio(wr))


def axis_spread_deg(G: Array) -> float:
    """Angular spread of the robot motions' rotation axes (deg): ``asin`` of the square root
    of the smallest over the largest eigenvalue of ``sum (2 I - R - R^T)`` (0 when every
    motion turns about one axis; `kinecal.calibration.handeye._motions.check_motions`)."""
    A = invert_transform(G[:1]) @ G[1:]
    R = A[:, :3, :3]
    M = 2.0 * len(R) * np.eye(3) - (R.sum(axis=0) + R.sum(axis=0).T)
    lam = np.clip(np.linalg.eigvalsh(M), 0.0, None)
    return float(np.degrees(np.arcsin(min(np.sqrt(lam[0] / lam[-1]), 1.0)))) if lam[-1] > 0 \
        else 0.0


def check_handeye_conditioning(unc: XUncertainty | None, G: Array, unit: str = "") -> None:
    """``handeye-conditioning``: X determined much worse along one direction than the others.

    Warns when the standard deviation of X's translation along its weakest direction
    exceeds `ANISOTROPY` times that along its best: AX = XB is then
    ill-conditioned, typically because the motions turn about nearly parallel axes, and
    the answer can be far off along that direction although the residuals look fine.
    """
    if unc is None or unc.anisotropy <= ANISOTROPY:
        return
    u = f" {unit}" if unit else ""
    d = np.round(unc.weak_direction, 2)
    warn("handeye-conditioning",
         f"AX = XB is ill-conditioned: X's translation is {unc.anisotropy:.0f} times less "
         f"certain along ({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f}) than along its best direction "
         f"(1 sigma {unc.weak_translation:.3g}{u} along it, rotation {unc.rotation_deg:.3g} deg);"
         " the robot's "
         f"rotation axes spread over only {axis_spread_deg(G):.2g} deg: add stations that turn "
         "about other axes (the star scheme of Li, Xiao, Lai and Hu 2024: kinecal handeye-poses)")
