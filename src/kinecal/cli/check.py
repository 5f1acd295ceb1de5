"""``kinecal check``: is a robot's current calibration still valid? And ``kinecal
plan-check``: the few poses that tell. (docs/robot-life.md; the test is
`kinecal.registry.check`'s.)"""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, echo_json, warnings_scope, with_warnings
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    load_model_arg,
    seed_option,
    strict_option,
    tip_link_option,
)
from kinecal.cli._programs import (
    check_program_for,
    program_option,
    wait_option,
    write_program_for,
)
from kinecal.cli._registry_common import (
    check_serial,
    command_text,
    date_option,
    db_input,
    db_option,
    parse_date_option,
    serial_argument,
)
from kinecal.errors import InputError


@app.command("check")
def check(
    serial: str = serial_argument(),
    data: list[str] = typer.Argument(..., metavar="FEW.csv...", help="Today's measurements "
                                     "of 5 to 20 poses, any kind (docs/measurement-kinds.md); "
                                     "several files of several kinds make one check."),
    limit: float | None = typer.Option(None, "--limit", help="Largest acceptable systematic "
                                       "error, RMS per pose (length unit; default twice the "
                                       "calibration's RMS error)."),
    alpha: float = typer.Option(1e-4, "--alpha", help="Probability that an unchanged robot "
                                "is found changed (false alarm)."),
    sigma: list[str] | None = typer.Option(None, "--sigma", help="Today's instrument noise, "
                                           "1 sigma per coordinate (length unit; default: "
                                           "the file's sigma column, else the "
                                           "calibration's); FILE=SIGMA per file."),
    register: str | None = typer.Option(None, "--register", metavar="[base]", help="base: "
                                        "fit the base frame to today's data (the instrument "
                                        "was set up elsewhere); base changes are then not "
                                        "judged."),
    date: str | None = date_option("measurement"),
    operator: str | None = typer.Option(None, "--operator", help="Who measured."),
    instrument: str | None = typer.Option(None, "--instrument", help="The instrument."),
    note: str | None = typer.Option(None, "--note", help="Free text."),
    out: Path | None = typer.Option(None, "--out", help="Also write the check's JSON here."),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the check as JSON."),
    strict: bool = strict_option(),
    angle_unit: str | None = angle_unit_option("the files' joint columns"),
) -> None:
    """Check a robot's current calibration against a few poses measured today; stored in
    the registry. Exit 0 valid, 3 drifted (within the limit), 4 recalibrate."""
    from kinecal.cli._common import resolve_data_path, write_json
    from kinecal.cli.calibrate_kinds import parse_sigma
    from kinecal.registry.check import EXIT_CODES
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.store import open_registry

    serial = check_serial(serial)
    check_angle_unit(angle_unit)
    if register not in (None, "base"):
        raise InputError(f"expected base, got {register!r}", option="--register")
    check_paths({**db_input(db), **{f"DATA {d}": d for d in data}}, {"--out": out})
    paths = [resolve_data_path(d) for d in data]
    stated = parse_sigma(sigma, data)
    when = parse_date_option(date)
    with open_registry(db) as reg, warnings_scope(strict) as found:
        doc, stored, new = check_robot(
            reg, serial, paths, sigma=stated, limit=limit, alpha=alpha,
            register_base=register == "base", date=when, operator=operator,
            instrument=instrument, note=note, command=command_text(),
            warnings=lambda: list(found), angle_unit=angle_unit)
    result = with_warnings({"serial": serial, "id": stored["id"], "date": stored["date"],
                            **doc}, found)
    if out is not None:
        write_json(out, result)
    if not new:
        typer.echo(f"this check is in the registry already as check {stored['id']} "
                   f"({stored['date']}): its verdict {stored['verdict']}", err=True)
    if json_out:
        echo_json(result)
    else:
        typer.echo(_text(serial, stored, doc))
    raise typer.Exit(EXIT_CODES[stored["verdict"]])


