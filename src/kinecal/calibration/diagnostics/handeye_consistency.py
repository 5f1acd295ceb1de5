"""``handeye-inconsistent``: robot and target poses that no X and target pose can join.

A hand-eye fit always returns an X. When the two pose lists are not what they claim to be
(angles in degrees read as radians, quaternions stored x, y, z, w under w, x, y, z
columns, base2flange given as flange2base, cam2target as target2cam, the other set-up,
rows of the two files for different stations) the fit is an X that explains nothing:
the stations stay tens of degrees and a sizeable fraction of the camera distance from
``G_i X C_i = Y``. Measurement noise never does that at half of the stations: a camera
pose from a board or a marker is off by a fraction of a degree and well below 1 % of its
distance (the AR-marker recording of camodocal: 1.8 deg and 0.2 % median), a robot far
less. So the check looks at the **median** station residual (robust to up to half the
stations being outliers) against `ROTATION_LIMIT_DEG` and `TRANSLATION_LIMIT` times the
RMS camera-target distance. It also tries the usual mix-ups (poses inverted, quaternion
order) with Park's closed form: one that fits `FAR_BETTER` times better than the poses as
given is named, also when the poses as given stay within the limits (look-at poses that
turn little about other axes than the optical one fit inverted robot poses to a few
degrees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.diagnostics import warn
from kinecal.spatial import (
    invert_transform,
    matrix_from_quaternion,
    project_to_rotation,
    quaternion_from_matrix,
)

__all__ = ["ROTATION_LIMIT_DEG", "TRANSLATION_LIMIT", "Inconsistency", "consistency_scores",
           "find_inconsistency", "screen_scores", "station_scores", "warn_inconsistent"]

Array = NDArray[np.float64]

#: median station rotation residual (deg) beyond which the poses do not fit one X
ROTATION_LIMIT_DEG = 10.0
#: median station translation residual, as a fraction of the RMS camera-target distance
TRANSLATION_LIMIT = 0.05
#: another reading of the poses is named when it fits this many times better (both scores
#: in units of their limits, Park's closed form for every reading)
FAR_BETTER = 5.0


def consistency_scores(G: Array, C: Array, X: Array, Y: Array) -> tuple[float, float]:
    """Median station residual of ``G_i X C_i = Y``: rotation (deg) and translation over
    the RMS camera-target distance (unitless)."""
    from kinecal.calibration.handeye.errors import station_residuals

    return station_scores(*station_residuals(G, X, C, Y), C)


def station_scores(rot: Array, tr: Array, C: Array) -> tuple[float, float]:
    """`consistency_scores` from the station residuals ``(n,)`` (deg, length) and the
    ``target2cam`` poses ``(n, 4, 4)``."""
    dist = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    return float(np.median(rot)), float(np.median(tr)) / max(dist, 1e-300)


def _xyzw(T: Array) -> Array:
    """Poses ``(..., 4, 4)`` whose quaternion was stored (x, y, z, w) and read as
    (w, x, y, z), put right."""
    q = quaternion_from_matrix(T[..., :3, :3])
    out = T.copy()
    out[..., :3, :3] = matrix_from_quaternion(q[..., [3, 0, 1, 2]])
    return out


def _fits(r: float, t: float) -> bool:
    return r <= ROTATION_LIMIT_DEG and t <= TRANSLATION_LIMIT


@dataclass
class Inconsistency:
    """Stations that miss ``G_i X C_i = Y``: median rotation (deg) and translation (fraction
    of the camera distance), and the mix-up that makes them fit, when one does."""

    rotation_deg: float
    translation: float
    fits_with: str | None = None
    fit: tuple[float, float] | None = None


def find_inconsistency(F: Array, C: Array, setup: str, X: Array, Y: Array,
                       method: str = "park", *,
                       scores: tuple[float, float] | None = None) -> Inconsistency | None:
    """None when the median station fits ``G_i X C_i = Y`` within `ROTATION_LIMIT_DEG`
    and `TRANSLATION_LIMIT` of the camera distance; else how far it is, and which of the
    usual mix-ups (poses inverted, quaternion order) makes the stations fit.

    Every reading (the poses as given and the six mix-ups) is screened by a closed form
    and the mean target pose, all readings in one vectorised pass (`screen_scores`).

    Parameters
    ----------
    F : ndarray, shape (n, 4, 4)
        ``flange2base`` as given.
    C : ndarray, shape (n, 4, 4)
        ``target2cam`` as given.
    setup : {"eye-in-hand", "eye-to-hand"}
    X, Y : ndarray, shape (4, 4)
        The solution (hand-eye transform, target pose).
    method : str
        Closed form of the solution (the screens always use Shah's, see `screen_scores`).
    scores : (float, float), optional
        `consistency_scores` of the solution, when the caller has them.
    """
    def robot(Fa: Array) -> Array:
        return Fa if setup == "eye-in-hand" else invert_transform(Fa)

    def size(rt: tuple[float, float]) -> float:
        return rt[0] / ROTATION_LIMIT_DEG + rt[1] / TRANSLATION_LIMIT

    r, t = consistency_scores(robot(F), C, X, Y) if scores is None else scores
    other = "eye-to-hand" if setup == "eye-in-hand" else "eye-in-hand"
    Fi, Ci = invert_transform(F), invert_transform(C)
    Fq, Cq = _xyzw(np.stack([F, C]))
    tries = [
        (f"with the robot poses inverted (base2flange, not flange2base: --invert-robot, or "
         f"--setup {other})", Fi, C),
        ("with the target poses inverted (cam2target, not target2cam: --invert-target)",
         F, Ci),
        ("with both pose lists inverted (--invert-robot --invert-target)", Fi, Ci),
        ("with the robot quaternions read in (x, y, z, w) order", Fq, C),
        ("with the target quaternions read in (x, y, z, w) order", F, Cq),
        ("with both quaternions read in (x, y, z, w) order", Fq, Cq),
    ]
    Gs = np.stack([robot(F)] + [robot(Fa) for _, Fa, _ in tries])
    Cs = np.stack([C] + [Ca for _, _, Ca in tries])
    screened = screen_scores(Gs, Cs, ROTATION_LIMIT_DEG, FAR_BETTER)
    found = Inconsistency(r, t)
    as_is = screened[0]
    best = np.inf if np.isnan(as_is[0]) else size(as_is) / FAR_BETTER
    for (label, _, _), sa in zip(tries, screened[1:], strict=True):
        if not np.isnan(sa[0]) and _fits(*sa) and size(sa) < best:
            best, found.fits_with, found.fit = size(sa), label, (float(sa[0]), float(sa[1]))
    if found.fits_with is None and _fits(r, t):
        return None
    return found


def screen_scores(G: Array, C: Array, rotation_limit: float | None = None,
                  far_better: float | None = None) -> Array:
    """`consistency_scores` of a closed form for stacks of readings, all in one pass.

    The closed form is Shah's (2013) on the absolute poses (``sum R_C (x) R_G^T``, its
    leading singular vectors, `calibration.handeye.axzb.shah`): its cost grows with the
    stations, not with their pairs as Park's does, and for a screen of mix-ups (scores of
    degrees and per cent) any consistent closed form serves. ``t_X`` and ``t_Y`` follow by
    least squares from the translation rows of ``G_i X C_i = Y``; the target pose is then
    the mean one (`calibration.handeye.errors.mean_target_pose`).

    Parameters
    ----------
    G, C : ndarray, shape (r, n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand) and
        ``target2cam`` of r readings of the same n stations.

    rotation_limit : float, optional
        Readings after the first whose rotation score exceeds this (deg) get no
        translation score (inf): they cannot fit anyway, and the translation part is half
        the work.
    far_better : float, optional
        With `rotation_limit`: also readings after the first whose rotation score alone,
        in units of `rotation_limit`, is already at least the first reading's score
        (`find_inconsistency`'s size) over `far_better`: they cannot fit that much better.

    Returns
    -------
    ndarray, shape (r, 2)
        Median station rotation residual (deg) and translation residual over the RMS
        camera-target distance; NaN where the robot or camera motions are degenerate
        (`calibration.handeye.solve` raises there).
    """
    from kinecal.calibration.handeye._motions import degenerate_motions

    r, n = G.shape[:2]
    RG, RC = G[..., :3, :3], C[..., :3, :3]
    RGt = np.swapaxes(RG, -1, -2)
    bad = degenerate_motions(np.stack([RGt[:, :1] @ RG[:, 1:],
                                       RC[:, :1] @ np.swapaxes(RC[:, 1:], -1, -2)])).any(axis=0)
    # R_C,i R_Y^-1-part: (R_C (x) R_G^T) vec(R_Y^T R_...) -> Shah's K; R_X^T = R_Z' (left)
    K = (np.swapaxes(RC.reshape(r, n, 9), 1, 2) @ RGt.reshape(r, n, 9))  # sum vec vec^T
    K = K.reshape(r, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(r, 9, 9)  # -> Kronecker
    U = np.linalg.eigh(K @ np.swapaxes(K, 1, 2))[1]  # left singular vectors of K
    RX = np.swapaxes(_signed_rotations(U[:, :, -1]), 1, 2)
    # the rotation score: the mean target rotation and every station's angle from it
    RGX = RG @ RX[:, None]
    RP = RGX @ RC
    RY = project_to_rotation(RP.mean(axis=1))
    out = np.full((r, 2), np.inf)
    out[:, 0] = np.median(np.degrees(_angles(np.swapaxes(RY, 1, 2)[:, None] @ RP)), axis=1)
    need = ~bad & (True if rotation_limit is None else out[:, 0] <= rotation_limit)
    need[0] = not bad[0]
    solvable = np.ones(r, bool)
    if rotation_limit is not None and far_better is not None and need[0]:
        out[0, 1], solvable[0] = (v[0] for v in _translation_scores(G[:1], C[:1], RX[:1]))
        first = out[0, 0] / rotation_limit + out[0, 1] / TRANSLATION_LIMIT
        if solvable[0] and np.isfinite(first):
            need &= out[:, 0] / rotation_limit < first / far_better
        need[0] = False
    if need.any():
        out[need, 1], solvable[need] = _translation_scores(G[need], C[need], RX[need])
    out[bad | ~solvable] = np.nan
    return out


def _translation_scores(G: Array, C: Array, RX: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Median station translation residual over the RMS camera-target distance ``(r,)`` of
    readings ``(r, n, 4, 4)`` with hand-eye rotations `RX` ``(r, 3, 3)`` (``t_X, t_Y`` by
    least squares on ``R_G t_X - t_Y = -t_G - R_G R_X t_C``, then the mean target
    position), and which readings had a solvable system ``(r,)``."""
    r, n = G.shape[:2]
    RG, tG, tC = G[..., :3, :3], G[..., :3, 3], C[..., :3, 3]
    RGt = np.swapaxes(RG, -1, -2)
    RGX = RG @ RX[:, None]
    rhs = -tG - np.einsum("rnij,rnj->rni", RGX, tC)
    N = np.zeros((r, 6, 6))
    N[:, :3, :3] = n * np.eye(3)  # sum R_G^T R_G
    N[:, :3, 3:] = -RGt.sum(axis=1)
    N[:, 3:, :3] = -RG.sum(axis=1)
    N[:, 3:, 3:] = n * np.eye(3)
    b = np.concatenate([np.einsum("rnji,rnj->ri", RG, rhs), -rhs.sum(axis=1)], axis=1)
    solvable = np.abs(np.linalg.det(N)) > 1e-9 * n**6
    tX = np.zeros((r, 3))
    if solvable.any():
        tX[solvable] = np.linalg.solve(N[solvable], b[solvable][..., None])[:, :3, 0]
    tP = np.einsum("rnij,rnj->rni", RGX, tC) + np.einsum("rnij,rj->rni", RG, tX) + tG
    tr = np.linalg.norm(tP - tP.mean(axis=1)[:, None], axis=2)
    dist = np.sqrt(np.mean(np.sum(tC**2, axis=2), axis=1))
    return np.median(tr, axis=1) / np.maximum(dist, 1e-300), solvable


def _angles(R: Array) -> Array:
    """Rotation angles (rad) of ``(..., 3, 3)`` by ``atan2(|axial part|, (trace - 1) / 2)``
    (accurate in absolute terms at any angle; no quaternion per matrix)."""
    ax = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                   R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    return np.arctan2(0.5 * np.linalg.norm(ax, axis=-1),
                      0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0))


