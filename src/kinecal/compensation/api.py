"""Compensation: put a calibrated model to work on a robot program.

A controller runs its *nominal* model; the arm moves like the *calibrated* one. Two kinds
of program are compensated (the job of RoboDK's "filter program" / "filter targets"):

* a **joint program** ``q_prog`` (what the controller was told): the intent is the nominal
  model's tool pose at those joints; the compensated joints make the calibrated model reach
  that pose (`solve_ik` seeded with the program's own joints, so the arm stays on its
  branch);
* **Cartesian targets** (positions, or poses): the joints an uncompensated controller would
  command are the nominal inverse kinematics of the targets (seeded with the program's seed
  joints when given); the compensated joints make the calibrated model reach the targets,
  and the **filtered targets** are the nominal model's poses at the compensated joints:
  what to send to a controller that still runs its nominal model.

Every result carries, per row, the joint correction, the Cartesian size of the correction
(how far the commanded pose moves; to first order the error the uncompensated program
would have on the real arm), whether the calibrated model reaches the intent within the IK
tolerances, and the remaining residual.

The calibrated and the nominal model must describe the same arm: the same joints, and
tool poses within a few percent of the arm's size over the workspace once registered onto
each other (`kinecal.compensation.same_arm`; any conventions, e.g. a D-H nominal model and
its calibrated URDF). The base frame is the calibrated one unless ``base="nominal"``,
which moves it by that best registration: a base far from nominal usually means the
measurements were taken in an instrument's frame (a warning says so), where the program's
poses do not live.
"""


from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal import diagnostics
from kinecal.calibration.diagnostics.envelope import (
    beyond_calibrated_range,
    check_calibrated_range,
)
from kinecal.calibration.diagnostics.program import check_target_units
from kinecal.compensation.findings import RowFindings
from kinecal.compensation.inputs import (
    check_base,
    check_tool,
    program_joints,
    program_models,
    program_targets,
    with_nominal_tool,
)
from kinecal.compensation.moves import mark_large_moves
from kinecal.compensation.result import CompensationResult
from kinecal.compensation.same_arm import check_same_arm, with_registered_base
from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import IKResult, pose_error, solve_ik
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["Arms", "CompensationResult", "RowFindings", "compensate", "prepare_arms"]

Array = NDArray[np.float64]

#: rows solved together (bounds the memory of very long programs)
BLOCK = 20_000


def _errors(intended: Array, T: Array) -> tuple[Array, Array]:
    dp, dr = pose_error(intended, T)
    pos = np.linalg.norm(dp, axis=1)
    rot = np.full(pos.shape, np.nan) if dr is None else np.linalg.norm(dr, axis=1)
    return pos, rot


