"""Command plumbing for robot systems (docs/systems.md): ``calibrate``, ``identifiability``,
``fk``, ``simulate``, ``compensate`` and ``export`` when MODEL is a system (a URDF with
several ``--tip-link``, or a ``kind: system`` file). No command is registered here: the
commands' own modules call these functions when `is_system_arg` says MODEL is one.

Rows of a system's files name their chain in a ``tip`` column, or ``--tip`` gives it for
a whole file; joint columns carry the system's joint names (blank off a row's chain).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    resolve_data_path,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["is_system_arg", "load_system_arg", "system_arms", "system_calibrate",
           "system_export", "system_fk", "system_identifiability", "system_select",
           "system_simulate"]


def is_system_arg(model: str, base_link: str | None, tips: list[str] | None) -> bool:
    """Whether MODEL with these ``--tip-link`` values is a robot system."""
    from kinecal.io.systems import is_system_spec

    return is_system_spec(model, base_link, tips or ())


def load_system_arg(model: str, base_link: str | None, tips: list[str] | None):
    """The `SystemModel` of MODEL and its ``--tip-link`` values."""
    from kinecal.io.systems import load_system

    return load_system(model, tips or (), base_link=base_link)


def _refuse(given: dict[str, Any], what: str = "a robot system") -> None:
    for option, value in given.items():
        if value not in (None, False, [], ()):
            raise InputError(f"does not apply to {what} (docs/systems.md)", option=option)


def _read(system, files: list[str], option: str, tip: str | None,
          angle_unit: str | None = None) -> list:
    from kinecal.io.system_data import read_system_data

    return [read_system_data(resolve_data_path(f, option), system, tip, angle_unit)
            for f in files]


def system_calibrate(a: dict[str, Any]) -> None:
    """``kinecal calibrate SYSTEM DATA.csv ...`` (`a`: the calibrate command's arguments)."""
    from kinecal.calibration.blocks.api import calibrate_system
    from kinecal.cli.calibrate_kinds import parse_sigma

    _refuse({"--error-model": a["error_model"], "--harmonics": a["harmonics"],
             "--folds": a["folds"], "--maxiter": a["maxiter"], "--target": a["target"],
             "--model-out": a["model_out"], "--fixture": a.get("fixture")})
    if a["method"] != "lm":
        raise InputError(f"method {a['method']!r}: a robot system is calibrated by lm on one "
                         "stacked problem", option="--method")
    files, validate = list(a["data"]), list(a["validate"] or [])
    inputs = {"MODEL": a["model"], **{f"DATA {f}": f for f in files},
              **{f"--validate {v}": v for v in validate}}
    check_paths(inputs, {"--out": a["out"], "--report": a["report"]})
    record = report_record(a["report"], inputs, a["instrument"], a["operator"], a["note"])
    stated = parse_sigma(a["sigma"], files)
    with warnings_scope(a["strict"]) as found:
        system = load_system_arg(a["model"], a["base_link"], a["tip_link"])
        sets = _read(system, files, "DATA", a["tip"], a.get("angle_unit"))
        vsets = _read(system, validate, "--validate", a["tip"], a.get("angle_unit")) or None
        res = calibrate_system(system, sets, validate=vsets, free=a["free"], loss=a["loss"],
                               sigma=stated, rotation_weight=a["rotation_weight"])
        res.warnings = list(found)
        result = with_warnings(res.to_dict(), found)
        write_outputs(out=a["out"], result=result, report=a["report"],
                      write_report=lambda path: _report(res, path, record),
                      quiet=a["quiet"] or a["json_out"])
    if a["json_out"]:
        echo_json(result)
    elif not a["quiet"]:
        typer.echo(res.summary(a["unit"]))


def _report(res: Any, path: Path, record: Any) -> None:
    from kinecal.report.html import calibration_report

    calibration_report(res, path, provenance=record)


def system_identifiability(a: dict[str, Any]) -> None:
    """``kinecal identifiability SYSTEM [--data A.csv ...] [--poses N]``: per chain and
    for the combination (`kinecal.calibration.blocks.system_ident`)."""
    from kinecal._limits import check_count
    from kinecal.calibration.blocks.plan import analyse_system
    from kinecal.calibration.blocks.system_ident import system_lines
    from kinecal.calibration.blocks.system_simulate import simulate_system

    _refuse({"--error-model": a["error_model"], "--harmonics": a["harmonics"],
             "--fixture": a.get("fixture")})
    with warnings_scope(a["strict"]) as found:
        system = load_system_arg(a["model"], a["base_link"], a["tip_link"])
        if a["data"]:
            sets = [_plan_or_data(system, f, a["tip"], a.get("angle_unit"))
                    for f in a["data"]]
        else:
            n = check_count(50 if a["poses"] is None else a["poses"], "--poses",
                            bytes_per_item=4096)
            sets = [simulate_system(system, n, rng=a["seed"] or 0).data]
        ana, kinds, section = analyse_system(system, sets, a["free"])
    out = ana.report.to_dict()
    out.update({"not_seen": list(ana.unseen), "kinds": kinds, "system": section})
    if a["json_out"]:
        echo_json(with_warnings(out, found))
    elif not a["quiet"]:
        typer.echo(ana.report.explain())
        typer.echo("identifiable: " + ", ".join(ana.report.identifiable))
        typer.echo("\n".join(system_lines(section)[1:]))


def system_select(a: dict[str, Any]) -> None:
    """``kinecal select-poses SYSTEM --count K [--tip T ...] --out PLAN.csv``: the rows of
    the chains that identify the most (joints and a tip column: a plan)."""
    from kinecal._limits import check_count
    from kinecal.calibration.blocks.plan import select_system_poses
    from kinecal.io.system_data import write_system_joints

    _refuse({"--gauge": a["gauge"], "--length": a["length"],
             "--angle-unit": a.get("angle_unit")})
    if a["kind"] != "tracker":
        raise InputError("a robot system plans tracker rows", option="--kind")
    check_paths({"MODEL": a["model"]}, {"--out": a["out"]})
    candidates = check_count(500 if a["candidates"] is None else a["candidates"],
                             "--candidates", bytes_per_item=4096, what="candidates")
    system = load_system_arg(a["model"], a["base_link"], a["tip_link"])
    plan, info = select_system_poses(system, a["count"], candidates=candidates,
                                     tips=a["tip"] or None, rng=a["seed"])
    write_system_joints(a["out"], plan.q, plan.marker, system)
    per_tip = ", ".join(f"{t} {n}" for t, n in info["per_tip"].items())
    typer.echo(f"wrote {a['count']} rows to {a['out']} ({per_tip}); O1 = {info['O1']:.4g}, "
               f"O2 = {info['O2']:.4g} ({info['rank']} identifiable parameters)", err=True)


def _plan_or_data(system, spec: str, tip: str | None, angle_unit: str | None = None):
    """A measurement file of a system, or a plan (joints and tips alone: what
    ``select-poses`` writes) measured by the nominal system (only its rows matter to an
    analysis)."""
    from kinecal.data import Measurements
    from kinecal.io.kinds import KINDS
    from kinecal.io.measurements import csv_header
    from kinecal.io.system_data import read_system_data, system_readings

    path = resolve_data_path(spec, "--data")
    header = csv_header(path)
    if any(c in header for cols in KINDS.values() for c in cols):
        return read_system_data(path, system, tip, angle_unit)
    q, tips, _, _ = system_readings(path, header, system, tip, angle_unit=angle_unit)
    return Measurements(q, system.positions(q, marker=tips), source=str(path), marker=tips,
                        marker_names=system.tips)


def _tips_of_file(system, path: Path, tip: str | None, angle_unit: str | None = None):
    from kinecal.io.measurements import csv_header
    from kinecal.io.system_data import system_readings

    return system_readings(path, csv_header(path), system, tip, angle_unit=angle_unit)[:2]


def _result_params(system, params: Path | None):
    if params is None:
        return None
    from kinecal.io.result_values import parameters_from_result

    return parameters_from_result(system, params)


def system_fk(a: dict[str, Any]) -> None:
    """``kinecal fk SYSTEM JOINTS.csv [--tip T]``: each row's tool point on its chain."""
    import sys

    from kinecal.spatial import quaternion_from_matrix

    with warnings_scope(a["strict"]):
        system = load_system_arg(a["model"], a["base_link"], a["tip_link"])
        tip = a["tip"] or _one_part(system, a["tip_link"])
        path = resolve_data_path(a["joints"], "JOINTS")
        q, tips = _tips_of_file(system, path, tip, a.get("angle_unit"))
        p = _result_params(system, a["params"])
    T = system.fk(q, p, tips)
    header = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if a["pose"] else [])
    out = T[:, :3, 3]
    if a["pose"]:
        out = np.column_stack([out, quaternion_from_matrix(T[:, :3, :3])])
    lines = [",".join(header)] + [",".join(map(repr, row)) for row in out.tolist()]
    sys.stdout.write("\n".join(lines) + "\n")


