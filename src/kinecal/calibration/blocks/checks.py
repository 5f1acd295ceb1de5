"""The plausibility checks of a stacked calibration: before the fit (joint readings, units,
each file against the nominal model, the count of equations) and after it (each block's
own check, the stated noise against the residual, outliers)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinecal.calibration.blocks.analysis import StackAnalysis
from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.tracker import TrackerBlock
from kinecal.calibration.diagnostics._common import plural, repeat_groups
from kinecal.calibration.diagnostics.kinds import check_block_noise, check_initial_error
from kinecal.calibration.diagnostics.serial import MIN_EQUATION_RATIO, reference
from kinecal.calibration.diagnostics.units import (
    check_frame_and_units,
    check_joint_limits,
    check_joint_units,
)
from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["MAX_STACK_ROWS", "MAX_STACK_UNKNOWNS", "check_block_data", "check_blocks",
           "check_fits", "check_stack_rows", "check_stack_unknowns",
           "check_validation_overlap"]

#: most file rows of one stacked calibration: every iteration evaluates every row (1e5
#: pair rows: 4 s of CPU on consistent data; a ballbar test has tens to thousands)
MAX_STACK_ROWS = 200_000
#: most unknowns (arm and the gauges' own) of one stacked calibration: its normal
#: equations are dense, each iteration solves them (2 430 unknowns, a ballbar and 200 files
#: of 4 fixed points: 25 s of CPU)
MAX_STACK_UNKNOWNS = 2_500


def check_stack_rows(data: Sequence, what: str = "") -> None:
    """Refuse, before any block is made, measurement sets of more than `MAX_STACK_ROWS`
    file rows in all: every iteration of the fit evaluates every row. Blocks made by the
    caller (a camera's) are bounded by their makers and not counted."""
    data = [d for d in data if not isinstance(d, ResidualBlock)]
    rows = [len(d) for d in data]
    if sum(rows) > MAX_STACK_ROWS:
        big = data[int(np.argmax(rows))]
        name = getattr(big, "source", None) or getattr(big, "name", "a set")
        raise InputError(f"{sum(rows):,} {what}rows in {plural(len(rows), 'set')} ({name}: "
                         f"{max(rows):,}): more than the {MAX_STACK_ROWS:,} one calibration "
                         "of several kinds takes (every iteration evaluates every row); keep "
                         "the rows that identify the most (kinecal select-poses --kind KIND) "
                         "or thin the files")


def check_stack_unknowns(blocks: Sequence[ResidualBlock], n_arm: int) -> None:
    """Refuse, before any fit, more than `MAX_STACK_UNKNOWNS` unknowns (`n_arm` of the arm
    and the blocks' own): the normal equations are dense, their cost the cube of it."""
    own = sum(b.n_nuisance for b in blocks)
    if n_arm + own > MAX_STACK_UNKNOWNS:
        raise InputError(f"{n_arm + own:,} unknowns ({n_arm} of the arm, {own:,} of the "
                         f"gauges' own in {plural(len(blocks), 'set')}): more than the "
                         f"{MAX_STACK_UNKNOWNS:,} one calibration of several kinds takes (its "
                         "normal equations are dense); measure fewer pivots, points or planes "
                         "per calibration, or merge the files of one gauge")


def check_blocks(model: SerialModel, blocks: Sequence[ResidualBlock], nuisance, before,
                 analysis: StackAnalysis, names: Sequence[str]) -> None:
    """Checks before the fit; raises ``too-few-poses`` when the rows cannot determine the
    unknowns."""
    from kinecal.calibration.diagnostics.sizes import check_tolerances

    check_tolerances(model)
    check_block_data(model, blocks, nuisance, before, analysis.report.names)
    m = sum(b.n_rows for b in blocks)
    n = len(names) + sum(b.n_nuisance for b in blocks)
    if m <= n:
        raise InputError(f"{m} equations for {n} unknowns ({len(names)} arm parameters and "
                         f"{n - len(names)} of the gauges' own): expected more than {n}; "
                         "measure more rows [too-few-poses]")
    if m < MIN_EQUATION_RATIO * n:
        warn("few-poses", f"{m} equations for {n} unknowns (fewer than {MIN_EQUATION_RATIO} "
             "per unknown): the fit can absorb noise and its uncertainty is unreliable; "
             "measure more rows")


def check_block_data(model: SerialModel, blocks: Sequence[ResidualBlock], nuisance, before,
                     names: Sequence[str], what: str = "") -> None:
    """Each set's own checks at the nominal geometry (joints, units, repeats, its gauges,
    its distance from the nominal model): of the calibration sets, and of the validation
    sets (`what` = ``"validation "``) of any kind."""
    ref = reference(model, names)
    base_free = set(BASE_NAMES) <= set(model.calibratable)
    p0 = model.nominal
    _check_same_sets(blocks, what)
    for b, v, e in zip(blocks, nuisance, before, strict=True):
        name = what + b.name
        check_joint_limits(model, b.q, name)
        warned = check_joint_units(model, b.q, name)
        if isinstance(b, TrackerBlock):
            _check_repeats(b)
            check_frame_and_units(model, b.data, ref, base_free, name, warned)
            continue
        b.check_data(model, p0, v)
        if b.unit == "length" and e.size and not warned:
            check_initial_error(name, float(np.sqrt(np.mean(e**2))), ref.reach,
                                ref.tolerance_error, model.length_unit)


def check_validation_overlap(blocks: Sequence[ResidualBlock],
                             validation: Sequence[ResidualBlock]) -> None:
    """``validation-overlap``: rows of a validation set whose joint readings (and marker)
    repeat rows of a calibration set of the same kind (one file given as both, or poses
    measured for both): its statistics are then not independent of the fit. Another kind
    at the same pose (a ballbar row where the tracker measured) is another measurement."""
    for v in validation:
        same = [b for b in blocks if b.kind == v.kind and np.shape(b.q)[1:] == np.shape(v.q)[1:]]
        if not same or not len(v.q):
            continue
        q = np.concatenate([b.q for b in same] + [v.q])
        marks = [np.zeros(len(b.q)) if b.marker is None else b.marker for b in [*same, v]]
        groups, _ = repeat_groups(q, np.concatenate(marks)[:, None])
        n_cal = len(q) - len(v.q)
        n = int(np.isin(groups[n_cal:], groups[:n_cal]).sum())
        if n:
            names = ", ".join(b.name for b in same)
            warn("validation-overlap",
                 f"validation {v.name}: {n} of {plural(len(v.q), 'row')} repeat the joint "
                 f"readings of {names}"
                 + (" (the validation set is a calibration set)" if n == len(v.q) else "")
                 + ": validation statistics are then not independent of the fit; validate "
                 "on poses not used for calibration")


def _check_same_sets(blocks: Sequence[ResidualBlock], what: str) -> None:
    """``duplicate-poses`` for two sets of one kind with the same joint readings (one file
    given twice, or a copy of it): its rows would count twice."""
    for i, a in enumerate(blocks):
        twin = next((b for b in blocks[:i] if b.kind == a.kind
                     and np.shape(b.q) == np.shape(a.q) and np.array_equal(b.q, a.q)), None)
        if twin is not None:
            warn("duplicate-poses",
                 f"{what}{a.name} repeats the joint readings of {twin.name} row for row: "
                 "one measurement given twice counts twice (its noise and standard errors "
                 "shrink by sqrt(2)); give each file once")


def _check_repeats(block: TrackerBlock) -> None:
    """``duplicate-poses`` for a tracker file in a mix (alone, the tracker path's own check
    warns or refuses)."""
    n = len(block.q)
    marker = np.zeros((n, 1)) if block.marker is None else np.asarray(block.marker)[:, None]
    _, distinct = repeat_groups(np.asarray(block.q, dtype=float), marker)
    if distinct < n:
        warn("duplicate-poses",
             f"{block.name}: {n - distinct} of {n} rows repeat the joint readings of another "
             f"row ({distinct} distinct): repeated rows add no geometry, and the noise and "
             "standard errors assume independent readings; measure distinct poses")


def check_fits(model: SerialModel, problem: StackedProblem, x: np.ndarray, residuals,
               fit, loss: str) -> list[tuple[int, int]]:
    """Checks after the fit: each block's hook, stated noise, outliers. Returns the
    outliers flagged (a plain fit reports them; a robust one has them in `fit`)."""
    params, nuis = problem.params(x), problem.nuisance(x)
    for i, (b, v, r, s) in enumerate(zip(problem.blocks, nuis, residuals, problem.sigma,
                                         strict=True)):
        b.check_fit(model, params, v, r, s)
        if fit.known[i]:
            rss = float(np.sum((r * problem.row_weight[i]) ** 2))
            check_block_noise(b.name, rss, float(fit.redundancy[i]), b.noise_of)
    if not fit.outliers:
        return []
    labels = pose_labels(problem.blocks, fit.outliers)
    shown = ", ".join(labels[:8]) + (", ..." if len(labels) > 8 else "")
    if loss == "linear":
        what = ("observation" if len(labels) == len(fit.outliers) else "pose")
        warn("outliers", f"{plural(len(labels), what)} ({shown}) far outside the "
             "spread of their measurement set: outliers pull a least-squares fit; check "
             "those rows or calibrate with a robust loss (--loss soft_l1)")
        return list(fit.outliers)
    return []


def pose_labels(blocks: Sequence[ResidualBlock], observations: Sequence[tuple[int, int]]
                ) -> list[str]:
    """One label per pose of the ``(block, observation)`` pairs: ``file:row`` for a pose of
    one observation, ``file:82-84`` for one measured at three markers (rows 82-84)."""
    out, seen = [], set()
    for i, j in observations:
        group, _ = blocks[i].observation_poses()
        if (i, int(group[j])) in seen:
            continue
        seen.add((i, int(group[j])))
        mine = [int(k) for k in np.flatnonzero(group == group[j])]
        labels = blocks[i].observation_labels()
        if len(mine) == 1:
            out.append(labels[j])
            continue
        stem = labels[mine[0]].rpartition(":")[0]
        rows = [labels[k].rpartition(":")[2] for k in mine]
        consecutive = mine[-1] - mine[0] == len(mine) - 1
        out.append(f"{stem}:{rows[0]}-{rows[-1]}" if consecutive else
                   f"{stem}:{'+'.join(rows)}")
    return out
