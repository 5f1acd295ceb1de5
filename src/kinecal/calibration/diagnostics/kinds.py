"""Plausibility checks of the gauge measurement kinds (`kinecal.calibration.blocks`).

Codes (docs/diagnostics.md): ``scale-mismatch`` for a distance column in another unit
than the model's (a ballbar's or a bar's lengths in metres for a millimetre model),
``pivot-moved`` (a ballbar's distances fit no single pivot to the noise), ``point-spread``
(a socket's touches disagree by more than the noise), ``plane-not-flat`` (a "plane" whose
touches are not flat to the noise), ``initial-error`` (a file far from the nominal model
even with its own unknowns fitted: another robot's file among the files).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtr, chdtri, fdtri
from kinecal.calibration.diagnostics._common import ALPHA, plural, unit_factor_name
from kinecal.diagnostics import warn

__all__ = ["UNIT_RATIO", "check_block_noise", "check_distance_units", "check_group_spread",
           "check_initial_error"]

Array = NDArray[np.float64]

#: stated / model distances beyond this factor (either way) are another unit, not an
#: arm's error (a calibration corrects lengths by far less than 50 %)
UNIT_RATIO = 1.5


def check_distance_units(name: str, stated: Array, model: Array, unit: str,
                         what: str = "distances") -> bool:
    """``scale-mismatch``: stated distances against those the nominal model gives.

    Parameters
    ----------
    name : str
        The measurement set (``ballbar (bb.csv)``).
    stated, model : ndarray, shape (n,)
        The file's distances and the nominal model's (length unit), paired.
    unit : str
        The model's length unit.

    Returns
    -------
    bool
        True when it warned.
    """
    stated = np.asarray(stated, dtype=float)
    model = np.asarray(model, dtype=float)
    ok = np.isfinite(model) & (model > 0) & (stated > 0)
    if not ok.any():
        return False
    ratio = float(np.median(stated[ok] / model[ok]))
    if 1.0 / UNIT_RATIO < ratio < UNIT_RATIO:
        return False
    warn("scale-mismatch",
         f"{name}: the {what} are {ratio:.4g} times those of the nominal model (median "
         f"{np.median(stated[ok]):.4g} vs {np.median(model[ok]):.4g} {unit}): probably "
         f"{unit_factor_name(ratio)}; give them in {unit}, the model's length unit")
    return True


def check_group_spread(code: str, name: str, word: str, groups: Sequence[str], rss: Array,
                       dof: Array, *, stated: bool, advice: str) -> list[str]:
    """A group (pivot, point, plane) whose rows fit its own unknowns worse than the noise.

    Parameters
    ----------
    code : str
        ``pivot-moved``, ``point-spread`` or ``plane-not-flat``.
    name, word : str
        The measurement set and what a group is (``pivot``).
    groups : sequence of str
        Group ids.
    rss : ndarray, shape (G,)
        Each group's sum of squared residuals in units of the noise used by the fit.
    dof : ndarray of int, shape (G,)
        Each group's residual rows minus its own unknowns (the arm's share is left out:
        the test errs on the quiet side).
    stated : bool
        The noise was stated (chi-square test against it); otherwise it was estimated
        from all groups and each group is tested against the others (F-test).
    advice : str
        What to do, appended to the message.

    Returns
    -------
    list of str
        The groups flagged.
    """
    rss = np.asarray(rss, dtype=float)
    dof = np.asarray(dof, dtype=int)
    G = rss.size
    use = dof > 0
    if not use.any():
        return []
    level = ALPHA / max(int(use.sum()), 1)  # Bonferroni over the groups
    flagged, ratios = [], []
    total, total_dof = float(rss[use].sum()), int(dof[use].sum())
    for g in range(G):
        if not use[g]:
            continue
        if stated:
            limit = float(chdtri(dof[g], level))
            bad = rss[g] > limit
            ratio = np.sqrt(rss[g] / dof[g])
        else:
            rest, rest_dof = total - rss[g], total_dof - dof[g]
            if rest_dof <= 0 or rest <= 0:
                continue
            f = (rss[g] / dof[g]) / (rest / rest_dof)
            bad = f > float(fdtri(dof[g], rest_dof, 1.0 - level))
            ratio = np.sqrt(f)
        if bad:
            flagged.append(groups[g])
            ratios.append(ratio)
    if flagged:
        shown = ", ".join(f"{g!r} ({r:.3g}x)" for g, r in zip(flagged[:6], ratios[:6],
                                                             strict=False))
        against = "the stated noise" if stated else "the other " + word + "s"
        warn(code, f"{name}: {plural(len(flagged), word)} fit worse than {against} "
                   f"(RMS residual in units of the noise): {shown}; {advice}")
    return flagged


def check_initial_error(name: str, error: float, reach: float, tolerance_error: float,
                        unit: str) -> bool:
    """``initial-error``: a measurement set far from the nominal model even with its own
    unknowns (pivots, points, planes) fitted to it: the wrong model, or another robot's
    file among the files. `error` is the RMS error per observation at nominal (length
    unit); the limits are those of the tracker check
    (`kinecal.calibration.diagnostics.units`). Returns True when it warned."""
    from kinecal.calibration.diagnostics.units import REACH_FRACTION, TOLERANCE_FACTOR

    limit = max(REACH_FRACTION * reach, TOLERANCE_FACTOR * tolerance_error)
    if not error > limit:
        return False
    warn("initial-error",
         f"{name}: {error:.4g} {unit} RMS from the nominal model with its own unknowns "
         f"fitted, {100 * error / reach:.0f} % of the reach ({reach:.4g} {unit}) and beyond "
         f"what the tolerances allow ({limit:.3g} {unit}): probably a file of another robot "
         "or model, or wrong joint order or zero offsets")
    return True


def check_block_noise(name: str, rss: float, redundancy: float, noise_of: str) -> bool:
    """``residual-above-noise`` / ``residual-below-noise``: a measurement set whose stated
    noise its residual exceeds, or whose residual is at most half of it (chi-square tests at
    `ALPHA`, either tail, as for one tracker file: `kinecal.calibration.diagnostics.noise`;
    `rss` in units of the stated noise, `redundancy` the degrees of freedom its rows keep
    after the fit). Returns True when it warned."""
    from kinecal.calibration.diagnostics.noise import MAX_DEFICIT

    if not redundancy > 0.5:
        return False
    ratio = float(np.sqrt(rss / redundancy))
    if float(chdtr(redundancy, rss)) < ALPHA and ratio <= MAX_DEFICIT:
        warn("residual-below-noise",
             f"{name}: the residual is {ratio:.3g} times the stated noise of {noise_of} "
             f"(chi-square {rss:.4g} on {redundancy:.1f} degrees of freedom, lower tail p = "
             f"{float(chdtr(redundancy, rss)):.2g}): the stated noise is pessimistic (another "
             "unit, or the instrument's worst case rather than its 1-sigma noise), and so "
             "are the standard errors computed with it")
        return True
    limit = float(chdtri(redundancy, ALPHA))
    if not rss > limit:
        return False
    warn("residual-above-noise",
         f"{name}: the residual is {ratio:.3g} times the stated noise "
         f"of {noise_of} (chi-square {rss:.4g} on {redundancy:.1f} degrees of freedom, "
         f"{1 - ALPHA:.1%} limit {limit:.4g}): the stated sigma is too small, or the model "
         "or the data are wrong; without --sigma the noise is estimated from the fit")
    return True