def _one_part(system, tip_links: list[str] | None) -> str | None:
    """A system file's one ``--tip-link`` names the chain (as ``--tip``)."""
    if system.source.get("system") and tip_links and len(tip_links) == 1:
        return tip_links[0]
    return None


def system_simulate(a: dict[str, Any]) -> None:
    """``kinecal simulate SYSTEM --poses N [--tip T ...] --out DATA.csv``: tracker rows of
    each chain (or ``--kind pair`` between two tips) from one true system."""
    from kinecal._limits import check_count, check_finite
    from kinecal.calibration.blocks.system_simulate import simulate_system
    from kinecal.calibration.serial.simulate import random_errors, read_truth, write_truth
    from kinecal.io.system_data import write_system_data

    _refuse({"--images": a["images"], "--pivot": a["pivot"],
             "--plane": a["plane"], "--radius": a["radius"], "--groups": a["groups"],
             "--sigma-column": a["sigma_column"], "--angle-noise": a["angle_noise"]})
    if a["kind"] not in ("tracker", "pair", "point"):
        raise InputError(f"kind {a['kind']!r}: a robot system simulates tracker, pair or "
                         "point rows", option="--kind")
    errors = a["errors"]
    check_paths({"MODEL": a["model"], "--errors": None if errors in ("zero", "random")
                 else errors, "--joints": a["joints"]},
                {"--out": a["out"], "--truth-out": a["truth_out"]})
    check_finite(a["noise"], "--noise")
    if a["poses"] is not None:
        check_count(a["poses"], "--poses", bytes_per_item=4096)
    with warnings_scope(a["strict"]):
        system = load_system_arg(a["model"], a["base_link"], a["tip_link"])
        if errors in ("zero", "random"):
            gen = np.random.default_rng(a["seed"])
            e = np.zeros(system.n_params) if errors == "zero" else random_errors(system, gen)
            true = system.nominal + e
        else:
            true = read_truth(Path(errors), system)
        centres = None
        if a["point"]:
            from kinecal.cli.calibrate_kinds import _vectors

            centres = _vectors(a["point"], 3, "--point")
        if a["joints"] is not None:  # the rows of a plan (select-poses), measured
            data = _measured_plan(system, a, true)
        else:
            data = simulate_system(system, a["poses"], kind=a["kind"], tips=a["tip"] or None,
                                   true_params=true, noise=a["noise"], rng=a["seed"],
                                   orientation=a["orientation"], length=a["length"],
                                   centres=centres, carrier=a["carrier"]).data
        write_system_data(a["out"], data, system)
        if a["truth_out"] is not None:
            write_truth(a["truth_out"], system, true)
    if not a["quiet"]:
        typer.echo(f"wrote {len(data)} {a['kind']} rows of {system.name} to {a['out']}"
                   + (f", truth to {a['truth_out']}" if a["truth_out"] else ""), err=True)


