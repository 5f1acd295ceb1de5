"""Plausibility checks of serial-arm calibration data, run before the fit.

`check_serial_data` runs them all from `kinecal.calibrate`; each check is also a plain
function of arrays and the model, with its stable code (docs/diagnostics.md):
``too-few-poses`` (an `InputError`), ``few-poses``, ``duplicate-poses``,
``validation-overlap``, ``rank-deficient``, and those of `units` (``joint-limits``,
``joint-units``, ``scale-mismatch``, ``mirrored-frame``, ``initial-error``).

The reference for "what this model can identify" is a set of well-spread random poses
within the model's joint limits (`reference`): a pose set that identifies fewer
parameters than those is rank-deficient beyond the model's usual confounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics._common import JOINT_RESOLUTION, repeat_groups
from kinecal.calibration.diagnostics.counts import MIN_EQUATION_RATIO, check_pose_count
from kinecal.calibration.diagnostics.observations import pose_groups
from kinecal.calibration.diagnostics.units import (
    check_frame_and_units,
    check_joint_limits,
    check_joint_units,
)
from kinecal.calibration.identifiability import IdentifiabilityReport
from kinecal.data import Measurements
from kinecal.diagnostics import warn
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "MIN_EQUATION_RATIO",
    "Reference",
    "SerialDataInfo",
    "check_pose_count",
    "check_pose_set",
    "check_rank",
    "check_serial_data",
    "check_validation_overlap",
    "reference",
]
# the unit checks live in `units`; re-exported for the calibration and CLI entry points
__all__ += ["check_frame_and_units", "check_joint_limits", "check_joint_units"]

Array = NDArray[np.float64]

#: random poses of the reference analysis (at least; 4 per parameter)
REFERENCE_POSES = 100


@dataclass
class Reference:
    """What a model identifies on well-spread random poses (`reference`).

    Attributes
    ----------
    report : IdentifiabilityReport
        Identifiability of the analysed parameters on the reference poses.
    reach : float
        Largest distance of the tool point from the base origin (length unit).
    tolerance_error : float
        RMS position effect of errors uniform within the model's tolerances on its
        calibratable parameters, base frame excluded (length unit).
    """

    report: IdentifiabilityReport
    reach: float
    tolerance_error: float


@dataclass
class SerialDataInfo:
    """What the data checks found that the fit and its uncertainty need.

    Attributes
    ----------
    groups : ndarray of int, shape (N,)
        Pose group of each row (rows with the same joint readings share one).
    n_distinct : int
        Number of distinct poses.
    unique_rows : ndarray of int or None
        First row of each group of exact copies (joint readings, measurements, weights),
        when there are copies: the rows that carry information.
    lost : list of str
        Parameters identifiable on well-spread poses but not on these.
    reference : Reference
    poses : ndarray of int, shape (N,) or None
        Pose of each row when poses were measured at several markers
        (`kinecal.calibration.diagnostics.observations.pose_groups`); None: a pose per row.
    """

    groups: Array
    n_distinct: int
    unique_rows: Array | None
    lost: list[str] = field(default_factory=list)
    reference: Reference | None = None
    poses: Array | None = None


# ---------------------------------------------------------------------- reference
def _model_key(model: SerialModel) -> tuple:
    return (model.convention, model.parameter_names, model.nominal.tobytes(),
            np.asarray(model.joint_limits).tobytes(), model.is_prismatic().tobytes(),
            tuple(sorted((model.tolerances or {}).items())))


_CACHE: dict[tuple, Reference] = {}


def _reference(model: SerialModel, names: tuple[str, ...], rotations: bool,
               tol: float) -> Reference:
    from kinecal.calibration.serial.problem import analyse_poses
    from kinecal.calibration.serial.simulate import random_configurations

    n = max(REFERENCE_POSES, 4 * model.n_params)
    q = random_configurations(model, n, np.random.default_rng(0))
    marker = np.arange(n) % len(model.marker_names) if model.marker_names else None
    T = model.fk(q, None, marker)
    ref = Measurements(q, T[:, :3, 3], None, "reference poses", T[:, :3, :3] if rotations else None,
                       marker=marker, marker_names=model.marker_names if marker is not None
                       else ())
    rep = analyse_poses(model, ref, list(names), tol=tol)
    # a robot system's tips stand on several bases: the measurement frame's origin
    origin = (model.nominal[model.index(list(BASE_NAMES[:3]))]
              if set(BASE_NAMES[:3]) <= set(model.parameter_names) else np.zeros(3))
    reach = float(np.linalg.norm(T[:, :3, 3] - origin, axis=1).max())
    cal = [p for p in model.calibratable if p not in BASE_NAMES]
    err = 0.0
    if cal:
        idx = model.index(cal)
        half = np.where(model.is_angle()[idx], model.tolerances["angle"],
                        model.tolerances["length"])
        J = model.identification_jacobian(q, marker=marker)[:, :, idx]
        err = float(np.sqrt((J**2 @ (half**2 / 3.0)).sum(axis=1).mean()))
    return Reference(rep, reach, err)


def reference(model: SerialModel, names: Sequence[str], rotations: bool = False,
              tol: float = 1e-4) -> Reference:
    """Identifiability of `names`, reach and tolerance-sized error on random poses.

    The poses are uniform within the model's joint limits (revolute ranges clipped to
    +-180 deg), ``max(100, 4 n_params)`` of them, seed 0; cached per model.
    """
    key = (_model_key(model), tuple(names), bool(rotations), float(tol))
    if key not in _CACHE:
        if len(_CACHE) >= 32:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = _reference(model, tuple(names), bool(rotations), float(tol))
    return _CACHE[key]


# ------------------------------------------------------------------- pose counts
def _marker_column(data: Measurements) -> Array:
    """The marker index of each pose as a column ``(N, 1)`` (zeros with one tool point): a
    pose measured at another marker is another measurement, not a repeat."""
    m = getattr(data, "marker", None)
    return np.zeros((len(data), 1)) if m is None else np.asarray(m, dtype=float)[:, None]


# ---------------------------------------------------------------- validation
def check_validation_overlap(cal: Measurements, val: Measurements) -> None:
    """``validation-overlap``: validation rows whose joint readings repeat calibration rows."""
    qc = np.asarray(cal.q, dtype=float)
    qv = np.asarray(val.q, dtype=float)
    if qc.shape[1] != qv.shape[1] or not len(qv):
        return
    mc, mv = _marker_column(cal), _marker_column(val)
    groups, _ = repeat_groups(np.concatenate([qc, qv]), np.concatenate([mc, mv]))
    shared = np.isin(groups[len(qc):], groups[:len(qc)])
    n = int(shared.sum())
    if n:
        warn("validation-overlap",
             f"{n} of {len(qv)} validation poses repeat calibration poses"
             + (" (the validation set is the calibration set)" if n == len(qv) else "")
             + ": validation statistics are then not independent of the fit; validate on "
             "poses not used for calibration")


# ---------------------------------------------------------------------- rank
def check_rank(model: SerialModel, data: Measurements, names: Sequence[str],
               report: IdentifiabilityReport, ref: Reference, tol: float) -> list[str]:
    """``rank-deficient``: parameters that well-spread poses identify but these do not.

    A parameter counts as lost only when it is unidentifiable on the data even at a
    threshold 100 times looser than `tol` (a clearly deficient pose set, e.g. one joint
    moved), while identifiable on the reference poses at `tol`. Returns the lost names.
    """
    if report.rank >= ref.report.rank:
        return []
    from kinecal.calibration.serial.problem import analyse_poses

    loose = analyse_poses(model, data, list(names), tol=tol * 1e-2)
    lost = [n for n in ref.report.identifiable if n not in loose.identifiable]
    if loose.rank >= ref.report.rank or not lost:
        return []
    moved = np.flatnonzero(np.ptp(np.asarray(data.q, dtype=float), axis=0) > JOINT_RESOLUTION)
    joints = ", ".join(f"q{j + 1}" for j in moved) or "none"
    shown = ", ".join(lost[:8]) + (", ..." if len(lost) > 8 else "")
    warn("rank-deficient",
         f"these poses identify {loose.rank} parameters where well-spread poses identify "
         f"{ref.report.rank} (joints moved: {joints}); not determined: {shown}; the "
         "calibrated model is only valid near these poses and its uncertainty elsewhere is "
         "unbounded: move every joint across its range")
    return lost


# ---------------------------------------------------------------------- all
def check_serial_data(model: SerialModel, data: Measurements, names: Sequence[str],
                      report: IdentifiabilityReport, *, validate: Measurements | None = None,
                      rank_tol: float = 1e-4) -> SerialDataInfo:
    """Every data check of a serial calibration (the module docstring's codes).

    Parameters
    ----------
    model : SerialModel
        Nominal model.
    data : Measurements
        Calibration poses.
    names : sequence of str
        Free parameters the fit will use.
    report : IdentifiabilityReport
        Identifiability of the candidate parameters on `data` (at `rank_tol`).
    validate : Measurements, optional
        Validation poses.
    rank_tol : float
        Rank threshold of `report`.

    Returns
    -------
    SerialDataInfo

    Raises
    ------
    InputError
        ``too-few-poses``; tolerances larger than the machine
        (`kinecal.calibration.diagnostics.sizes.check_tolerances`).
    """
    from kinecal.calibration.diagnostics.sizes import check_tolerances

    check_tolerances(model)  # the search box and the tolerance check need sane ones
    q = np.asarray(data.q, dtype=float)
    rows = 3 if data.rotations is None else 6
    groups, n_distinct = repeat_groups(q, _marker_column(data))
    poses = None if data.marker is None else pose_groups(q, data.marker)[0]
    well_spread = 0
    if rows * n_distinct <= len(names):  # refused below: say how many poses would do
        well_spread = reference(model, report.names, data.rotations is not None,
                                rank_tol).report.rank
    distinct_poses = None if poses is None else repeat_groups(q)[1]
    check_pose_count(len(q), n_distinct, rows, len(names), well_spread=well_spread,
                     n_poses=distinct_poses)
    unique_rows = None
    if n_distinct < len(q):
        parts = [q, _marker_column(data), data.xyz] + [x for x in (data.rotations, data.weights)
                                                       if x is not None]
        exact, n_exact = repeat_groups(*parts, resolution=0.0)
        if n_exact < len(q):
            unique_rows = np.sort(np.unique(exact, return_index=True)[1])
    ref = reference(model, report.names, data.rotations is not None, rank_tol)
    base_free = set(BASE_NAMES) <= set(model.calibratable)
    check_joint_limits(model, q)
    warned = check_joint_units(model, q)
    check_frame_and_units(model, data, ref, base_free, joint_units_warned=warned)
    if validate is not None:
        check_validation_overlap(data, validate)
        check_joint_limits(model, validate.q, "validation poses")
        if len(validate) >= 2:
            warned = check_joint_units(model, validate.q, "validation poses")
            check_frame_and_units(model, validate, ref, base_free, "validation poses", warned)
    lost = check_rank(model, data, report.names, report, ref, rank_tol)
    return SerialDataInfo(groups, n_distinct, unique_rows, lost, ref, poses)


def check_pose_set(model: SerialModel, data: Measurements, report: IdentifiabilityReport,
                   tol: float | None = None) -> list[str]:
    """The checks that apply to a pose set alone (``kinecal identifiability --data``):
    ``duplicate-poses``, ``joint-limits``, ``joint-units``, ``rank-deficient``.

    `report` is the identifiability of the pose set; `tol` its rank threshold (default the
    analysis default). Returns the parameters lost against well-spread poses.
    """
    from kinecal.calibration.identifiability import RANK_TOL

    tol = RANK_TOL if tol is None else tol
    q = np.asarray(data.q, dtype=float)
    _, n_distinct = repeat_groups(q, _marker_column(data))
    if n_distinct < len(q):
        warn("duplicate-poses",
             f"{len(q) - n_distinct} of {len(q)} poses repeat the joint readings of another "
             f"row ({n_distinct} distinct): repeated rows add no information about the geometry")
    check_joint_limits(model, q)
    check_joint_units(model, q)
    ref = reference(model, report.names, data.rotations is not None, tol)
    return check_rank(model, data, report.names, report, ref, tol)
