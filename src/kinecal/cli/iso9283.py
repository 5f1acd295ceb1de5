"""``kinecal iso9283``: ISO 9283 pose accuracy and repeatability (AP, RP) and distance
accuracy and repeatability (AD, RD) of repeated measurements (docs/iso9283.md)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import typer

from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    resolve_data_path,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    instrument_option,
    load_model_arg,
    note_option,
    operator_option,
    quiet_option,
    report_option,
    strict_option,
    tip_link_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError


def parse_pairs(text: str, labels: tuple[str, ...]) -> list[tuple[int, int]]:
    """``P1-P2,P2-P4`` -> index pairs; a label may itself contain ``-`` (the split that
    names two poses is taken)."""
    index = {label: i for i, label in enumerate(labels)}
    pairs = []
    for item in (t.strip() for t in text.split(",")):
        cuts = [(item[:k].strip(), item[k + 1:].strip()) for k, ch in enumerate(item)
                if ch == "-"]
        found = [(index[a], index[b]) for a, b in cuts if a in index and b in index]
        if len(found) != 1 or found[0][0] == found[0][1]:
            more = ", ..." if len(labels) > 8 else ""
            raise InputError(f"{item!r}: expected two different poses joined by '-' "
                             f"(poses: {', '.join(labels[:8])}{more})", option="--pairs")
        pairs.append(found[0])
    return pairs


def _report(res, path: Path, before, record, found: list) -> None:
    from kinecal.report.iso9283 import iso9283_report

    iso9283_report(res, path, before, provenance=record, warnings=found)


def _text(res: Any, before: Any) -> str:
    d = res.data
    u = d.length_unit
    p = res.poses
    lines = [f"ISO 9283: {len(d.labels)} poses x {d.n_cycles} cycles ({u})"]
    head = f"{'pose':>8s} {'AP':>10s} {'APx':>10s} {'APy':>10s} {'APz':>10s} {'RP':>10s}"
    if before is not None:
        head += f" {'AP nominal':>11s}"
    lines.append(head)
    for i, label in enumerate(d.labels):
        row = f"{label:>8.8s} " + " ".join(f"{float(p[k][i]):10.4g}"
                                           for k in ("AP", "APx", "APy", "APz", "RP"))
        if before is not None:
            row += f" {float(before.poses['AP'][i]):11.4g}"
        lines.append(row)
    if "RPa" in p:
        import math

        keys = [k for k in ("APa", "APb", "APc", "RPa", "RPb", "RPc") if k in p]
        lines.append(f"{'[deg]':>8s} " + " ".join(f"{k:>10s}" for k in keys))
        lines += [f"{label:>8.8s} " + " ".join(f"{math.degrees(float(p[k][i])):10.4g}"
                                               for k in keys)
                  for i, label in enumerate(d.labels)]
    if res.distances:
        lines.append(f"{'pair':>17s} {'D_c':>10s} {'AD':>10s} {'RD':>10s}")
        for (i, k), f in zip(res.pairs, res.distances, strict=True):
            pair = f"{d.labels[i]}-{d.labels[k]}"
            lines.append(f"{pair:>17.17s} {f['D_commanded']:10.6g} {f['AD']:10.4g} "
                         f"{f['RD']:10.4g}")
    return "\n".join(lines)


@app.command("iso9283")
def iso9283_cmd(
    meas: str = typer.Argument(..., help="CSV: pose, cycle, x, y, z [qw, qx, qy, qz] and the "
                               "commanded cx, cy, cz [cqw..cqz], or joints q1..qn with --model."),
    model: str | None = typer.Option(None, "--model", help=MODEL_HELP + " The commanded "
                                     "poses are its forward kinematics of the joint columns."),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    params: Path | None = typer.Option(None, "--params", help="Calibration result JSON "
                                       "(kinecal calibrate --out): commanded poses by the "
                                       "calibrated model, the nominal model's AP beside."),
    pairs: str | None = typer.Option(None, "--pairs", help="Pose pairs of the distance "
                                     "figures, e.g. P2-P4,P1-P3 (default: every pair)."),
    length_unit: str | None = typer.Option(None, "--length-unit", help="Unit of the file's "
                                           "positions without --model (a label; default mm)."),
    json_out: bool = typer.Option(False, "--json", help="Print the figures as JSON."),
    report: Path | None = report_option(),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    instrument: str | None = instrument_option(),
    operator: str | None = operator_option(),
    note: str | None = note_option(),
    angle_unit: str | None = angle_unit_option("the joint columns (with --model)"),
) -> None:
    """ISO 9283 pose accuracy AP, repeatability RP and distance figures AD, RD."""
    if check_angle_unit(angle_unit) and model is None:
        raise InputError("applies to joint columns, with --model", option="--angle-unit")
    check_paths({"MEAS": meas, "--model": model, "--params": params}, {"--report": report})
    record = report_record(report, {"MEAS": meas, "--model": model, "--params": params},
                           instrument, operator, note)
    if params is not None and model is None:
        raise InputError("needs --model (the model the result calibrated)", option="--params")
    if length_unit is not None and (model is not None or not length_unit.strip()):
        raise InputError("labels a file without --model (the model's unit applies)"
                         if model is not None else "expected a unit name such as mm",
                         option="--length-unit")
    from kinecal.io.repeatability import read_repeatability
    from kinecal.metrology.iso9283 import iso9283

    with warnings_scope(strict) as found:
        m = None if model is None else load_model_arg(model, base_link, tip_link)
        path = resolve_data_path(meas, "MEAS")
        data = read_repeatability(path, m, length_unit, angle_unit=angle_unit)
        before = None
        if params is not None:
            from kinecal.cli._serial_common import parameters_from_result
            from kinecal.io.result_values import model_for_result

            m = model_for_result(m, params)
            before = iso9283(data, [], check=False)
            T = m.fk(data.joints, parameters_from_result(m, params))
            data = dataclasses.replace(data, commanded=T[:, :3, 3],
                                       commanded_rotations=T[:, :3, :3])
        pair_list = None if pairs is None else parse_pairs(pairs, data.labels)
        res = iso9283(data, pair_list)
        result = res.to_dict()
        if before is not None:
            result["before"] = {"commanded": "nominal model", "poses": [
                {k: e[k] for k in ("pose", "AP", "APx", "APy", "APz") + tuple(
                    k for k in ("APa", "APb", "APc") if k in e)}
                for e in before.to_dict()["poses"]]}
        result = with_warnings({"file": str(path), **result}, found)
        write_outputs(report=report, write_report=lambda path: _report(
            res, path, before, record, list(found)), quiet=quiet or json_out)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(_text(res, before))