def _measured_plan(system, a: dict[str, Any], true):
    """``simulate SYSTEM --joints PLAN.csv``: tracker rows at a plan's joints and tips."""
    from kinecal.data import Measurements

    if a["kind"] != "tracker":
        raise InputError("applies to tracker rows only", option="--joints")
    q, tips = _tips_of_file(system, resolve_data_path(a["joints"], "--joints"), None,
                            a.get("angle_unit"))
    T = system.fk(q, true, tips)
    gen = np.random.default_rng(a["seed"])
    xyz = T[:, :3, 3] + (gen.normal(0.0, a["noise"], (len(q), 3)) if a["noise"] > 0 else 0.0)
    return Measurements(q, xyz, None, f"simulated {system.name}",
                        T[:, :3, :3] if a["orientation"] else None, tips, system.tips)


def system_arms(calibrated: str, nominal: str | None, base_link: str | None,
                tips: list[str] | None, tip: str | None, tool: str):
    """``compensate RESULT.json PROGRAM --nominal SYSTEM --tip T``: the nominal and the
    calibrated chain of tip `T` as serial models (`SystemModel.tip_model`)."""
    if nominal is None:
        raise InputError("a robot system's result: give the system it calibrated (--nominal "
                         "SYSTEM, with its --tip-link)", option="--nominal")
    if not str(calibrated).lower().endswith(".json"):
        raise InputError("a robot system is compensated from its calibration result JSON "
                         "(kinecal calibrate --out)", option="CALIBRATED")
    if tool != "calibrated":
        raise InputError("does not apply to a robot system", option="--tool")
    system = load_system_arg(nominal, base_link, tips)
    tip = tip or _one_part(system, tips)
    if tip is None:
        raise InputError(f"which chain: give --tip (one of {', '.join(system.tips)})",
                         option="--tip")
    p = _result_params(system, Path(calibrated))
    return system.tip_model(tip), system.tip_model(tip, p)