def compensate(
    calibrated: Any,
    nominal: SerialModel | None = None,
    *,
    joints: ArrayLike | None = None,
    targets: ArrayLike | None = None,
    seeds: ArrayLike | None = None,
    outputs: str | None = None,
    base: str = "calibrated",
    tool: str = "calibrated",
    restarts: int = 10,
    rng: int | np.random.Generator | None = 0,
    diagnose: bool = True,
    progress: Any = None,
    findings: RowFindings | None = None,
    **ik_options: Any,
) -> CompensationResult:
    """Compensate a joint program or Cartesian targets with a calibrated model.

    Parameters
    ----------
    calibrated : SerialModel, CalibrationResult, str, Path, Arms or array_like (n_params,)
        The calibrated arm: a model (e.g. ``load_model("calibrated.yaml")``), a calibration
        result (its nominal model is used when `nominal` is None; also one read by
        `kinecal.load_result`), a path of either (a model file, or a result JSON), the
        calibrated parameter vector of `nominal`, or both models already checked
        (`prepare_arms`; `nominal`, `base` and `tool` are then ignored).
    nominal : SerialModel, str or Path, optional
        The model the controller runs (required unless `calibrated` is a result); a bundled
        name or a model file path is loaded.
    joints : array_like, shape (N, n_joints), optional
        A joint program (rad; prismatic joints in the length unit).
    targets : array_like, shape (N, 3), (N, 7) or (N, 4, 4), optional
        Cartesian targets: tool points, ``x, y, z, qw, qx, qy, qz`` poses, or tool frames, in
        the program's frame (length unit).
    seeds : array_like, shape (N, n_joints), optional
        Targets only: joints near the wanted configuration (the nearest branch is kept).
        Without seeds the nominal inverse kinematics starts from the middle of the joint
        limits with `restarts` random restarts (the branch is the solver's choice; a
        warning says so).
    outputs : {"pose", "position"}, optional
        Compensate the full tool pose or the tool point only. Default: pose for joint
        programs of arms with at least 6 joints and for targets with orientations,
        position otherwise.
    base : {"calibrated", "nominal"}
        Base frame of the calibrated model used: its own (the program lives in the frame
        the calibration measured in), or the one that registers the calibrated arm best
        onto the nominal arm over the workspace (measurements taken in an instrument's
        frame: base-frame errors are left to the user frame).
    tool : {"calibrated", "nominal"}
        Tool of the calibrated model used: its own (the calibration measured the program's
        tool), or the nominal model's (the calibration measured a target such as a tracker
        reflector: the program's tool, as the controller knows it, on the calibrated arm;
        needs a calibrated model with the nominal model's parameters).
    restarts, rng : int
        Random restarts of the nominal IK of unseeded targets (same rng, same result).
    diagnose : bool
        Report rows that did not converge, near-singular rows and the other findings
        through `kinecal.diagnostics.warn` (False: only in the result, e.g. for a report
        section that shows the counts itself).
    progress : callable, optional
        ``progress(rows_done, rows_total)`` after every block of `BLOCK` rows (long
        programs are solved block by block; every row's answer is the same as in one
        batch).
    findings : RowFindings, optional
        Gathers the per-row warnings (rows outside the limits, not converged, near a
        singularity) instead of issuing them, for a program compensated block by block
        (its ``offset`` numbers the block's rows; `RowFindings.warn` at the end).
    **ik_options
        Passed to `kinecal.kinematics.serial.ik.solve_ik` (``tol_position``, ``tol_rotation``,
        ``max_iterations``, ``singular_threshold``, ``rotation_weight``).

    Returns
    -------
    CompensationResult

    Raises
    ------
    InputError
        Neither or both of `joints` and `targets`, bad shapes or values, a calibrated
        model of another arm.
    """
    warn = diagnostics.warn if diagnose else _silent
    arms = calibrated if isinstance(calibrated, Arms) else \
        prepare_arms(calibrated, nominal, base=base, tool=tool, diagnose=diagnose)
    nom, cal = arms.nominal, arms.calibrated
    # row findings: issued below, or gathered over the blocks of a program by `findings`
    row_warn = _silent if findings is not None else warn
    if (joints is None) == (targets is None):
        raise InputError("give either a joint program (joints=) or Cartesian targets "
                         "(targets=)")
    if outputs not in (None, "pose", "position"):
        raise InputError(f"outputs: expected 'pose' or 'position', got {outputs!r}")
    if joints is not None:
        if seeds is not None:
            raise InputError("seeds apply to Cartesian targets; a joint program seeds itself")
        kind = "joints"
        q_nom = program_joints(nom, joints, "program joints", row_warn)
        _outside(findings, nom, q_nom, "program joints")
        outputs = outputs or ("pose" if nom.n_joints >= 6 else "position")
        T = nom.fk(q_nom)
        intended = T if outputs == "pose" else T[:, :3, 3]
        nominal_ok = np.ones(q_nom.shape[0], dtype=bool)
    else:
        kind = "targets"
        t = program_targets(targets)
        outputs = outputs or ("pose" if t.ndim == 3 else "position")
        if outputs == "pose" and t.ndim == 2:
            raise InputError("pose compensation needs target orientations (qw, qx, qy, qz)")
        intended = t if outputs == "pose" or t.ndim == 2 else t[:, :3, 3]
        if diagnose:  # metres given to a millimetre arm fold it onto its base
            check_target_units(cal, t if t.ndim == 2 else t[:, :3, 3])
        if seeds is None:
            warn(
                "no-seed-joints",
                "targets without seed joints: the solver chose each target's configuration "
                "(elbow, wrist); give seed joints (q1..qn columns) to keep the robot's own")
            first = _blocks(nom, intended, None, None, dict(ik_options, restarts=restarts,
                                                            rng=rng))
        else:
            q0 = program_joints(nom, seeds, "seed joints", row_warn)
            _outside(findings, nom, q0, "seed joints")
            if q0.shape[0] != intended.shape[0]:
                raise InputError(f"{q0.shape[0]} seed rows for {intended.shape[0]} targets")
            first = _blocks(nom, intended, q0, None, ik_options)
        q_nom, nominal_ok = first.q, first.converged
    res = _blocks(cal, intended, q_nom, progress, ik_options)
    filtered_T = nom.fk(res.q)
    filtered = filtered_T if outputs == "pose" else filtered_T[:, :3, 3]
    corr, corr_rot = _errors(intended, filtered_T)
    before, before_rot = _errors(intended, cal.fk(q_nom))
    out = CompensationResult(
        kind=kind, outputs=outputs, q=res.q, q_nominal=q_nom, dq=res.q - q_nom,
        intended=intended, filtered=filtered, correction=corr, correction_rotation=corr_rot,
        error_before=before, error_before_rotation=before_rot, residual=res.position_error,
        residual_rotation=res.rotation_error, converged=res.converged,
        status=mark_large_moves(nom, res.status, res.q - q_nom, corr, corr_rot),
        nominal_converged=nominal_ok, ik=res, length_unit=nom.length_unit,
        prismatic=nom.is_prismatic())
    if findings is not None:
        if arms.envelope is not None:  # rows beyond the calibrated joint range
            findings.add_beyond(beyond_calibrated_range(res.q, arms.envelope, cal),
                                arms.envelope, cal)
        findings.add("compensation-not-converged", ~out.converged, first_status=out.status)
        findings.add("nominal-ik-not-converged", ~out.nominal_converged)
        findings.add("near-singular", out.status == "near-singular")
        findings.rows += len(out)
    elif diagnose:
        _warn_rows(out)
        check_calibrated_range(res.q, arms.envelope, cal, "compensated joints")
    return out


