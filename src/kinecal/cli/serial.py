"""Serial-arm commands: ``models``, ``fk``."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.calibration.method_options import check_error_model_options, check_method_options
from kinecal.cli._app import app
from kinecal.cli._common import (
    MODEL_HELP,
    base_link_option,
    check_paths,
    echo_json,
    load_model_arg,
    quiet_option,
    resolve_data_path,
    seed_option,
    strict_option,
    tip_link_option,
    warnings_scope,
    with_warnings,
    write_json,
)
from kinecal.errors import InputError

#: peak memory of simulate / identifiability per random pose and per joint (+10): measured
#: 330 B (irb120, 6 joints) and 580 B with orientations, taken with a margin
_POSE_BYTES = 64


def result_markers(params: dict) -> list[str]:
    """Marker names of a result's ``tool.NAME.x`` parameters (several markers)."""
    return [n[5:-2] for n in params if n.startswith("tool.") and n.endswith(".x")
            and n.count(".") >= 2]


def model_for_result(model, path: Path):
    """`model`, given one tool point per marker when the result has several markers."""
    from kinecal._files import read_json
    from kinecal.kinematics.markers import model_for_markers

    data = read_json(path)
    params = data.get("parameters") if isinstance(data, dict) else None
    if not isinstance(params, dict):
        raise InputError("expected a calibration result with a 'parameters' mapping", file=path)
    model = _with_result_joint_errors(model, data, path)
    return model_for_markers(model, result_markers(params))


def parameters_from_result(model, path: Path) -> np.ndarray:
    """Full parameter vector from a calibration result JSON (``identified`` values).

    Refuses (`InputError`) a result without parameters, with a parameter the model does not
    have, a value that is not a finite number, other units, or nominal values that differ
    from the model's (a result of another model).
    """
    from kinecal._files import read_json

    data = read_json(path)
    params = data.get("parameters") if isinstance(data, dict) else None
    if not isinstance(params, dict) or not params:
        raise InputError("expected a calibration result with a non-empty 'parameters' mapping",
                         file=path)
    for key, mine in (("length_unit", model.length_unit), ("angle_unit", model.angle_unit)):
        theirs = data.get(key)
        if theirs is not None and theirs != mine:
            raise InputError(f"the result's {key} is {theirs!r}, model {model.name!r} uses "
                             f"{mine!r}: a result of another model", file=path)
    angle = model.is_angle()
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    p = model.nominal
    for name, entry in params.items():
        k = model.index([name])[0] if name in model.parameter_names else None
        if k is None:
            raise InputError(f"parameter {name!r} does not belong to model {model.name!r}",
                             file=path)
        conv = scale if angle[k] else 1.0
        try:
            raw = entry["identified"] if isinstance(entry, dict) else entry
            value = float(raw)
            nominal = float(entry["nominal"]) if isinstance(entry, dict) and entry.get(
                "nominal") is not None else None
        except (KeyError, TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'identified'",
                             file=path) from None
        if isinstance(raw, bool) or not np.isfinite(value) or (
                nominal is not None and not np.isfinite(nominal)):
            raise InputError(f"parameter {name!r}: expected a finite number, got {raw!r}",
                             file=path)
        mine = p[k] / conv
        if nominal is not None and abs(nominal - mine) > 1e-6 * max(1.0, abs(mine)):
            raise InputError(f"parameter {name!r} has nominal {nominal:.6g} in the result but "
                             f"{mine:.6g} in model {model.name!r}: a result of another model",
                             file=path)
        p[k] = value * conv
    return p


def _with_result_joint_errors(model, data: dict, path: Path):
    """`model` with the joint-error terms a calibration result JSON declares (``joint_errors.
    model``, written by ``--error-model``), so that its parameters fit; else `model`."""
    section = data.get("joint_errors")
    if not isinstance(section, dict) or "model" not in section:
        return model
    import dataclasses

    from kinecal.io.joint_errors_file import joint_errors_from_file

    plain = dataclasses.replace(model, joint_errors=None)
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    try:
        je = joint_errors_from_file(plain, section["model"], scale)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    return dataclasses.replace(plain, joint_errors=je)


