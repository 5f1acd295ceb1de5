"""``kinecal compensate``: a robot program rewritten for the calibrated arm.

PROGRAM.csv is either a joint program (``q1..qn`` in the model's angle unit, what the
controller was told) or Cartesian targets (``x,y,z`` and optionally ``qw,qx,qy,qz``, in the
model's length unit, with optional seed joints ``q1..qn``). Every column of the program is
written back in its place (``q1..qn`` hold the joints to command, added if absent), followed
by the compensation columns (see ``docs/compensate.md``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    progress,
    resolve_data_path,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import (
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    check_unit,
    choices,
    quiet_option,
    single_tip,
    strict_option,
    tip_links_option,
    tip_option,
    unit_option,
)
from kinecal.errors import InputError

_SUFFIX = "-calibrated"


def _is_urdf(spec: str | Path | None) -> bool:
    from kinecal.io.models import is_urdf_path

    return is_urdf_path(spec)


def load_calibrated(spec: str, nominal: str | None, base_link: str | None = None,
                    tip_link: str | None = None, tool: str = "calibrated"):
    """(nominal model, calibrated model) from a model file or a result JSON.

    A result JSON names its nominal model (``"model"``); a model file written by
    ``calibrate --model-out`` is called ``NAME-calibrated``. Either gives the default of
    `nominal` when that is a bundled model; otherwise ``--nominal`` is required. Joint-error
    terms of a result (``--error-model``) come with it. `base_link` and `tip_link` choose
    the chain of the nominal model when it is a URDF, else of a calibrated URDF. With
    `tool` ``"nominal"`` the calibrated model carries the nominal model's tool (markers of
    a calibration with several targets replaced by it).
    """
    from kinecal.compensation.inputs import with_nominal_tool
    from kinecal.compensation.same_arm import check_same_arm
    from kinecal.io.models import bundled_models
    from kinecal.io.models import load_model as _load_model

    if (base_link or tip_link) and not (_is_urdf(spec) or _is_urdf(nominal)):
        raise InputError("applies to URDF models only",
                         option="--base-link" if base_link else "--tip-link")
    # the chain ends choose the nominal URDF's chain (the one the controller runs); a
    # calibrated URDF written by `kinecal export` is read along its own default chain
    # (world -> tool: the calibrated base frame and tool point included), unless it is
    # the only URDF
    links_for = nominal if _is_urdf(nominal) else spec

    def load_model(name: str | Path):
        if _is_urdf(name) and str(name) == str(links_for):
            return _load_model(name, base_link=base_link, tip_link=tip_link)
        try:
            return _load_model(name)
        except InputError as exc:
            # an export's tool link beside a gripper's fingers: the calibrated chain ends
            # there (the --tip-link option names the nominal URDF's tip)
            if not (_is_urdf(name) and "branches" in exc.message):
                raise
            from kinecal.io.urdf import read_urdf

            if "tool" not in {link.name for link in read_urdf(name).robot.links}:
                raise
            return _load_model(name, tip_link="tool")

    path = Path(spec)
    if not path.exists():
        if spec in bundled_models():
            raise InputError(f"{spec} is a bundled nominal model: expected the calibrated "
                             "model (calibrate --model-out) or result JSON (calibrate --out); "
                             "the nominal model goes to --nominal", option="CALIBRATED")
        raise InputError("file not found", file=spec, option="CALIBRATED")
    if path.suffix.lower() == ".json":
        from kinecal._files import read_json
        from kinecal.cli._serial_common import parameters_from_result
        from kinecal.io.result_values import model_for_result, serial_result_parameters

        data = read_json(path)
        serial_result_parameters(data, path)
        named = data.get("model") if isinstance(data, dict) else None
        if nominal is None:
            if not (isinstance(named, str) and named in bundled_models()):
                raise InputError(f"{path}: give --nominal MODEL (the model this result "
                                 "calibrated)", option="--nominal")
            nominal = named
        nom = load_model(nominal)
        if isinstance(named, str) and named != nom.name:
            raise InputError(f"the result calibrated model {named!r}, not {nom.name!r}: "
                             "refusing to compensate another arm", file=path)
        full = model_for_result(nom, path)
        cal = full.with_params(parameters_from_result(full, path), name=f"{nom.name}{_SUFFIX}")
    else:
        cal = load_model(path)
        if nominal is None:
            stem = cal.name[: -len(_SUFFIX)] if cal.name.endswith(_SUFFIX) else None
            if stem is None or stem not in bundled_models():
                raise InputError(f"{path}: give --nominal MODEL (the model the controller "
                                 "runs)", option="--nominal")
            nominal = stem
        nom = load_model(nominal)
    try:
        if tool == "nominal":
            cal = with_nominal_tool(cal, nom)
        check_same_arm(nom, cal)
    except InputError as exc:
        if exc.option is not None:
            raise
        raise InputError(exc.message, file=path) from None
    return nom, cal


@app.command("compensate")
def compensate_cmd(
    calibrated: str = typer.Argument(..., help="Calibrated model (YAML from calibrate "
                                     "--model-out, or a calibrated URDF from export) or "
                                     "calibration result JSON."),
    program: str = typer.Argument(..., help="Program CSV: joints q1..qn, or targets x,y,z"
                                  "[,qw,qx,qy,qz] with optional seed joints q1..qn."),
    nominal: str | None = typer.Option(None, "--nominal", help="The model the controller runs "
                                       "(bundled name or path); default: the one CALIBRATED "
                                       "names."),
    out: Path = typer.Option(..., "--out", help="Compensated program CSV to write."),
    position_only: bool = typer.Option(False, "--position-only", help="Compensate the tool "
                                       "point only (default: the full pose on arms with at "
                                       "least 6 joints, or when targets have orientations)."),
    base: str = typer.Option("calibrated", "--base", metavar=choices("calibrated", "nominal"),
                             help="calibrated (the program lives in "
                             "the measured frame) or nominal (measured in an instrument's "
                             "frame: the base is registered onto the nominal arm)."),
    tool: str = typer.Option("calibrated", "--tool", metavar=choices("calibrated", "nominal"),
                             help="calibrated (the calibration "
                             "measured the program's tool) or nominal (it measured a target, "
                             "e.g. a tracker reflector: the nominal tool on the calibrated "
                             "arm)."),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    tip: str | None = tip_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the statistics as JSON."),
    unit: str = unit_option(),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    angle_unit: str | None = angle_unit_option("the program's joint columns, in and out"),
) -> None:
    """Rewrite a joint program or Cartesian targets for the calibrated arm."""
    from kinecal.cli._program import count_rows, program_columns, stream
    from kinecal.compensation.api import prepare_arms
    from kinecal.io.measurements import joint_columns

    shown = check_unit(unit)
    check_angle_unit(angle_unit)
    check_paths({"CALIBRATED": calibrated, "PROGRAM": program, "--nominal": nominal},
                {"--out": out})
    if base not in ("calibrated", "nominal"):
        raise InputError(f"expected calibrated or nominal, got {base!r}", option="--base")
    if tool not in ("calibrated", "nominal"):
        raise InputError(f"expected calibrated or nominal, got {tool!r}", option="--tool")
    from kinecal.cli.systems import is_system_arg

    system = nominal is not None and is_system_arg(nominal, base_link, tip_link)
    if tip is not None and not system:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    with warnings_scope(strict) as found:
        if system:  # one chain of a robot system (--tip)
            from kinecal.cli.systems import system_arms

            nom, cal = system_arms(calibrated, nominal, base_link, tip_link, tip, tool)
        else:
            nom, cal = load_calibrated(calibrated, nominal, base_link, single_tip(tip_link),
                                       tool)
        path = resolve_data_path(program, "PROGRAM")
        header, required, optional = program_columns(path, nom)
        joints = joint_columns(header, nom, path, required=False)
        envelope = None  # the joint readings a result was calibrated on
        if Path(calibrated).suffix.lower() == ".json":
            from kinecal.io.result_values import read_result_envelope

            envelope = read_result_envelope(nom, calibrated)
        arms = prepare_arms(cal, nom, base=base, tool=tool, envelope=envelope)
        total = count_rows(path)
        with progress(f"compensate {total} rows", total, quiet or json_out) as bar:
            rows = stream(path, out, header, required, optional, joints, arms,
                           "position" if position_only else None, bar, angle_unit)
    stats = {"program": str(program), "out": str(out), "model": nom.name,
             "base": base, "tool": tool, **rows.stats()}
    if json_out:
        echo_json(with_warnings(stats, found))
    elif not quiet:
        typer.echo(rows.summary(shown))
        typer.echo(f"wrote {len(rows)} rows to {out}")


def demo_compensation(result, out: Path, label: str) -> tuple[object, Path, str]:
    """Compensate the validation poses of a calibration result as a joint program.

    Writes ``compensated.csv`` (``pose, q1..qn`` and the compensation columns) into `out`
    and returns the `CompensationResult`, its path and a short text for the terminal.
    """
    from kinecal.cli._program import fmt_float, program_output_columns, write_program
    from kinecal.compensation.api import compensate

    nom = result.nominal_model
    q = result.q_validation if result.q_validation is not None else result.q_calibration
    res = compensate(result, joints=q)
    joints = [f"q{i}" for i in range(1, nom.n_joints + 1)]
    scale = nom.joint_scale()
    cells = [[str(k + 1), *(fmt_float(v) for v in row / scale)] for k, row in enumerate(q)]
    path = out / "compensated.csv"
    write_program(path, ["pose", *joints], cells, {}, program_output_columns(res, nom, joints))
    unit = nom.length_unit
    dq = np.degrees(res.joint_motion()[0])  # revolute joints (prismatic: a length)
    lines = [f"compensation of the {len(res)} held-out poses as a joint program ({label}):",
             f"  {'pose':>4s} {'max |dq| [deg]':>15s} {'correction [' + unit + ']':>17s} "
             f"{'angle [deg]':>12s}  status"]
    for k in range(min(len(res), 5)):
        lines.append(f"  {k + 1:4d} {dq[k]:15.4f} {res.correction[k]:17.4f} "
                     f"{np.degrees(res.correction_rotation[k]):12.4f}  {res.status[k]}")
    if len(res) > 5:
        lines.append(f"  ... ({len(res) - 5} more in {path.name})")
    c = res.correction
    lines.append(f"{int(res.converged.sum())} of {len(res)} converged; corrections "
                 f"{c.min():.3g}-{c.max():.3g} {unit} (mean {c.mean():.3g} {unit}), joints "
                 f"by up to {dq.max():.3g} deg: the calibrated arm reaches the nominal poses "
                 f"to {res.residual[res.converged].max():.1g} {unit}")
    return res, path, "\n".join(lines)
