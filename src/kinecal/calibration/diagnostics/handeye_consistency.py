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
from kinecal.errors import InputError
from kinecal.spatial import invert_transform, matrix_from_quaternion, quaternion_from_matrix

__all__ = ["ROTATION_LIMIT_DEG", "TRANSLATION_LIMIT", "Inconsistency", "consistency_scores",
           "find_inconsistency", "warn_inconsistent"]

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

    rot, tr = station_residuals(G, X, C, Y)
    dist = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    return float(np.median(rot)), float(np.median(tr)) / max(dist, 1e-300)


def _xyzw(T: Array) -> Array:
    """Poses whose quaternion was stored (x, y, z, w) and read as (w, x, y, z), put right."""
    q = quaternion_from_matrix(T[:, :3, :3])
    out = T.copy()
    out[:, :3, :3] = matrix_from_quaternion(q[:, [3, 0, 1, 2]])
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
                       method: str = "park") -> Inconsistency | None:
    """None when the median station fits ``G_i X C_i = Y`` within `ROTATION_LIMIT_DEG`
    and `TRANSLATION_LIMIT` of the camera distance; else how far it is, and which of the
    usual mix-ups (poses inverted, quaternion order) makes the stations fit.

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
        Closed form used to try the alternatives.
    """
    from kinecal.calibration.handeye._motions import check_motions, motion_pairs
    from kinecal.calibration.handeye.axxb import SOLVERS
    from kinecal.calibration.handeye.errors import mean_target_pose

    def solve(G: Array, Ca: Array) -> tuple[Array, Array]:
        """Park's closed form and the mean target pose (`calibration.handeye.solve`)."""
        check_motions(invert_transform(G[:1]) @ G[1:], "robot motions")
        check_motions(Ca[:1] @ invert_transform(Ca[1:]), "camera motions")
        Xa = SOLVERS["park"](*motion_pairs(G, Ca, "all"))
        return Xa, mean_target_pose(G, Xa, Ca)

    def robot(Fa: Array) -> Array:
        return Fa if setup == "eye-in-hand" else invert_transform(Fa)

    def screen(Fa: Array, Ca: Array) -> tuple[float, float] | None:
        """Scores of Park's closed form (fast, the same for every reading)."""
        try:
            Xa, Ya = solve(robot(Fa), Ca)
        except InputError:
            return None
        return consistency_scores(robot(Fa), Ca, Xa, Ya)

    def size(rt: tuple[float, float]) -> float:
        return rt[0] / ROTATION_LIMIT_DEG + rt[1] / TRANSLATION_LIMIT

    r, t = consistency_scores(robot(F), C, X, Y)
    other = "eye-to-hand" if setup == "eye-in-hand" else "eye-in-hand"
    tries = [
        (f"with the robot poses inverted (base2flange, not flange2base: --invert-robot, or "
         f"--setup {other})", invert_transform(F), C),
        ("with the target poses inverted (cam2target, not target2cam: --invert-target)",
         F, invert_transform(C)),
        ("with both pose lists inverted (--invert-robot --invert-target)",
         invert_transform(F), invert_transform(C)),
        ("with the robot quaternions read in (x, y, z, w) order", _xyzw(F), C),
        ("with the target quaternions read in (x, y, z, w) order", F, _xyzw(C)),
        ("with both quaternions read in (x, y, z, w) order", _xyzw(F), _xyzw(C)),
    ]
    found = Inconsistency(r, t)
    as_is = screen(F, C)
    best = np.inf if as_is is None else size(as_is) / FAR_BETTER
    for label, Fa, Ca in tries:
        sa = screen(Fa, Ca)
        if sa is not None and _fits(*sa) and size(sa) < best:
            best, found.fits_with, found.fit = size(sa), label, sa
    if found.fits_with is None and _fits(r, t):
        return None
    return found


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