@dataclass(frozen=True)
class Arms:
    """The nominal model and the calibrated one a program is compensated with, checked
    (`prepare_arms`): pass it to `compensate` as `calibrated` to compensate a program block
    by block without checking the models again."""

    nominal: SerialModel
    calibrated: SerialModel
    envelope: JointEnvelope | None = None


def prepare_arms(calibrated: Any, nominal: SerialModel | None = None, *,
                 base: str = "calibrated", tool: str = "calibrated",
                 diagnose: bool = True, envelope: JointEnvelope | None = None) -> Arms:
    """The models of `compensate` (its `calibrated`, `nominal`, `base` and `tool`), checked
    once: the same arm, the tool point and the base frame (warnings unless `diagnose` is
    False). `envelope`: the joint readings the calibration saw (default: a result's
    stored envelope, or that of a calibrated model's joint-error terms)."""
    warn = diagnostics.warn if diagnose else _silent
    if base not in ("calibrated", "nominal"):
        raise InputError(f"base: expected 'calibrated' or 'nominal', got {base!r}",
                         option="--base")
    if tool not in ("calibrated", "nominal"):
        raise InputError(f"tool: expected 'calibrated' or 'nominal', got {tool!r}",
                         option="--tool")
    nom, cal = program_models(calibrated, nominal)
    if tool == "nominal":
        cal = with_nominal_tool(cal, nom)
    else:
        check_tool(nom, cal, warn)
    reg = check_same_arm(nom, cal)
    if base == "calibrated":
        check_base(nom, reg, warn)
    else:
        cal = with_registered_base(cal, reg)
    if envelope is None:
        envelope = getattr(calibrated, "envelope", None)
    if envelope is None and cal.joint_errors is not None:
        envelope = cal.joint_errors.envelope
    return Arms(nom, cal, envelope)


def _outside(findings: RowFindings | None, model: SerialModel, q: Array, what: str) -> None:
    """Rows of `q` outside the joint limits into `findings` (`program_joints` warns
    itself when there are none)."""
    if findings is not None:
        lim = model.joint_limits
        findings.add("joints-outside-limits", ((q < lim[:, 0]) | (q > lim[:, 1])).any(axis=1),
                     what)


def _blocks(model: SerialModel, targets: Array, q0: Array | None, progress: Any,
            options: dict) -> IKResult:
    """`solve_ik` over blocks of `BLOCK` rows (bounded memory, progress), concatenated."""
    n = targets.shape[0]
    if n <= BLOCK:
        out = solve_ik(model, targets, q0, **options)
        if progress is not None:
            progress(n, n)
        return out
    parts = []
    for start in range(0, n, BLOCK):
        sl = slice(start, min(start + BLOCK, n))
        parts.append(solve_ik(model, targets[sl], None if q0 is None else q0[sl], **options))
        if progress is not None:
            progress(sl.stop, n)
    first = parts[0]
    arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in (
        "q", "converged", "status", "position_error", "rotation_error", "iterations",
        "condition", "restarts")}
    return replace(first, **arrays)


def _silent(code: str, message: str) -> None:
    """`diagnostics.warn` replacement that drops the finding (``diagnose=False``)."""


def _warn_rows(res: CompensationResult) -> None:
    """The per-row warnings of one compensated program (`RowFindings` over one block)."""
    found = RowFindings()
    found.add("compensation-not-converged", ~res.converged, first_status=res.status)
    found.add("nominal-ik-not-converged", ~res.nominal_converged)
    found.add("near-singular", res.status == "near-singular")
    found.rows = len(res)
    found.warn()
