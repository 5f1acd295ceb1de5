"""Plausibility checks of a serial-arm fit, run after it.

Codes: ``unidentifiable-free``, ``parameter-tolerance``, ``residual-offset``,
``lack-of-fit``, ``outliers`` (docs/diagnostics.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal._special import fdtri
from kinecal.calibration.diagnostics._common import (
    ALPHA,
    FitTest,
    plural,
)
from kinecal.calibration.diagnostics.observations import describe_poses, pose_outliers
from kinecal.calibration.diagnostics.sizes import serial_size
from kinecal.diagnostics import warn
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "PRACTICAL_RSS_DROP",
    "TOLERANCE_MULTIPLE",
    "check_lack_of_fit",
    "check_outliers",
    "check_parameter_tolerance",
    "check_residual_offset",
    "check_unidentifiable_free",
    "pose_leverage",
]

Array = NDArray[np.float64]

#: a parameter further from nominal than this many tolerances (beyond 3 standard errors)
#: contradicts the model file: its tolerances say the real arm cannot be that different
TOLERANCE_MULTIPLE = 5.0
#: a structure in the residual is reported when it is significant (F-test at `ALPHA`) and
#: dominates it: removing it would lower the residual sum of squares by at least this
#: fraction (the RMS error at least halves)
PRACTICAL_RSS_DROP = 0.75


def _values(model: SerialModel, names: Sequence[str], values: Array) -> str:
    """``name = value unit`` in the model file's units."""
    angle = model.is_angle()[model.index(list(names))]
    deg = model.angle_unit == "deg"
    out = []
    for n, v, a in zip(names, values, angle, strict=True):
        if a:
            out.append(f"{n} {np.degrees(v) if deg else v:+.3g} {model.angle_unit}")
        else:
            out.append(f"{n} {v:+.3g} {model.length_unit}")
    return ", ".join(out)


def check_unidentifiable_free(names: Sequence[str], free_choice: object) -> None:
    """``unidentifiable-free``: free parameters the poses cannot identify individually
    (with ``free="identifiable"``: chosen at the nominal geometry, lost at the solution)."""
    if not names:
        return
    some = f"{len(names)} parameter{'s' if len(names) > 1 else ''}"
    if free_choice == "identifiable":
        warn("unidentifiable-free",
             f"{some} identifiable at the nominal geometry are not at the solution "
             f"({', '.join(names)}): the fit went where these poses no longer determine "
             "them, their values are arbitrary and have no standard error; check the other "
             "warnings (units, joint order, another robot's file)")
        return
    how = "--free all" if free_choice == "all" else "the explicit free list"
    warn("unidentifiable-free",
         f"{how} frees {some} these poses "
         f"cannot identify ({', '.join(names)}): only combinations of them are determined, "
         "their values are arbitrary and have no standard error; use --free identifiable")


