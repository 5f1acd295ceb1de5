"""``kinecal export``: a model or a calibration result as URDF or as a kinecal model file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import (
    base_link_option,
    check_paths,
    choices,
    load_model_arg,
    strict_option,
    tip_link_option,
    warnings_scope,
)
from kinecal.errors import InputError

FORMATS = ("urdf", "yaml")
_SUFFIX = {".urdf": "urdf", ".yaml": "yaml", ".yml": "yaml"}
#: relative tolerance when checking a result's nominal values against --nominal
_NOMINAL_RTOL = 1e-9


def _format(fmt: str | None, out: Path) -> str:
    if fmt is None:
        fmt = _SUFFIX.get(out.suffix.lower())
        if fmt is None:
            raise InputError(f"cannot tell the format from {out.name!r}: give --format urdf "
                             "or --format yaml", option="--format")
    if fmt not in FORMATS:
        raise InputError(f"unknown format {fmt!r}; expected urdf or yaml", option="--format")
    if fmt == "yaml" and out.name.lower().endswith((".urdf", ".xacro")):
        raise InputError(f"a model file (yaml) named {out.name!r} would be read back as a "
                         "URDF: name it .yaml, or give --format urdf", option="--format")
    return fmt


def _check_nominal(model, data: dict, path: Path) -> None:
    """Refuse a --nominal model whose values differ from those the result was computed
    from (the identified values would be applied to the wrong arm)."""
    scale = np.where(model.is_angle(), 180.0 / np.pi if model.angle_unit == "deg" else 1.0,
                     1.0)
    nominal = model.nominal * scale
    for name, entry in data["parameters"].items():
        if not isinstance(entry, dict) or "nominal" not in entry or \
                name not in model.parameter_names:
            continue
        k = model.index([name])[0]
        try:
            value = float(entry["nominal"])
        except (TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'nominal'",
                             file=path) from None
        if not np.isclose(value, nominal[k], rtol=_NOMINAL_RTOL, atol=1e-12):
            raise InputError(
                f"parameter {name}: the result's nominal value {value:.12g} is not the model's "
                f"{nominal[k]:.12g}: give --nominal the model the result was calibrated from",
                file=path)


def model_and_params(source: str, nominal: str | None, base_link: str | None,
                     tip_link: str | None):
    """The model, the identified parameter vector (or None) and the URDF file the model
    was read from (or None) behind SOURCE.

    SOURCE is a model (bundled name, YAML, URDF) or a calibration result JSON; for a
    result the nominal model is `nominal`, or the bundled model the result names.
    """
    from kinecal._files import read_json
    from kinecal.io.results import (
        model_for_result,
        parameters_from_result,
        serial_result_parameters,
    )

    if not source.lower().endswith(".json"):
        if nominal is not None:
            raise InputError("--nominal applies to a calibration result (RESULT.json) only",
                             option="--nominal")
        return load_model_arg(source, base_link, tip_link), None, _urdf_path(source)
    path = Path(source)
    data = read_json(path)
    serial_result_parameters(data, path)
    if nominal is None:
        from kinecal.io.models import bundled_models

        name = data.get("model")
        if name not in bundled_models():
            raise InputError(f"the result is for model {name!r}, not a bundled one: give "
                             "--nominal MODEL (the model file or URDF it was calibrated from)",
                             option="--nominal")
        nominal = str(name)
    model = model_for_result(load_model_arg(nominal, base_link, tip_link), path)
    _check_nominal(model, data, path)
    return model, parameters_from_result(model, path), _urdf_path(nominal)


def _urdf_path(spec: str) -> Path | None:
    from kinecal.io.models import is_urdf_path

    return Path(spec) if is_urdf_path(spec) else None


@app.command("export")
def export(
    source: str = typer.Argument(..., help="Model (bundled name, YAML, URDF) or calibration "
                                 "result JSON (kinecal calibrate --out)."),
    out: Path = typer.Option(..., "--out", help="File to write (.urdf, .yaml)."),
    fmt: str | None = typer.Option(None, "--format", metavar=choices(*FORMATS),
                                   help="Output format (default: from the --out suffix)."),
    nominal: str | None = typer.Option(None, "--nominal", help="With a RESULT.json: the model "
                                       "it was calibrated from (default: the bundled model "
                                       "the result names)."),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    chain_only: bool = typer.Option(False, "--chain-only", help="For a model read from a "
                                    "URDF: write only the chain, not a copy of that URDF "
                                    "(meshes, other branches) with the chain's values."),
    strict: bool = strict_option(),
) -> None:
    """Write a model, or a calibrated one, as URDF (metres, radians) or as a model file.

    A model read from a URDF is written into a copy of that URDF: its chain's joint origins
    take the calibrated values, a tool link (and the measurement frame) are added, and
    everything else (meshes, inertias, other branches) is kept.
    """
    from kinecal.io.models import save_model
    from kinecal.io.urdf_export import save_urdf
    from kinecal.io.urdf_patch import save_patched_urdf

    fmt = _format(fmt, out)
    check_paths({"SOURCE": source, "--nominal": nominal}, {"--out": out})
    with warnings_scope(strict):
        model, params, urdf = model_and_params(source, nominal, base_link, tip_link)
        if fmt == "urdf" and model.joint_errors is not None:
            from kinecal.diagnostics import warn

            warn("joint-errors-not-exported",
                 f"the model's {len(model.parameter_names) - model._n_geometric} joint-error "
                 "coefficients (compliance, harmonics, scale) have no URDF equivalent: the "
                 "URDF carries the geometry only; use the model file (--format yaml) for fk, "
                 "ik and compensate")
    what = f"model {model.name}" if params is None else f"{source} (calibrated {model.name})"
    if fmt == "urdf":
        comment = f"written by kinecal export from {what}; lengths in metres, angles in radians"
        if urdf is not None and not chain_only:
            save_patched_urdf(urdf, model, out, params, comment=comment + f", into {urdf.name}")
        else:
            save_urdf(model, out, params, comment=comment)
        unit = "metres, radians"
    else:
        target = model if params is None else model.with_params(
            params, name=f"{model.name}-calibrated")
        save_model(target, out)
        unit = f"{model.length_unit}, {model.angle_unit}"
    typer.echo(f"wrote {out} ({fmt}, {model.n_joints} joints, {unit}) from {what}", err=True)
