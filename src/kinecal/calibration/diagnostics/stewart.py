"""Plausibility checks of a Stewart-platform (parallel CMM) geometry calibration.

Codes (docs/diagnostics.md): ``too-few-poses`` (an `InputError`), ``few-poses``,
``duplicate-poses``, ``scale-mismatch``, ``angle-units``, ``leg-range``, ``initial-error``,
``validation-overlap``, ``rank-deficient``, ``outliers``.

The unit checks compare the leg readings with the inverse kinematics of the measured
poses under every reading of the units (poses and legs in the geometry's length unit or a
thousand times off, pose angles in degrees as the files say or in radians): a reading that
explains the data `EXPLAINS_BETTER` times better than the data as given is named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics._common import (
    chi_outliers,
    plural,
    repeat_groups,
)
from kinecal.calibration.diagnostics.counts import check_pose_count
from kinecal.calibration.diagnostics.units import EXPLAINS_BETTER, REACH_FRACTION
from kinecal.calibration.stewart.identification import identification_jacobian
from kinecal.diagnostics import warn
from kinecal.kinematics.stewart.platform import N_PARAMETERS

__all__ = [
    "POSE_RESOLUTION",
    "StewartDataInfo",
    "check_stewart_data",
    "check_stewart_fit",
    "check_stewart_units",
    "data_rank",
    "reference_rank",
]

Array = NDArray[np.float64]

#: two measured poses closer than this (length unit and rad, relative to the leg stroke for
#: lengths) in every coordinate are the same pose
POSE_RESOLUTION = 1e-9
#: length factors tried by the unit check (data / geometry)
_FACTORS = (1.0, 1e3, 1e-3)
_FACTOR_NAMES = {1e3: "millimetres in a metre geometry", 1e-3: "metres in a millimetre geometry"}


@dataclass
class StewartDataInfo:
    """What the data checks found.

    Attributes
    ----------
    n_distinct : int
        Distinct poses.
    unique_rows : ndarray of int or None
        First row of each group of exact copies, when there are copies.
    reference_rank : int
        Rank the 42 parameters reach on well-spread random workspace poses.
    """

    n_distinct: int
    unique_rows: Array | None
    reference_rank: int


_RANKS: dict[tuple, int] = {}


#: rank threshold (relative singular value) of "identifiable" on well-spread poses, as
#: the serial calibration's default; a pose set loses a parameter only below a 100 times
#: looser one (`DATA_RANK_TOL`)
RANK_TOL = 1e-4
DATA_RANK_TOL = 1e-6


def reference_rank(geom) -> int:
    """Rank (at `RANK_TOL`) of the 42-parameter Jacobian on 200 random workspace poses
    (seed 0), cached per geometry."""
    key = (geom.parameters.tobytes(), geom.probe_offset, tuple(geom.leg_range))
    if key not in _RANKS:
        poses = geom.random_poses(200, np.random.default_rng(0))
        s = np.linalg.svd(identification_jacobian(geom, poses), compute_uv=False)
        _RANKS[key] = int((s > RANK_TOL * s[0]).sum())
    return _RANKS[key]


def data_rank(singular_values: Array) -> int:
    """Rank of a pose set's Jacobian at `DATA_RANK_TOL` (relative singular values)."""
    s = np.asarray(singular_values, dtype=float)
    return int((s > DATA_RANK_TOL * s[0]).sum()) if s.size and s[0] > 0 else 0


def _leg_rms(geom, poses: Array, legs: Array) -> float:
    with np.errstate(all="ignore"):
        r = geom.inverse(poses) - legs
    v = float(np.sqrt(np.mean(r * r)))
    return v if np.isfinite(v) else float("inf")


def check_stewart_units(geom, poses: Array, legs: Array, unit: str = "m",
                        what: str = "poses") -> bool:
    """``scale-mismatch`` and ``angle-units``: the data read in other units fit far better.

    Parameters
    ----------
    geom : StewartPlatform
    poses : ndarray, shape (N, 6)
        Measured poses as read (length unit, rad).
    legs : ndarray, shape (N, 6)
        Leg readings as read.
    unit : str
        The geometry's length unit (for the messages).

    Returns
    -------
    bool
        True when it warned (the data's units are wrong: other checks would only repeat it).
    """
    given = _leg_rms(geom, poses, legs)
    best = (given, 1.0, 1.0, False)
    for fp in _FACTORS:
        for fl in _FACTORS:
            for rad in (False, True):
                if fp == fl == 1.0 and not rad:
                    continue
                x = np.array(poses, dtype=float, copy=True)
                x[:, :3] /= fp
                if rad:  # the angle columns held radians, read as degrees
                    x[:, 3:] *= 180.0 / np.pi
                e = _leg_rms(geom, x, np.asarray(legs) / fl)
                if e < best[0]:
                    best = (e, fp, fl, rad)
    e, fp, fl, rad = best
    if not e * EXPLAINS_BETTER < given:
        return False
    if fp != 1.0 or fl != 1.0:
        parts = [f"{name} look like {_FACTOR_NAMES[f]}"
                 for name, f in (("positions", fp), ("leg readings", fl)) if f != 1.0]
        warn("scale-mismatch",
             f"the {what} fit the geometry {given / e:.0f} times better with other length "
             f"units ({' and '.join(parts)}; leg RMS {e:.3g} vs {given:.3g} {unit}): give "
             f"positions and leg readings in the geometry's unit ({unit})")
    if rad:
        warn("angle-units",
             f"the {what} fit the geometry {given / e:.0f} times better when the pose angles "
             "(alpha, beta, gamma) are read as radians: the files expect degrees; convert them")
    return True


