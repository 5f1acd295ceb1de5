"""Validation data from another tracker set-up: re-register before judging
(``--validate-register all|N%``), and say so when nobody did (``validation-frame``).

A validation set measured after the tracker (or the tool) moved sits in another frame: its
errors at the calibrated model are the move, metres, not the model's accuracy ("3355 mm,
improvement 12 %" for the UR10 of ipa-robot-accuracy, series A -> C). With
``--validate-register`` the base frame and the tool (every ``tool.*`` parameter: a point,
a frame, the markers) are refitted on the validation rows with the
arm's geometry held, for the nominal model (before) and the calibrated one (after):

* ``all``: on every validation row, errors on the same rows (6 to 12 parameters fitted
  to them: slightly optimistic on a few rows, negligible on hundreds);
* ``N%``: on N % of the rows, drawn by a generator seeded with ``--seed`` (the same rows
  for the same seed), errors on the other rows only.

Each station of a validation set with a ``station`` column is registered on its own rows.
The refit starts from a rigid registration of the rows
(`kinecal.calibration.serial.registration`) and is a Levenberg-Marquardt fit of the
identifiable frame parameters.

Without the option a validation set whose errors are far beyond the calibration's and
mostly explained by one rigid motion warns ``validation-frame`` (`check_validation_frame`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.problem import CalibrationProblem, resolve_free
from kinecal.calibration.serial.registration import rigid_fit, rigid_fit_poses
from kinecal.data import Measurements
from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.frames import frame_pose, frame_transform, with_frame_transform
from kinecal.kinematics.serial.model import SerialModel
from kinecal.metrology.stats import axis_stats, error_stats
from kinecal.optimize.lsq import levenberg_marquardt
from kinecal.spatial import rotation_angle

__all__ = ["FRAME_RATIO", "RIGID_SHARE", "apply_validation_register", "check_validation_frame",
           "judge_validation", "parse_register", "register_frames", "registered_errors"]

Array = NDArray[np.float64]

#: `check_validation_frame`: the validation RMS error is more than this many times the
#: calibration's ...
FRAME_RATIO = 3.0
#: ... and one rigid motion leaves less than this share of it
RIGID_SHARE = 0.3


def parse_register(spec: str | float | None) -> float | None:
    """``all`` -> 1.0, ``N%`` (0 < N < 100) -> N / 100, None -> None."""
    if spec is None:
        return None
    text = str(spec).strip().lower()
    if text == "all":
        return 1.0
    try:
        value = float(text[:-1]) if text.endswith("%") else None
    except ValueError:
        value = None
    if value is None or not (0.0 < value < 100.0):
        raise InputError(f"{spec!r}: expected all or a share N% of the validation rows with "
                         "0 < N < 100 (e.g. 20%)", option="--validate-register")
    return value / 100.0


def _frame_names(model: SerialModel) -> list[str]:
    """The base and the tool parameters (the tool point, frame or markers; also where the
    model holds them by design: a remounted tool moves them all the same)."""
    return list(BASE_NAMES) + [n for n in model.parameter_names if n.startswith("tool.")]


def register_frames(model: SerialModel, params: Array, data: Measurements) -> Array:
    """`params` with the base frame and the tool refitted to `data`, the rest held.

    Starts from the rigid registration of the model's tool points (and orientations) on
    the measured ones; then Levenberg-Marquardt on the identifiable ones of the base and
    tool parameters.
    """
    p = np.asarray(params, dtype=float)
    T = model.fk(data.q, p, data.marker)
    X = rigid_fit_poses(T[:, :3, 3], data.xyz, T[:, :3, :3], data.rotations)
    p = with_frame_transform(model, p, X @ frame_transform(model, p, "base"))
    at = model.with_params(p)
    _, report = resolve_free(at, data, _frame_names(at), tol=1e-6)
    names = [n for n in _frame_names(at) if n in report.identifiable]
    if not names:
        return p
    problem = CalibrationProblem(at, dataclasses.replace(data, sigma=None), names)
    res = levenberg_marquardt.fit(problem.residuals, problem.jacobian, problem.x0)
    return problem.full(res.x)


def _split(n: int, fraction: float, seed: int | None) -> tuple[Array, Array]:
    """Rows to register on and rows to judge (`fraction` 1: all rows for both)."""
    if fraction >= 1.0:
        return np.arange(n), np.arange(n)
    k = math.ceil(fraction * n)
    if k < 3 or n - k < 1:
        raise InputError(f"{fraction:.0%} of {n} validation rows leaves {k} to register on and "
                         f"{n - k} to judge: expected at least 3 and 1",
                         option="--validate-register")
    order = np.random.default_rng(0 if seed is None else seed).permutation(n)
    return np.sort(order[:k]), np.sort(order[k:])


def _stations(data: Measurements) -> list[Measurements]:
    if data.station is None:
        return [data]
    return [data.subset(np.flatnonzero(np.asarray(data.station) == s))
            for s in range(len(data.station_names))]


def registered_errors(model: SerialModel, params: Array, data: Measurements,
                      fraction: float, seed: int | None) -> dict[str, Any]:
    """Validation errors after re-registration, nominal (before) and calibrated (after).

    Returns a dict: ``before`` / ``after`` position errors ``(M, 3)``, ``rotation_before``
    / ``rotation_after`` (deg, ``(M,)``, or None), the judged rows' ``q`` and ``marker``,
    ``fit_rows`` / ``judged_rows`` counts and each set-up's ``frames`` (base pose after
    registration, calibrated model).
    """
    out: dict[str, Any] = {k: [] for k in ("before", "after", "rotation_before",
                                           "rotation_after", "q", "marker")}
    out.update(fit_rows=0, judged_rows=0, frames=[])
    for d in _stations(data):
        fit, judge = _split(len(d), fraction, seed)
        d_fit, d_judge = d.subset(fit), d.subset(judge)
        for when, p in (("before", model.nominal), ("after", params)):
            p_reg = register_frames(model, p, d_fit)
            out[when].append(model.positions(d_judge.q, p_reg, d_judge.marker) - d_judge.xyz)
            if d.rotations is not None:
                R = model.fk(d_judge.q, p_reg, d_judge.marker)[:, :3, :3]
                out["rotation_" + when].append(np.degrees(rotation_angle(
                    R @ np.swapaxes(np.asarray(d_judge.rotations), 1, 2))))
            if when == "after":
                out["frames"].append(frame_pose(model, p_reg).tolist())
        out["q"].append(np.asarray(d_judge.q))
        out["marker"].append(None if d_judge.marker is None else np.asarray(d_judge.marker))
        out["fit_rows"] += len(fit)
        out["judged_rows"] += len(judge)
    for key in ("before", "after", "q"):
        out[key] = np.concatenate(out[key])
    for key in ("rotation_before", "rotation_after"):
        out[key] = np.concatenate(out[key]) if out[key] else None
    out["marker"] = (None if any(m is None for m in out["marker"])
                     else np.concatenate(out["marker"]))
    return out


def apply_validation_register(res, validate: Measurements | list, spec: str, fraction: float,
                              seed: int | None) -> None:
    """Replace `res`'s validation errors by those after re-registration (in place):
    ``val_before``, ``val_after``, the per-axis and orientation statistics, the validation
    poses, and ``extra["validation_register"]`` saying how."""
    sets = [validate] if isinstance(validate, Measurements) else [
        v for v in validate if isinstance(v, Measurements)]
    if not sets:
        raise InputError("applies to tracker validation sets (x, y, z rows)",
                         option="--validate-register")
    model, params = res.nominal_model, res.params
    parts = [registered_errors(model, params, v, fraction, seed) for v in sets]
    e0 = np.concatenate([p["before"] for p in parts])
    e1 = np.concatenate([p["after"] for p in parts])
    res.val_before, res.val_after = np.linalg.norm(e0, axis=1), np.linalg.norm(e1, axis=1)
    res.q_validation = np.concatenate([p["q"] for p in parts])
    markers = [p["marker"] for p in parts]
    res.marker_validation = None if any(m is None for m in markers) else np.concatenate(markers)
    res.extra.setdefault("axis_errors", {})["validation"] = {
        "before": axis_stats(e0), "after": axis_stats(e1)}
    rot = [(p["rotation_before"], p["rotation_after"]) for p in parts
           if p["rotation_before"] is not None]
    if rot:
        res.extra.setdefault("rotation_deg", {})["validation"] = {
            "before": error_stats(np.concatenate([a for a, _ in rot])),
            "after": error_stats(np.concatenate([b for _, b in rot]))}
    for entry in res.extra.get("validation_kinds", []):  # the stacked result's table
        for v, part in zip(sets, parts, strict=True):
            if entry.get("file") == v.source and entry.get("kind") == "tracker":
                entry["before"] = error_stats(np.linalg.norm(part["before"], axis=1))
                entry["after"] = error_stats(np.linalg.norm(part["after"], axis=1))
                entry["sigma_source"] = "re-registered"
    res.extra["validation_register"] = {
        "rows": spec, "seed": seed, "fit_rows": sum(p["fit_rows"] for p in parts),
        "judged_rows": sum(p["judged_rows"] for p in parts),
        "frames": [f for p in parts for f in p["frames"]],
        "refitted": _frame_names(model)}


def check_validation_frame(model: SerialModel, params: Array, validate: Measurements,
                           calibration_errors: Array) -> None:
    """``validation-frame`` when `validate` sits in another frame than the calibration.

    Its RMS distance error at the calibrated model is more than `FRAME_RATIO` times the
    calibration's (`calibration_errors`, distances after the fit) and the best rigid motion
    of the model's tool points onto the measured ones leaves less than `RIGID_SHARE` of it:
    a tracker (or a tool) moved between the sessions, not a model that fails there.
    """
    if len(validate) < 3:
        return
    P = model.positions(validate.q, params, validate.marker)
    M = np.asarray(validate.xyz, dtype=float)
    raw = float(np.sqrt(np.mean(np.sum((P - M) ** 2, axis=1))))
    cal = float(np.sqrt(np.mean(np.square(calibration_errors)))) if len(
        calibration_errors) else 0.0
    if not raw > FRAME_RATIO * cal:
        return
    try:
        X = rigid_fit(P, M)
    except InputError:
        return
    left = float(np.sqrt(np.mean(np.sum((P @ X[:3, :3].T + X[:3, 3] - M) ** 2, axis=1))))
    if left >= RIGID_SHARE * raw:
        return
    unit = model.length_unit
    angle = float(np.degrees(rotation_angle(X[:3, :3])))
    shift = float(np.linalg.norm(X[:3, 3] + X[:3, :3] @ P.mean(axis=0) - P.mean(axis=0)))
    warn("validation-frame",
         f"the validation data ({validate.source or 'validation set'}) sit in another frame "
         f"than the calibration's: {raw:.4g} {unit} RMS at the calibrated model "
         f"(calibration {cal:.4g} {unit}), {left:.4g} {unit} after one rigid motion "
         f"({shift:.4g} {unit} and {angle:.3g} deg at their centroid): a tracker or tool "
         "moved between the sessions; judge the model after re-registering the base and "
         "tool on them (--validate-register all, or N% to judge on the other rows)")


def judge_validation(res, validate, spec: str | None, rng) -> None:
    """After a calibration with validation data: re-register them (`spec` ``all`` or
    ``N%``: `apply_validation_register`) or check that they sit in the calibration's
    frame (`check_validation_frame`, each tracker set); the warnings join `res`'s."""
    from kinecal import diagnostics

    seed = int(rng) if isinstance(rng, int | np.integer) else None
    sets = [validate] if isinstance(validate, Measurements) else [
        v for v in validate if isinstance(v, Measurements)]
    with diagnostics.collect(python_warnings=True) as found:
        if spec is not None:
            apply_validation_register(res, validate, spec, parse_register(spec), seed)
        elif not res.extra.get("not_seen"):  # a mix blind to the base: no frame to leave
            for v in sets:
                if v.station is None:  # a set of stations is registered per station
                    check_validation_frame(res.nominal_model, res.params, v,
                                           np.asarray(res.errors_after))
    res.warnings = list(dict.fromkeys([*res.warnings, *found]))