def check_parameter_tolerance(model: SerialModel, params: Array, std: Array,
                              names: Sequence[str],
                              confounded_with: dict[str, dict[str, float]] | None = None,
                              q: Array | None = None) -> None:
    """``parameter-tolerance``: identified values far beyond the model's tolerances.

    Checks the free, identifiable parameters except the base frame and the tool points
    (the measurement set-up, not the arm: where the instrument stands is arbitrary, and
    where its reflectors sit on the flange is rarely known to the tolerances of the arm;
    a URDF's tool point and markers named by a file start at the flange). A free
    parameter also takes up the errors of the parameters confounded with it (``d6`` of a
    tool point on the last axis moves ``a5`` by ``d6 * alpha6``): its allowance is its own
    tolerance plus ``sum |c| * tolerance`` over the confounded parameters (coefficients
    `confounded_with` of the identifiability report; unbounded when a held tool point or
    base parameter is among them). Warns on a change larger than `TOLERANCE_MULTIPLE`
    allowances plus three standard errors. `params` is the full vector, `std` that of the
    free `names` (``inf`` where not identifiable).

    A joint with joint-error terms is judged by its whole correction at the calibration
    readings `q` (its offset's change plus the terms, `_joint_corrections`), not by its
    offset and coefficients one by one: over a partial turn the terms are nearly collinear
    with each other and with the offset, and large coefficients cancel.
    """
    def tol_of(n: str) -> float:
        a = model.is_angle()[model.index([n])[0]]
        return float(model.tolerances["angle"] if a else model.tolerances["length"])

    def setup(n: str) -> bool:
        return n in BASE_NAMES or n.startswith("tool.")

    names = list(names)
    std = np.asarray(std, dtype=float)
    found: list[tuple[float, str]] = []
    if model.joint_errors is not None and q is not None:
        judged = _corrected_joints(model)
        found = _joint_corrections(model, np.asarray(params, dtype=float), q,
                                   dict(zip(names, std.tolist(), strict=True)))
        keep = [i for i, n in enumerate(names) if n not in judged]
        names, std = [names[i] for i in keep], std[keep]
    idx = model.index(names)
    delta = np.asarray(params)[idx] - model.nominal[idx]
    tol = np.array([tol_of(n) for n in names])
    allow = tol.copy()
    pos = {n: i for i, n in enumerate(names)}
    for other, combo in (confounded_with or {}).items():
        if other in pos:
            continue
        for n, c in combo.items():
            if n in pos:
                # a held set-up parameter (a marker's tool point the joint geometry stands
                # in for, e.g. a6 for tool.A.x) can be anywhere: so can its stand-in
                allow[pos[n]] += (np.inf if setup(other) and abs(c) > 1e-3
                                  else abs(c) * tol_of(other))
    base = np.array([setup(n) for n in names], dtype=bool)
    bad = (np.isfinite(std) & ~base
           & (np.abs(delta) > TOLERANCE_MULTIPLE * allow + 3.0 * std))
    k = np.flatnonzero(bad)
    worst = k[np.argsort(-np.abs(delta[k]) / allow[k])]
    items = [(float(np.abs(delta[i]) / tol[i]), _values(model, [names[i]], delta[i:i + 1]))
             for i in worst] + found
    if not items:
        return
    items.sort(key=lambda it: -it[0])
    shown = ", ".join(text for _, text in items[:4])
    warn("parameter-tolerance",
         f"{plural(len(items), 'identified parameter')} moved far beyond the model's "
         f"tolerances ({shown}; {items[0][0]:.0f} tolerances for the first): probably the "
         "wrong model, wrong units or frame, or outliers; check them (or widen the "
         "tolerances if the nominal values are only rough)")


def _corrected_joints(model: SerialModel) -> set[str]:
    """The parameters judged by their joints' whole corrections: the joint-error
    coefficients and the offsets of the joints that have terms."""
    terms = model._joint_terms
    n_geo = model._n_geometric
    offsets = {model.parameter_names[int(model._joint_columns[j])]
               for j in set(terms.joint_of.tolist())}
    return set(model.parameter_names[n_geo:]) | offsets


def _joint_corrections(model: SerialModel, params: Array, q: Array,
                       std: dict[str, float]) -> list[tuple[float, str]]:
    """``(tolerances, text)`` of the joints whose whole correction at readings `q` (the
    offset's change plus the joint-error terms, against the nominal model's) exceeds
    `TOLERANCE_MULTIPLE` tolerances plus three times a bound of its standard error (the
    free parameters' standard errors `std` by name, summed with the terms' weights: a
    correction the poses barely see, such as a last joint's with the tool point near its
    axis, is not judged by its value)."""
    terms = model._joint_terms
    n_geo = model._n_geometric
    q = np.asarray(q, dtype=float)
    W = terms.basis(q)
    dq = terms.dq(q, params[n_geo:]) - terms.dq(q, model.nominal[n_geo:])
    coef = np.array([std.get(n, 0.0) for n in terms.names])
    out = []
    for j in sorted(set(terms.joint_of.tolist())):
        k = int(model._joint_columns[j])
        total = dq[:, j] + (params[k] - model.nominal[k])
        sel = terms.joint_of == j
        with np.errstate(invalid="ignore"):  # 0 * inf: a free coefficient without a std
            bound = std.get(model.parameter_names[k], 0.0) + np.abs(W[:, sel]) @ coef[sel]
        bound = np.where(np.isfinite(bound), bound, np.inf)
        tol = float(model.tolerances["angle" if model.is_angle()[k] else "length"])
        excess = np.abs(total) - 3.0 * bound
        worst = float(np.abs(total).max(initial=0.0))
        if (excess > TOLERANCE_MULTIPLE * tol).any():
            i = int(np.argmax(np.abs(total)))
            value = _values(model, [model.parameter_names[k]], total[i:i + 1])
            out.append((worst / tol, f"joint {j + 1} offset and terms {value.split(' ', 1)[1]}"))
    return out


