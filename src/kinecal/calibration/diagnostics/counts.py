"""``too-few-poses``, ``few-poses`` and ``duplicate-poses``: the count of distinct poses
(stations) against the free parameters, shared by the serial, hand-eye and Stewart checks
(`kinecal.calibration.diagnostics.serial`, `.handeye`, `.stewart`). A module of its own so
that the hand-eye checks load none of the serial arm's."""

from __future__ import annotations

import numpy as np

from kinecal.calibration.diagnostics._common import plural
from kinecal.diagnostics import warn
from kinecal.errors import InputError

__all__ = ["MIN_EQUATION_RATIO", "check_pose_count"]

#: warn when the distinct poses give fewer equations than this many per free parameter
MIN_EQUATION_RATIO = 3


def check_pose_count(n_rows: int, n_distinct: int, rows_per_pose: int, n_free: int,
                     what: str = "poses", repeats: str = "joint readings",
                     well_spread: int = 0, n_poses: int | None = None) -> None:
    """Refuse too few distinct poses; warn on few or repeated ones.

    `well_spread` is the number of parameters well-spread poses identify (0: unknown):
    when the few poses given identify fewer (one pose identifies 3), the advice on how
    many poses to measure counts those, not the few the poses at hand determine.
    `n_poses`: the arm configurations the `n_distinct` rows were measured in, when a pose
    is measured at several markers (one row each): the counts and the advice are in poses.

    Raises
    ------
    InputError
        ``too-few-poses``: the distinct poses give no more equations than free parameters
        (nothing left to estimate the noise or check the fit).
    """
    eq = rows_per_pose * n_distinct
    if n_distinct < n_rows:
        warn("duplicate-poses",
             f"{n_rows - n_distinct} of {n_rows} {what} repeat the {repeats} of another "
             f"row ({n_distinct} distinct): repeated rows add no geometry, and standard errors "
             f"assume independent measurements; measure distinct {what}")
    poses = n_distinct if n_poses is None or n_poses >= n_distinct else n_poses
    per = rows_per_pose * n_distinct / max(poses, 1)  # equations per distinct pose
    counted = plural(poses, "distinct " + what.rstrip("s"))
    if poses < n_distinct:
        each = n_distinct / poses
        counted += (f" ({n_distinct} rows, {each:.0f} markers each)" if each == round(each)
                    else f" ({n_distinct} rows, {each:.3g} markers on average)")
    gives = "gives" if poses == 1 else "give"
    if eq <= n_free:
        need = max(n_free, well_spread)
        least = int(need // per) + 1
        good = int(np.ceil(MIN_EQUATION_RATIO * need / per))
        spread = (f"well-spread {what} identify {need} parameters: measure " if need > n_free
                  else "")
        raise InputError(
            f"{counted} {gives} {eq} equations for "
            f"{n_free} free parameters: expected more than {n_free} ({spread}at least {least} "
            f"distinct {what}, {good} or more recommended) [too-few-poses]")
    if eq < MIN_EQUATION_RATIO * n_free:
        warn("few-poses",
             f"{counted} {gives} {eq} equations for {n_free} free "
             f"parameters (fewer than {MIN_EQUATION_RATIO} per parameter): the fit can absorb "
             "noise and its uncertainty is unreliable; measure at least "
             f"{int(np.ceil(MIN_EQUATION_RATIO * n_free / per))} distinct {what}")
