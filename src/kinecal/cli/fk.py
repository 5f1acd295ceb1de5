"""Serial-arm commands ``models`` and ``fk``: the bundled files, forward kinematics."""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import echo_json
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    quiet_option,
    strict_option,
    tip_links_option,
    tip_option,
)


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
    given = dict(locals())
    from kinecal.cli._fk_run import run_fk

    return run_fk(**given)