def system_export(source: str, nominal: str | None, base_link: str | None,
                  tips: list[str] | None, out: Path, fmt: str, chain_only: bool) -> None:
    """``kinecal export [RESULT.json] --nominal SYSTEM --format urdf --out TREE.urdf``: the
    whole (calibrated) tree (`kinecal.io.urdf_tree_export`)."""
    from kinecal._files import write_text_atomic
    from kinecal.io.urdf_tree_export import patched_tree_urdf, tree_urdf_string

    if fmt != "urdf":
        raise InputError(f"a robot system exports as urdf (the whole tree), not {fmt}",
                         option="--format")
    is_result = str(source).lower().endswith(".json")
    spec = nominal if is_result else source
    if spec is None:
        raise InputError("a robot system's result: give the system it calibrated (--nominal "
                         "SYSTEM, with its --tip-link)", option="--nominal")
    system = load_system_arg(spec, base_link, tips)
    params = _result_params(system, Path(source)) if is_result else None
    what = (f"{source} (calibrated {system.name})" if is_result else f"system {system.name}")
    comment = f"written by kinecal export from {what}; lengths in metres, angles in radians"
    urdf = system.source.get("urdf")
    if urdf is not None and not chain_only:
        text = patched_tree_urdf(urdf, system, params, comment=comment + f", into "
                                 f"{Path(urdf).name}")
    else:
        text = tree_urdf_string(system, params, comment=comment)
    write_text_atomic(out, text)
    typer.echo(f"wrote {out} (urdf, {len(system.tips)} tips, {system.n_joints} joints, "
               f"metres, radians) from {what}", err=True)
