"""Serial-arm commands ``models`` and ``fk``: the bundled files, forward kinematics."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import echo_json, resolve_data_path, warnings_scope
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    load_model_arg,
    quiet_option,
    single_tip,
    strict_option,
    tip_links_option,
    tip_option,
)
from kinecal.errors import InputError


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
    from kinecal.io.bundled import bundled_names
    from kinecal.io.systems import load_system

    systems = []
    for name in bundled_names("system"):
        s = load_system(name)
        systems.append({"name": name, "tips": list(s.tips), "joints": s.n_joints,
                        "parameters": s.n_params, "length_unit": s.length_unit,
                        "description": s.description})
    if json_out:
        echo_json({"models": arms, "systems": systems, "geometries": geometries,
                   "datasets": datasets})
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
    for s in systems:
        console.print(f"system {s['name']}: tips {', '.join(s['tips'])} ({s['joints']} "
                      f"joints, {s['parameters']} parameters, {s['length_unit']})")
    if geometries:
        console.print("Stewart geometries: " + ", ".join(
            g if isinstance(g, str) else g.get("name", "") for g in geometries))
    for d in datasets:
        console.print(f"dataset {d['name']} ({d['license']}): {', '.join(d['parts'])}")


@app.command()
def fk(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    joints: str = typer.Argument(..., help="CSV with q1..qn (model angle unit) or NAME:PART; "
                                 "a robot system's: its joint names and a tip column."),
    pose: bool = typer.Option(False, "--pose", help="Also print qw,qx,qy,qz of the tool frame."),
    params: Path | None = typer.Option(None, "--params", help="Calibration result JSON."),
    tip: str | None = tip_option(),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    angle_unit: str | None = angle_unit_option("JOINTS"),
) -> None:
    """Forward kinematics: tool-point positions (CSV on stdout)."""
    check_angle_unit(angle_unit)
    from kinecal.cli.systems import is_system_arg

    if is_system_arg(model, base_link, tip_link):
        from kinecal.cli.systems import system_fk

        return system_fk(dict(locals()))
    if tip is not None:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    tip_link = single_tip(tip_link)
    from kinecal.calibration.diagnostics.units import check_joint_limits, check_joint_units
    from kinecal.io.measurements import read_joints, read_markers

    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        if params is not None:  # imported here: a plain fk reads no result
            from kinecal.cli._serial_common import parameters_from_result
            from kinecal.io.result_values import model_for_result, read_result_envelope

            m = model_for_result(m, params)
        path = resolve_data_path(joints, "JOINTS")
        q = read_joints(path, m, angle_unit=angle_unit)
        marker = read_markers(path, m)[0] if m.marker_names else None
        check_joint_limits(m, q, "joint readings")
        check_joint_units(m, q, "joint readings")
        p = None if params is None else parameters_from_result(m, params)
        # the joint readings the calibration saw: the result's, or those of the terms of a
        # calibrated model file
        envelope = (read_result_envelope(m, params) if params is not None else
                    None if m.joint_errors is None else m.joint_errors.envelope)
        if envelope is not None:
            from kinecal.calibration.diagnostics.envelope import check_calibrated_range

            check_calibrated_range(q, envelope, m, "joint readings")
    T = m.fk(q, p, marker)
    header = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if pose else [])
    out = T[:, :3, 3]
    if pose:
        from kinecal.spatial import quaternion_from_matrix

        out = np.column_stack([out, quaternion_from_matrix(T[:, :3, :3])])
    # shortest round-trip digits (repr): what the API computes, bit for bit, in any unit
    lines = [",".join(header)] + [",".join(map(repr, row)) for row in out.tolist()]
    sys.stdout.write("\n".join(lines) + "\n")