@app.command()
def models(json_out: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List the bundled models, Stewart geometries and datasets."""
    from kinecal.datasets import DATASETS
    from kinecal.io.models import bundled_models, load_model

    arms = []
    for name in bundled_models():
        m = load_model(name)
        arms.append({"name": name, "convention": m.convention, "joints": m.n_joints,
                     "parameters": m.n_params, "calibratable": len(m.calibratable),
                     "length_unit": m.length_unit, "description": m.description})
    try:
        from kinecal.io.geometry import bundled_geometries
        geometries = bundled_geometries()
    except ImportError:
        geometries = []
    datasets = [{"name": n, "parts": [f"{n}:{p}" for p in d["parts"]], "license": d["license"],
                 "model": d["model"], "description": d["description"]}
                for n, d in DATASETS.items()]
    if json_out:
        echo_json({"models": arms, "geometries": geometries, "datasets": datasets})
        return
    from rich.console import Console
    from rich.table import Table

    console = Console()
    t = Table(title="Serial-arm models")
    for col in ("name", "convention", "joints", "parameters", "calibratable", "unit"):
        t.add_column(col)
    for a in arms:
        t.add_row(a["name"], a["convention"], str(a["joints"]), str(a["parameters"]),
                  str(a["calibratable"]), a["length_unit"])
    console.print(t)
    if geometries:
        console.print("Stewart geometries: " + ", ".join(
            g if isinstance(g, str) else g.get("name", "") for g in geometries))
    for d in datasets:
        console.print(f"dataset {d['name']} ({d['license']}): {', '.join(d['parts'])}")


@app.command()
def fk(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    joints: str = typer.Argument(..., help="CSV with q1..qn (model angle unit) or NAME:PART."),
    pose: bool = typer.Option(False, "--pose", help="Also print qw,qx,qy,qz of the tool frame."),
    params: Path | None = typer.Option(None, "--params", help="Calibration result JSON."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
) -> None:
    """Forward kinematics: tool-point positions (CSV on stdout)."""
    from kinecal.calibration.diagnostics.serial import check_joint_limits, check_joint_units
    from kinecal.io.measurements import read_joints, read_markers
    from kinecal.spatial import quaternion_from_matrix

    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        if params is not None:
            m = model_for_result(m, params)
        path = resolve_data_path(joints, "JOINTS")
        q = read_joints(path, m)
        marker = read_markers(path, m)[0] if m.marker_names else None
        check_joint_limits(m, q, "joint readings")
        check_joint_units(m, q, "joint readings")
        p = None if params is None else parameters_from_result(m, params)
    T = m.fk(q, p, marker)
    header = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if pose else [])
    out = T[:, :3, 3]
    if pose:
        out = np.column_stack([out, quaternion_from_matrix(T[:, :3, :3])])
    lines = [",".join(header)] + [",".join(f"{v:.10g}" for v in row) for row in out]
    sys.stdout.write("\n".join(lines) + "\n")


def _free_option(free: str) -> str | list[str]:
    if free in ("all", "identifiable"):
        return free
    names = [n.strip() for n in free.split(",") if n.strip()]
    if not names:
        raise InputError("expected all, identifiable or comma-separated parameter names",
                         option="--free")
    return names


@app.command()
def simulate(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    poses: int = typer.Option(..., "--poses", help="Number of random poses (a model with "
                              "markers measures every marker at each: poses x markers rows)."),
    noise: float = typer.Option(0.0, "--noise", help="Gaussian noise sigma per coordinate."),
    errors: str = typer.Option("random", "--errors", help="zero, random or TRUTH.json."),
    seed: int = seed_option(),
    out: Path = typer.Option(..., "--out", help="Measurement CSV to write."),
    truth_out: Path | None = typer.Option(None, "--truth-out", help="Truth JSON to write."),
    orientation: bool = typer.Option(False, "--orientation",
                                     help="Also measure the tool orientation (qw..qz columns)."),
    angle_noise: float = typer.Option(0.0, "--angle-noise",
                                      help="Orientation noise sigma (model angle unit)."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
) -> None:
    """Simulate measurements of a model with true errors and noise."""
    from kinecal.calibration.simulate import read_truth, write_truth
    from kinecal.calibration.simulate import simulate as run
    from kinecal.io.measurements import write_measurements

    check_paths({"MODEL": model, "--errors": None if errors in ("zero", "random") else errors},
                {"--out": out, "--truth-out": truth_out})
    check_finite(noise, "--noise")
    check_finite(angle_noise, "--angle-noise")
    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        check_count(poses, "--poses", bytes_per_item=_POSE_BYTES * (m.n_joints + 10))
        if errors in ("zero", "random"):
            err: object = errors
        else:
            err = read_truth(Path(errors), m) - m.nominal
        if angle_noise and not orientation:
            raise InputError("--angle-noise needs --orientation", option="--angle-noise")
        to_rad = np.pi / 180.0 if m.angle_unit == "deg" else 1.0
        sim = run(m, poses, errors=err, noise=noise, rng=seed, orientation=orientation,
                  angle_noise=angle_noise * to_rad)
        write_measurements(out, sim.data, m)
        if truth_out is not None:
            write_truth(truth_out, m, sim.true_params)
    if not quiet:
        typer.echo(f"wrote {poses} poses to {out}"
                   + (f", truth to {truth_out}" if truth_out else ""), err=True)


@app.command()
def identifiability(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    data: str | None = typer.Option(None, "--data", help="Measurement CSV (poses to analyse)."),
    poses: int | None = typer.Option(None, "--poses", help="Random poses when no --data is "
                                     "given (default 50)."),
    free: str = typer.Option("all", "--free", help="all, identifiable or comma-separated names."),
    seed: int | None = typer.Option(None, "--seed", min=0, help="Random seed for the poses "
                                    "(without --data; default 0)."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    error_model: str | None = typer.Option(
        None, "--error-model", help="Also analyse joint-error terms: compliance, harmonic, "
        "scale, full or families joined by '+' (default: the model file's joint_errors)."),
    harmonics: int | None = typer.Option(None, "--harmonics",
                                         help="Harmonic order (default 2)."),
) -> None:
    """Rank, identifiable and unidentifiable parameters, condition number, O1-O5."""
    from kinecal.calibration.diagnostics.serial import check_pose_set
    from kinecal.calibration.problem import resolve_free
    from kinecal.calibration.simulate import simulate as run
    from kinecal.io.measurements import read_measurements
    from kinecal.kinematics.markers import model_for_markers

    for option, value in (("--poses", poses), ("--seed", seed)):
        if data is not None and value is not None:
            raise InputError("applies to random poses only, not with --data", option=option)
    with warnings_scope(strict) as found:
        m = load_model_arg(model, base_link, tip_link)
        if data is not None:
            meas = read_measurements(resolve_data_path(data, "--data"), m)
        else:
            poses = check_count(50 if poses is None else poses, "--poses",
                                bytes_per_item=_POSE_BYTES * (m.n_joints + 10))
            meas = run(m, poses, errors="zero", rng=seed or 0).data
        m = model_for_markers(m, meas.marker_names)  # one tool point per marker measured
        if error_model is not None or harmonics is not None or m.joint_errors is not None:
            from kinecal.calibration.joint_identifiability import identifiability_with_terms

            # the geometry first, then the joint-error coefficients beyond it
            m, report = identifiability_with_terms(m, meas, _free_option(free), error_model,
                                                   harmonics)
        else:
            _, report = resolve_free(m, meas, _free_option(free))
        if data is not None:
            check_pose_set(m, meas, report)
    if json_out:
        echo_json(with_warnings(report.to_dict(), found))
        return
    if quiet:
        return
    typer.echo(report.explain())
    typer.echo("identifiable: " + ", ".join(report.identifiable))
    typer.echo("observability: " + ", ".join(f"{k}={v:.4g}"
                                             for k, v in report.observability.items()))


@app.command()
def calibrate(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    data: str = typer.Argument(..., help="Measurement CSV or NAME:PART."),
    method: str = typer.Option("lm", "--method", help="lm, householder, a metaheuristic "
                               "(ga, pso, afsa, sa-iafsa, gwo, igwo, dlh-gwo-de, de) or hybrid-*."),
    validate: str | None = typer.Option(None, "--validate", help="Validation CSV or NAME:PART."),
    free: str = typer.Option("identifiable", "--free",
                             help="identifiable, all or comma-separated names."),
    seed: int = seed_option("Random seed (metaheuristics; an integer >= 0)."),
    loss: str = typer.Option("linear", "--loss", help="linear, huber, soft_l1, cauchy, arctan."),
    maxiter: int | None = typer.Option(None, "--maxiter", help="Iteration budget."),
    target: float | None = typer.Option(None, "--target", help="Stop at this mean error."),
    out: Path | None = typer.Option(None, "--out", help="Result JSON to write."),
    model_out: Path | None = typer.Option(None, "--model-out", help="Calibrated model YAML."),
    report: Path | None = typer.Option(None, "--report", help="HTML report to write."),
    json_out: bool = typer.Option(False, "--json", help="Print the result JSON."),
    quiet: bool = quiet_option(),
    strict: bool = strict_option(),
    rotation_weight: float | None = typer.Option(
        None, "--rotation-weight", help="With measured orientations: length units per rad of "
        "rotation error (default: the workspace's characteristic length)."),
    error_model: str | None = typer.Option(
        None, "--error-model", help="geometric, compliance, harmonic, scale, full, auto "
        "(chosen by cross-validation on the calibration poses) or families joined by '+' "
        "(default: the model file's joint_errors, else geometric). See docs/error-models.md."),
    harmonics: int | None = typer.Option(
        None, "--harmonics", help="Harmonic order (default 2; auto tries 1..3)."),
    folds: int | None = typer.Option(None, "--folds", help="Cross-validation folds "
                                     "(--error-model auto; default 10)."),
) -> None:
    """Calibrate a serial arm from measured tool positions (and orientations if given)."""
    from kinecal.calibration.serial import CALIBRATION_METHODS
    from kinecal.calibration.serial import calibrate as run
    from kinecal.cli._common import progress
    from kinecal.io.measurements import read_measurements

    if method not in CALIBRATION_METHODS:
        raise InputError(f"unknown method {method!r}; expected one of "
                         f"{', '.join(CALIBRATION_METHODS)}", option="--method")
    check_paths({"MODEL": model, "DATA": data, "--validate": validate},
                {"--out": out, "--model-out": model_out, "--report": report})
    if maxiter is not None and maxiter < 1:
        raise InputError(f"expected a positive iteration budget, got {maxiter}",
                         option="--maxiter")
    check_finite(target, "--target")
    check_finite(rotation_weight, "--rotation-weight", positive=True)
    check_method_options(method, loss=loss, maxiter=maxiter, target=target)
    check_error_model_options(error_model, harmonics=harmonics, folds=folds)
    with warnings_scope(strict) as found:
        m = load_model_arg(model, base_link, tip_link)
        meas = read_measurements(resolve_data_path(data, "DATA"), m)
        if rotation_weight is not None and meas.rotations is None:
            raise InputError("applies to measured orientations (qw..qz columns) only",
                             option="--rotation-weight")
        val = None
        if validate is not None:
            val = read_measurements(resolve_data_path(validate, "--validate"), m)
        iterative = method not in ("lm",)
        with progress(f"calibrate {m.name} ({method})", maxiter if iterative else None,
                      quiet or json_out) as update:
            kw = dict(free=_free_option(free), validate=val, rng=seed, loss=loss,
                      maxiter=maxiter, target=target, rotation_weight=rotation_weight,
                      progress=(lambda it, best: update(1, best)) if iterative else None)
            if error_model is None and m.joint_errors is None and harmonics is None:
                res = run(m, meas, method, **kw)
            else:
                from kinecal.calibration.error_model import calibrate_error_model

                res = calibrate_error_model(m, meas, error_model or "model", method=method,
                                            harmonics=harmonics, **kw,
                                            **({} if folds is None else {"folds": folds}))
        res.warnings = list(found)  # the readers' warnings as well as the calibration's
        result = with_warnings(res.to_dict(), found)
        if out is not None:
            write_json(out, result)
        if model_out is not None:
            res.save_model(model_out)
        if report is not None:
            res.report(report)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(res.summary())


@app.command("select-poses")
def select_poses_cmd(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    count: int = typer.Option(..., "--count", help="Number of poses to select."),
    candidates: int = typer.Option(2000, "--candidates", help="Random candidate poses."),
    seed: int = seed_option("Random seed for the candidates (an integer >= 0)."),
    out: Path = typer.Option(..., "--out", help="CSV of the selected q1..qn."),
) -> None:
    """Choose calibration poses maximising observability (O1, D-optimal)."""
    from kinecal.calibration.pose_selection import candidate_measurements, select_poses
    from kinecal.calibration.problem import resolve_free
    from kinecal.calibration.simulate import random_configurations
    from kinecal.io.csvtable import write_table

    check_paths({"MODEL": model}, {"--out": out})
    m = load_model_arg(model, base_link, tip_link)
    check_count(candidates, "--candidates", bytes_per_item=128 * m.n_params, what="candidates")
    q = random_configurations(m, candidates, np.random.default_rng(seed))
    ident, _ = resolve_free(m, candidate_measurements(m, q), "identifiable", tol=1e-4)
    idx, obs = select_poses(m, q, count, free=ident)
    scale = 1.0 / m.joint_scale()  # to the file's units per joint column
    write_table(out, {f"q{i + 1}": q[idx, i] * scale[i] for i in range(m.n_joints)})
    typer.echo(f"wrote {count} poses to {out}; O1 = {obs['O1']:.4g}, O2 = {obs['O2']:.4g} "
               f"({len(ident)} identifiable parameters)", err=True)