def _signed_rotations(v: Array) -> Array:
    """Rotations ``(r, 3, 3)`` proportional to row-major 9-vectors ``(r, 9)`` (det > 0)."""
    R = v.reshape(-1, 3, 3)
    det = np.linalg.det(R)
    # a rotation scaled to a unit 9-vector has |det| = 3^-1.5; a (near-)singular one (the
    # null vector of a degenerate, e.g. one-axis, system) keeps its sign, scale 1
    mag = np.cbrt(np.abs(det))
    mag = np.where(np.isfinite(mag) & (mag > 1e-3), mag, 1.0)
    R = R / (np.where(det < 0, -1.0, 1.0) * mag)[:, None, None]
    return project_to_rotation(np.nan_to_num(R))


def warn_inconsistent(inc: Inconsistency) -> None:
    """The ``handeye-inconsistent`` warning for `find_inconsistency`'s finding."""
    if inc.fits_with is not None and inc.fit is not None:
        hint = (f"they fit {inc.fits_with} (median {inc.fit[0]:.3g} deg, "
                f"{100 * inc.fit[1]:.2g} %): check how the poses were exported")
    else:
        hint = ("check the rotation format and angle unit of both files (--robot-format, "
                "--target-format: rad or :deg, quaternion order w, x, y, z), --setup, and that "
                "row i of both lists is the same station")
    warn("handeye-inconsistent",
         f"the stations do not fit one X and one target pose: the median station is "
         f"{inc.rotation_deg:.3g} deg and {100 * inc.translation:.2g} % of the camera-target "
         f"distance from G X C = Y (measurement noise stays below {ROTATION_LIMIT_DEG:g} deg "
         f"and {100 * TRANSLATION_LIMIT:g} %), so X is meaningless; {hint}")