def _text(serial: str, stored: dict, res: dict) -> str:
    unit = res["length_unit"]
    dof = res["noise_dof"]
    test = "chi-square" if dof is None else f"F (noise dof {dof:.0f})"
    d = res["directed"]
    lines = [
        f"{serial}: {res['verdict'].upper()} (check {stored['id']}, {stored['date']}, of "
        f"calibration {res['calibration']})",
        f"  overall {test} test: statistic {res['statistic']:.4g} on {res['dof']} dof, "
        f"p = {res['p_value']:.3g}; directed test ({d['dof']} directions): "
        f"statistic {d['statistic']:.4g}, p = {d['p_value']:.3g}; alpha {res['alpha']:g}",
        f"  systematic error {res['deviation']:.4g} {unit} RMS per pose (limit "
        f"{res['limit']:.4g} {unit})",
    ]
    if res.get("base_registered") and res["base_registered"] != "asked for":
        lines.append(f"  the base frame was fitted to today's data: "
                     f"{res['base_registered']}")
    big = sorted(res["directions"].items(), key=lambda kv: -abs(kv[1]["change"]) /
                 max(kv[1]["std"], 1e-300))[:3]
    for name, d in big:
        if abs(d["change"]) > 3 * d["std"]:
            lines.append(f"  {name} changed by {d['change']:+.4g} +- {d['std']:.2g} "
                         f"{d['unit']}")
    worst = sorted(res["poses"], key=lambda p: -(p["ratio"] or 0))[:3]
    for p in worst:
        lines.append(f"  pose {p['set']}:{p['row']}: error {p['error']:.4g} {unit} "
                     f"(expected {p['expected']:.3g} without a change)")
    return "\n".join(lines)


@app.command("plan-check")
def plan_check_cmd(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    poses: int = typer.Option(10, "--poses", help="Number of check poses (3 to 200)."),
    out: Path = typer.Option(..., "--out", help="CSV of the poses' joints q1..qn (model "
                             "units)."),
    program: Path | None = program_option(),
    candidates: int = typer.Option(2000, "--candidates", help="Random candidate poses."),
    seed: int = seed_option("Random seed for the candidates (an integer >= 0)."),
    sigma: float | None = typer.Option(None, "--sigma", help="The instrument's noise (length "
                                       "unit): say what each change must be to be seen."),
    limit: float | None = typer.Option(None, "--limit", help="The check's limit (length "
                                       "unit): say how large each change is at the limit."),
    wait: float = wait_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the plan as JSON."),
    angle_unit: str | None = angle_unit_option("the plan's joint columns"),
) -> None:
    """Choose the few poses that best reveal joint offsets, a moved base and a bent link."""
    check_angle_unit(angle_unit)
    from kinecal._limits import check_count, check_finite
    from kinecal.io.csvtable import write_table
    from kinecal.registry.plan import plan_check

    check_paths({"MODEL": model}, {"--out": out, "--program": program})
    check_finite(sigma, "--sigma", positive=True)
    check_finite(limit, "--limit", positive=True)
    m = load_model_arg(model, base_link, tip_link)
    check_program_for(program, m, wait)
    check_count(candidates, "--candidates", bytes_per_item=256 * m.n_params,
                what="candidates")
    plan = plan_check(m, poses, candidates=candidates, seed=seed, sigma=sigma, limit=limit)
    scale = 1.0 / m.joint_scale(angle_unit)
    from kinecal._files import all_or_nothing

    with all_or_nothing():  # the plan and its program both, or neither
        write_table(out, {f"q{i + 1}": plan.q[:, i] * scale[i] for i in range(m.n_joints)})
        if program is not None:
            write_program_for(program, m, plan.q, wait,
                              f"kinecal plan-check {m.name}: check poses")
    if json_out:
        echo_json(plan.to_dict())
        return
    typer.echo(f"wrote {len(plan.q)} check poses to {out}"
               f"{f' and {program}' if program else ''}; O1 = "
               f"{plan.observability.get('O1', float('nan')):.4g}", err=True)
    for name, d in plan.directions.items():
        parts = [f"{d['kind']:6s}"]
        if d["at_limit"] is not None:
            parts.append(f"at the limit {d['at_limit']:.3g} {d['unit']}")
        if d["std"] is not None:
            parts.append(f"seen at {d['std']:.2g} {d['unit']} (1 sigma)")
        typer.echo(f"  {name:16s} " + ", ".join(parts))