def check_residual_offset(problem, x: Array) -> None:
    """``residual-offset``: structure in the residual that a free base frame would take.

    The base-frame parameters that are not free (all six when the model has no base) are
    added to the linearised fit at the solution; when they lower the residual sum of
    squares significantly (extra-sum-of-squares F-test at level `ALPHA`) and by at least
    `PRACTICAL_RSS_DROP`, the measurement frame is probably not the model's base frame.
    """
    from kinecal.calibration.serial.problem import column_scale

    model = problem.model
    cand = [n for n in BASE_NAMES if n not in problem.free]
    if not cand or len(problem.data) < 3:
        return
    names = list(problem.free) + cand
    params = problem.full(x)
    G, P = problem.pose_rows.gram(params, model.index(names))
    scale = column_scale(model, problem.data, names, params, positions=P)
    t = FitTest(G, problem.n_free, problem.rows * len(problem.data), scale)
    if not t.significant or t.rss_full > (1.0 - PRACTICAL_RSS_DROP) * t.rss_free:
        return
    n = len(problem.data)
    before = np.sqrt(t.rss_free / n)
    after = np.sqrt(t.rss_full / n)
    shown = _values(model, cand, t.step)
    warn("residual-offset",
         f"the residual holds a systematic offset that a free base (measurement) frame would "
         f"take ({shown}): the RMS error per pose would fall from {before:.3g} to "
         f"{after:.3g} {model.length_unit}; if the instrument's frame is not the robot's "
         "base frame, add base: [0, 0, 0, 0, 0, 0] to the model (or free base.*)")


def pose_leverage(problem, x: Array, normal: Array | None = None) -> Array:
    """Mean leverage ``(N,)`` of each pose's position rows at the solution `x`.

    The diagonal of the hat matrix ``J (J^T J)^+ J^T`` averaged over a pose's three position
    rows: a least-squares fit pulls the residual of a high-leverage pose towards zero (its
    variance is ``sigma^2 (1 - h)``), which matters when there are few residual degrees of
    freedom per parameter. Two chunked passes over the poses, one when `normal` (the
    weighted ``J^T J`` at `x`, which Levenberg-Marquardt returns) is given.
    """
    rows = problem.pose_rows
    p = problem.full(x)
    A = rows.gram(p, problem.index)[0][:-1, :-1] if normal is None else normal
    Ainv = np.linalg.pinv(A)
    h = np.empty(len(problem.data))
    k = problem.n_free
    for sel in rows.chunks(k):
        _, Jt, _ = rows.evaluate(p, sel, problem.index)
        J = np.ascontiguousarray(Jt[:, :3, :]).reshape(k, -1)  # (k, 3 n): position rows
        # diag(J^T Ainv J) by one matrix product and a column-wise dot (a three-operand
        # einsum would loop over k^2 3 n terms without BLAS)
        d = np.einsum("kj,kj->j", J, Ainv @ J)
        h[sel] = d.reshape(3, -1).sum(axis=0) / 3.0
    return np.clip(h, 0.0, 1.0)


#: errors below this fraction of the machine's size are round-off, not measurements: a
#: noise-free fit's 1e-15 m "outlier" against a 4e-16 m median is no finding
ROUND_OFF = 1e-9


def check_outliers(distances: Array, unit: str, leverage: Array | None = None,
                   size: float | None = None, group: Array | None = None) -> list[int]:
    """``outliers``: poses whose distance error after a least-squares fit is an outlier
    (`chi3_outliers` on the errors studentized by the rows' `leverage`, when given);
    none when every error is below `ROUND_OFF` times the machine's `size`. `group`: the
    pose of each row (`kinecal.calibration.diagnostics.observations.pose_groups`; rows of
    one pose at several markers are tested, and named, as one pose). Returns the 0-based
    indices of the rows of the outlier poses."""
    d = np.asarray(distances, dtype=float)
    if size is not None and d.size and d.max() <= ROUND_OFF * size:
        return []
    if leverage is not None:
        d = d / np.sqrt(np.maximum(1.0 - np.asarray(leverage, dtype=float), 1e-3))
    out = pose_outliers(d, None if group is None else np.asarray(group))
    if out:
        d = np.asarray(distances, dtype=float)
        n, shown = describe_poses(out, None if group is None else np.asarray(group))
        verb = "has an error" if n == 1 else "have errors"
        warn("outliers",
             f"{plural(n, 'pose')} ({shown}; 0-based) {verb} of up to "
             f"{d[out].max():.3g} {unit} against a median of {np.median(d):.3g} {unit}: outliers "
             "pull a least-squares fit; check those measurements or calibrate with a "
             "robust loss (--loss soft_l1)")
    return out