def check_leg_range(geom, legs: Array, what: str = "poses") -> None:
    """``leg-range``: leg readings outside the geometry's ``leg_range``."""
    lo, hi = geom.leg_range
    legs = np.asarray(legs, dtype=float)
    span = hi - lo if np.isfinite(hi) else max(abs(lo), 1.0)
    out = (legs < lo - 1e-9 * span) | (legs > hi + 1e-9 * span)
    if out.any():
        rows = int(out.any(axis=1).sum())
        warn("leg-range",
             f"{plural(rows, 'row')} of the {what} have leg readings outside the geometry's "
             f"leg_range [{lo:.6g}, {hi:.6g}] (seen {legs.min():.6g} to {legs.max():.6g}): "
             "check the leg columns' order and units, or the geometry's leg_range")


def check_stewart_data(geom, data, *, validate=None, unit: str = "m") -> StewartDataInfo:
    """Every data check of a Stewart calibration (see the module docstring).

    Raises
    ------
    InputError
        ``too-few-poses``: the distinct poses give no more than 42 equations.
    """
    poses = np.asarray(data.poses, dtype=float)
    legs = np.asarray(data.legs, dtype=float)
    _, n_distinct = repeat_groups(poses, resolution=POSE_RESOLUTION)
    check_pose_count(len(poses), n_distinct, 6, N_PARAMETERS, repeats="measured poses")
    unique_rows = None
    if n_distinct < len(poses):
        exact, n_exact = repeat_groups(poses, legs, resolution=0.0)
        if n_exact < len(poses):
            unique_rows = np.sort(np.unique(exact, return_index=True)[1])
    wrong_units = check_stewart_units(geom, poses, legs, unit)
    if not wrong_units:
        check_leg_range(geom, legs)
        lo, hi = geom.leg_range
        stroke = hi - lo if np.isfinite(hi) else float(np.mean(legs))
        e0 = _leg_rms(geom, poses, legs)
        if e0 > REACH_FRACTION * stroke:
            warn("initial-error",
                 f"the leg readings differ from the nominal geometry's by {e0:.4g} {unit} RMS, "
                 f"{100 * e0 / stroke:.0f} % of the leg stroke ({stroke:.4g} {unit}): probably "
                 "another geometry, legs in another order, or poses in another frame")
    if validate is not None:
        vp = np.asarray(validate.poses, dtype=float)
        g, _ = repeat_groups(np.concatenate([poses, vp]), resolution=POSE_RESOLUTION)
        shared = int(np.isin(g[len(poses):], g[:len(poses)]).sum())
        if shared:
            warn("validation-overlap",
                 f"{shared} of {len(vp)} validation poses repeat calibration poses: validation "
                 "statistics are then not independent of the fit; validate on other poses")
        check_stewart_units(geom, vp, validate.legs, unit, "validation poses")
    return StewartDataInfo(n_distinct, unique_rows, reference_rank(geom))


def check_stewart_fit(residuals: Array, rank: int, reference: int, unit: str = "m",
                      unidentifiable: list[str] | None = None) -> list[int]:
    """``rank-deficient`` and ``outliers`` after a Stewart calibration.

    Parameters
    ----------
    residuals : ndarray, shape (N, 6)
        Leg residuals after the fit.
    rank, reference : int
        Rank of the 42 parameters on the calibration poses and on well-spread poses.
    unidentifiable : list of str, optional
        The parameters pivoted QR drops on the calibration poses.

    Returns
    -------
    list of int
        Outlier poses (0-based).
    """
    if rank < reference:
        lost = ", ".join((unidentifiable or [])[:8])
        warn("rank-deficient",
             f"these poses identify {rank} of the 42 geometry parameters where well-spread "
             f"workspace poses identify {reference} (not determined: {lost}): the calibrated "
             "geometry's uncertainty is unbounded; spread the poses over the workspace in "
             "position and orientation")
    d = np.linalg.norm(np.asarray(residuals, dtype=float), axis=1)
    out = chi_outliers(d, 6)
    if out:
        shown = ", ".join(str(i) for i in out[:10]) + (", ..." if len(out) > 10 else "")
        warn("outliers",
             f"{plural(len(out), 'pose')} ({shown}; 0-based) {'has' if len(out) == 1 else 'have'}"
             f" leg residuals of up to {d[out].max():.3g} {unit} against a median of "
             f"{np.median(d):.3g} {unit}: outliers pull the least-squares fit; check those "
             "measurements")
    return out
