"""Serial-arm commands: ``models``, ``fk``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import echo_json, resolve_data_path
from kinecal.errors import InputError


def parameters_from_result(model, path: Path) -> np.ndarray:
    """Full parameter vector from a calibration result JSON (``identified`` values)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not a readable JSON file ({exc})", file=path) from None
    params = data.get("parameters") if isinstance(data, dict) else None
    if not isinstance(params, dict):
        raise InputError("expected a calibration result with a 'parameters' mapping", file=path)
    angle = model.is_angle()
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    p = model.nominal
    for name, entry in params.items():
        k = model.index([name])[0] if name in model.parameter_names else None
        if k is None:
            raise InputError(f"parameter {name!r} does not belong to model {model.name!r}",
                             file=path)
        try:
            value = float(entry["identified"] if isinstance(entry, dict) else entry)
        except (KeyError, TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'identified'",
                             file=path) from None
        p[k] = value * scale if angle[k] else value
    return p


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
    model: str = typer.Argument(..., help="Bundled model name or model YAML path."),
    joints: str = typer.Argument(..., help="CSV with q1..qn (model angle unit) or NAME:PART."),
    pose: bool = typer.Option(False, "--pose", help="Also print qw,qx,qy,qz of the tool frame."),
    params: Path | None = typer.Option(None, "--params", help="Calibration result JSON."),
) -> None:
    """Forward kinematics: tool-point positions (CSV on stdout)."""
    from kinecal.io.csvtable import read_table
    from kinecal.io.models import load_model
    from kinecal.spatial import quaternion_from_matrix

    m = load_model(model)
    path = resolve_data_path(joints, "JOINTS")
    if path.suffix == "" or "x_t" in path.read_text(encoding="utf-8", errors="replace")[:200]:
        from kinecal.io.measurements import read_measurements

        q = read_measurements(path, m).q
    else:
        names = [f"q{i}" for i in range(1, m.n_joints + 1)]
        cols = read_table(path, names)
        scale = np.pi / 180.0 if m.angle_unit == "deg" else 1.0
        q = np.column_stack([cols[n] for n in names]) * scale
    p = None if params is None else parameters_from_result(m, params)
    T = m.fk(q, p)
    header = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if pose else [])
    out = T[:, :3, 3]
    if pose:
        out = np.column_stack([out, quaternion_from_matrix(T[:, :3, :3])])
    lines = [",".join(header)] + [",".join(f"{v:.10g}" for v in row) for row in out]
    sys.stdout.write("\n".join(lines) + "\n")