def check_lack_of_fit(errors: Array, groups: Array, n_params: int, unit: str) -> None:
    """``lack-of-fit``: residual far above the repeatability of repeated poses.

    Rows with the same joint readings but different measurements are replicates: their
    scatter about their mean is pure measurement error. The classical lack-of-fit F-test
    compares the rest of the residual with it (level `ALPHA`).

    Parameters
    ----------
    errors : ndarray, shape (N, 3)
        Position residual vectors after the fit.
    groups : ndarray of int, shape (N,)
        Pose group of each row (`repeat_groups` of the joint readings).
    n_params : int
        Rank of the fit.
    unit : str
        Length unit for the message.
    """
    e = np.asarray(errors, dtype=float)
    groups = np.asarray(groups)
    n, k = e.shape[0], int(groups.max()) + 1 if groups.size else 0
    if k == n or k == 0:
        return
    counts = np.bincount(groups, minlength=k)
    means = np.zeros((k, 3))
    np.add.at(means, groups, e)
    means /= counts[:, None]
    ss_pe = float(((e - means[groups]) ** 2).sum())
    dof_pe = 3 * (n - k)
    dof_lof = 3 * k - n_params
    ss_lof = float((e**2).sum()) - ss_pe
    if ss_pe <= 0 or dof_lof <= 0 or dof_pe < 3:
        return
    f = (ss_lof / dof_lof) / (ss_pe / dof_pe)
    if f > float(fdtri(dof_lof, dof_pe, 1.0 - ALPHA)):
        rep = np.sqrt(ss_pe / (n - k))
        warn("lack-of-fit",
             f"the residual is {np.sqrt(f):.1f} times the repeatability seen on the "
             f"{n - k} repeated measurements ({rep:.3g} {unit}): the model misses a "
             "systematic error (base or tool frame, joint-dependent errors, wrong model)")


def check_serial_fit(problem, x: Array, std: Array, estimable: Array, *, free_choice: object,
                     least_squares: bool, robust: bool, groups: Array | None,
                     rank: int, confounded_with: dict | None = None,
                     normal: Array | None = None, residual: Array | None = None,
                     poses: Array | None = None) -> list[int]:
    """Every after-fit check of a serial calibration (the module docstring's codes).

    Parameters
    ----------
    problem : CalibrationProblem
        The fitted problem.
    x : ndarray, shape (k,)
        Solution (free parameters).
    std, estimable : ndarray, shape (k,)
        Standard errors and identifiability of the free parameters.
    free_choice : str or sequence
        What ``free`` the user asked for.
    least_squares : bool
        The solution minimises the sum of squares (lm, householder): the residual checks
        apply.
    robust : bool
        A robust loss was used (outliers are then down-weighted, not warned about).
    groups : ndarray of int, shape (N,) or None
        Pose groups of the rows (replicates), None when every pose is distinct.
    rank : int
        Rank of the fit.
    confounded_with : dict, optional
        The identifiability report's confounding coefficients of the held parameters.
    normal, residual : ndarray, optional
        The weighted ``J^T J`` ``(k, k)`` and the residual vector at `x` when the solver has
        them (each saves a pass over the poses).
    poses : ndarray of int, shape (N,), optional
        Pose of each row (rows of one pose at several markers: one observation of the
        outlier test); None: a pose per row.

    Returns
    -------
    list of int
        Rows of the outlier poses found after a least-squares fit.
    """
    model = problem.model
    names = list(problem.free)
    if free_choice != "identifiable":
        check_unidentifiable_free([n for n, e in zip(names, estimable, strict=True) if not e],
                                  free_choice)
    check_parameter_tolerance(model, problem.full(x), std, names, confounded_with,
                              q=problem.data.q)
    check_residual_offset(problem, x)
    if not least_squares or robust:
        return []
    e = problem.errors(x) if residual is None else problem.errors_from_residuals(residual)
    out = check_outliers(np.linalg.norm(e, axis=1), model.length_unit,
                         pose_leverage(problem, x, normal), serial_size(model), poses)
    if groups is not None:
        check_lack_of_fit(e, groups, rank, model.length_unit)
    return out
