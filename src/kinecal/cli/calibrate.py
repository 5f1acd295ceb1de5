"""Serial-arm commands ``calibrate`` and ``select-poses`` (the poses that identify the most);
``identifiability`` is in `kinecal.cli.identifiability`."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.calibration.method_options import check_error_model_options, check_method_options
from kinecal.cli import _calibrate_options as opt
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
    check_unit,
    instrument_option,
    load_model_arg,
    note_option,
    operator_option,
    quiet_option,
    report_option,
    seed_option,
    single_tip,
    strict_option,
    tip_links_option,
    tip_option,
    unit_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.cli._programs import (
    check_program_for,
    program_option,
    wait_option,
    write_program_for,
)
from kinecal.cli._registry_common import db_option, register_option
from kinecal.cli._serial_common import free_option
from kinecal.cli.calibrate_kinds import (
    calibrate_files,
    file_kind,
    parse_sigma,
)
from kinecal.cli.tracker_options import (
    check_tracker_options,
    orientation_format_option,
    station_per_file_option,
    validate_register_option,
)
from kinecal.errors import InputError


@app.command()
def calibrate(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    tip: str | None = tip_option(),
    data: list[str] = opt.DATA,
    method: str = opt.METHOD,
    validate: list[str] | None = opt.VALIDATE,
    free: str = opt.FREE,
    seed: int = seed_option("Random seed (metaheuristics; an integer >= 0)."),
    loss: str = opt.LOSS,
    maxiter: int | None = opt.MAXITER,
    target: float | None = opt.TARGET,
    box: str | None = opt.BOX,
    out: Path | None = opt.OUT,
    model_out: Path | None = opt.MODEL_OUT,
    report: Path | None = report_option(),
    json_out: bool = opt.JSON,
    unit: str = unit_option(),
    quiet: bool = quiet_option(),
    strict: bool = strict_option(),
    rotation_weight: float | None = opt.ROTATION_WEIGHT,
    error_model: str | None = opt.ERROR_MODEL,
    harmonics: int | None = opt.HARMONICS,
    folds: int | None = opt.FOLDS,
    sigma: list[str] | None = opt.SIGMA,
    prior: str | None = opt.PRIOR,
    prior_from: Path | None = opt.PRIOR_FROM,
    instrument: str | None = instrument_option(),
    operator: str | None = operator_option(),
    note: str | None = note_option(),
    images: Path | None = opt.IMAGES,
    board: list[str] | None = opt.BOARD,
    camera: list[str] | None = opt.CAMERA,
    intrinsics: Path | None = opt.INTRINSICS,
    setup: str = opt.SETUP,
    min_corners: int | None = opt.MIN_CORNERS,
    fixture: list[Path] | None = opt.FIXTURE,
    angle_unit: str | None = angle_unit_option("the data files' joint columns"),
    orientation_format: str | None = orientation_format_option(),
    station_per_file: bool = station_per_file_option(),
    validate_register: str | None = validate_register_option(),
    validate_images: Path | None = typer.Option(
        None, "--validate-images", help="With --images: folder of the --validate stations' "
        "images (default: the --images folder)."),
    register: str | None = register_option(),
    db: str | None = db_option(),
) -> None:
    """Calibrate a serial arm from measured tool positions (and orientations if given),
    or from board images with --images; a robot system from rows of its chains."""
    if register is not None:  # the calibration, then its record: kinecal.cli.registry
        args = dict(locals())
        from kinecal.cli._registry_common import registering

        return registering(args, calibrate)
    if db is not None:
        raise InputError("applies to --register only", option="--db")
    check_angle_unit(angle_unit)
    from kinecal.cli.systems import is_system_arg

    priors = {"prior": prior, "prior_from": prior_from}
    if (prior is not None or prior_from is not None) and (
            images is not None or is_system_arg(model, base_link, tip_link)):
        raise InputError("applies to a serial arm's measurement files (not to --images or "
                         "a robot system) yet", option="--prior")
    if images is not None:  # several cameras and boards, or images mixed: docs/rigs.md
        from kinecal.cli.calibrate_rig import calibrate_rig_cli, is_rig_call

        if is_rig_call(camera, board, data, is_system_arg(model, base_link, tip_link)):
            return calibrate_rig_cli({**locals(), "free": free_option(free)})
    elif camera:
        raise InputError("applies to --images only", option="--camera")
    from kinecal.cli.calibrate_rig import one_board

    board = one_board(board)
    if images is None and is_system_arg(model, base_link, tip_link):
        from kinecal.cli.systems import system_calibrate

        return system_calibrate({**locals(), "free": free_option(free),
                                 "unit": check_unit(unit)})
    if tip is not None:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    tip_link = single_tip(tip_link)
    if images is not None:  # the arm from camera images: its own module
        from kinecal.cli.calibrate_images import calibrate_images

        return calibrate_images(dict(locals()))
    for option, value in (("--board", board), ("--intrinsics", intrinsics),
                          ("--min-corners", min_corners), ("--validate-images", validate_images)):
        if value is not None:
            raise InputError("applies to --images only", option=option)
    from kinecal.calibration.serial.api import CALIBRATION_METHODS

    if method not in CALIBRATION_METHODS:
        raise InputError(f"unknown method {method!r}; expected one of "
                         f"{', '.join(CALIBRATION_METHODS)}", option="--method")
    shown = check_unit(unit)
    validate = validate or []
    check_tracker_options(orientation_format, validate_register, validate)
    tracker = {"orientation": orientation_format, "station_per_file": station_per_file,
               "register": validate_register}
    if station_per_file or len(data) > 1 or len(validate) > 1 or fixture or any(
            file_kind(f, o) != "tracker" for f, o in [(data[0], "DATA")]
            + [(v, "--validate") for v in validate]):
        return calibrate_files(
            model, data, base_link=base_link, tip_link=tip_link, validate=validate,
            method=method, free=free_option(free), seed=seed, loss=loss, maxiter=maxiter,
            target=target, out=out, model_out=model_out, report=report, json_out=json_out,
            quiet=quiet, strict=strict, rotation_weight=rotation_weight, sigma=sigma,
            extra_options={"--error-model": error_model, "--harmonics": harmonics,
                           "--folds": folds, "--box": box}, record=(instrument, operator, note),
            unit=shown, fixture=fixture, angle_unit=angle_unit, tracker=tracker,
            priors=priors)
    return _calibrate_tracker(SimpleNamespace(**locals()), shown)


def _calibrate_tracker(a: SimpleNamespace, shown: str | None) -> None:
    """``kinecal calibrate MODEL DATA.csv``: one tracker file (`a`: the command's
    arguments; `shown`: the summary's unit)."""
    from kinecal.calibration.diagnostics.noise import check_stated_sigma
    from kinecal.calibration.method_options import box_option
    from kinecal.calibration.serial.prior import prior_file
    from kinecal.cli._common import progress
    from kinecal.io.measurements import read_measurements

    data, validate = a.data[0], (a.validate[0] if a.validate else None)
    sigma = parse_sigma(a.sigma, [data])[0]
    check_paths({"MODEL": a.model, "DATA": data, "--validate": validate,
                 "--prior-from": a.prior_from, "--prior": prior_file(a.prior)},
                {"--out": a.out, "--model-out": a.model_out, "--report": a.report})
    record = report_record(a.report, {"MODEL": a.model, "DATA": data, "--validate": validate},
                           a.instrument, a.operator, a.note)
    if a.model_out is not None:
        from kinecal.io.models import check_model_file_name

        check_model_file_name(a.model_out, "--model-out")
    if a.maxiter is not None and a.maxiter < 1:
        raise InputError(f"expected a positive iteration budget, got {a.maxiter}",
                         option="--maxiter")
    check_finite(a.target, "--target")
    check_finite(a.rotation_weight, "--rotation-weight", positive=True)
    check_finite(sigma, "--sigma", positive=True)
    options = box_option(a.method, a.box)
    check_method_options(a.method, loss=a.loss, maxiter=a.maxiter, target=a.target)
    check_error_model_options(a.error_model, harmonics=a.harmonics, folds=a.folds)
    with warnings_scope(a.strict) as found:
        m = load_model_arg(a.model, a.base_link, a.tip_link)
        check_stated_sigma(m, sigma)  # not larger than the machine
        meas = read_measurements(resolve_data_path(data, "DATA"), m, a.orientation_format,
                                 angle_unit=a.angle_unit)
        if a.rotation_weight is not None and meas.rotations is None:
            raise InputError("applies to measured orientations (qw..qz columns) only",
                             option="--rotation-weight")
        val = None
        if validate is not None:
            val = read_measurements(resolve_data_path(validate, "--validate"), m,
                                    a.orientation_format, angle_unit=a.angle_unit)
        iterative = a.method not in ("lm",)
        with progress(f"calibrate {m.name} ({a.method})", a.maxiter if iterative else None,
                      a.quiet or a.json_out) as update:
            kw = dict(free=free_option(a.free), validate=val, rng=a.seed, loss=a.loss,
                      maxiter=a.maxiter, target=a.target, rotation_weight=a.rotation_weight,
                      sigma=sigma, validate_register=a.validate_register, options=options,
                      progress=(lambda it, best: update(1, best)) if iterative else None)
            if a.error_model is None and m.joint_errors is None and a.harmonics is None:
                from kinecal.calibration.serial.api import calibrate as run

                res = run(m, meas, a.method, **kw, **a.priors)
            elif a.prior is not None or a.prior_from is not None:
                raise InputError("not with joint-error models (--error-model, a model's "
                                 "joint_errors) yet", option="--prior")
            else:
                from kinecal.calibration.serial.error_model import calibrate_error_model

                res = calibrate_error_model(m, meas, a.error_model or "model", method=a.method,
                                            harmonics=a.harmonics, **kw,
                                            **({} if a.folds is None else {"folds": a.folds}))
        res.warnings = list(found)  # the readers' warnings as well as the calibration's
        result = (with_warnings(res.to_dict(), found) if a.out is not None or a.json_out
                  else None)
        write_outputs(out=a.out, result=result, model_out=a.model_out,
                      save_model=res.save_model, report=a.report,
                      write_report=lambda path: _report(res, path, record, val),
                      quiet=a.quiet or a.json_out)
    if a.json_out:
        echo_json(result)
    elif not a.quiet:
        typer.echo(res.summary(shown))


def _report(res, path: Path, record, validation) -> None:
    from kinecal.report.html import calibration_report

    calibration_report(res, path, provenance=record, validation=validation)


@app.command("select-poses")
def select_poses_cmd(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    tip: list[str] | None = typer.Option(None, "--tip", help="Robot system: the chains to "
                                         "plan rows of (repeatable; default every tip)."),
    count: int = typer.Option(..., "--count", help="Number of poses to select."),
    candidates: int | None = typer.Option(
        None, "--candidates", help="Random candidate poses (default 2000; gauge kinds: per "
        "pivot, point or plane, default 100)."),
    seed: int = seed_option("Random seed for the candidates (an integer >= 0)."),
    out: Path = typer.Option(..., "--out", help="CSV of the selected q1..qn."),
    kind: str = typer.Option("tracker", "--kind", help="tracker, or a gauge kind: ballbar, "
                             "pair, point, plane (--count per pivot, point or plane; pairs "
                             "in all; --candidates per gauge, default 100)."),
    gauge: list[str] | None = typer.Option(
        None, "--gauge", help="Gauge kinds: a pivot or point X,Y,Z, or a plane "
        "X,Y,Z,NX,NY,NZ (repeatable; default reachable ones)."),
    length: float | None = typer.Option(None, "--length", help="Ballbar or bar length."),
    angle_unit: str | None = angle_unit_option("the plan's joint columns"),
    program: Path | None = program_option(),
    wait: float = wait_option(),
) -> None:
    """Choose calibration poses maximising observability (O1, D-optimal); for a gauge kind
    the rows of its file (docs/measurement-kinds.md); for a robot system, which chain in
    which configuration (docs/systems.md)."""
    check_angle_unit(angle_unit)
    from kinecal.cli.systems import is_system_arg

    if is_system_arg(model, base_link, tip_link):
        if program is not None:
            raise InputError("writes one arm's program; a robot system's plan has rows of "
                             "several chains", option="--program")
        from kinecal.cli.systems import system_select

        return system_select(dict(locals()))
    if tip:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    tip_link = single_tip(tip_link)
    if kind != "tracker":
        from kinecal.cli.calibrate_kinds import select_kind_file

        return select_kind_file(model, kind, count=count, candidates=candidates, seed=seed,
                                out=out, gauge=gauge, length=length, base_link=base_link,
                                tip_link=tip_link, angle_unit=angle_unit,
                                program=(program, wait))
    for option, value in (("--gauge", gauge), ("--length", length)):
        if value:
            raise InputError("applies to the gauge kinds (--kind ballbar, pair, point, plane)",
                             option=option)
    candidates = 2000 if candidates is None else candidates
    from kinecal.calibration.serial.pose_selection import candidate_measurements, select_poses
    from kinecal.calibration.serial.problem import resolve_free
    from kinecal.calibration.serial.simulate import random_configurations
    from kinecal.io.csvtable import write_table

    check_paths({"MODEL": model}, {"--out": out, "--program": program})
    m = load_model_arg(model, base_link, tip_link)
    check_program_for(program, m, wait)
    check_count(candidates, "--candidates", bytes_per_item=128 * m.n_params, what="candidates")
    q = random_configurations(m, candidates, np.random.default_rng(seed))
    ident, _ = resolve_free(m, candidate_measurements(m, q), "identifiable", tol=1e-4)
    idx, obs = select_poses(m, q, count, free=ident)
    scale = 1.0 / m.joint_scale(angle_unit)  # to the file's units per joint column
    from kinecal._files import all_or_nothing

    with all_or_nothing():  # the plan and its program both, or neither
        write_table(out, {f"q{i + 1}": q[idx, i] * scale[i] for i in range(m.n_joints)})
        if program is not None:
            write_program_for(program, m, q[idx], wait, f"kinecal select-poses {m.name}: "
                              "calibration poses")
    also = f" and {program}" if program else ""
    typer.echo(f"wrote {count} poses to {out}{also}; O1 = {obs['O1']:.4g}, O2 = {obs['O2']:.4g} "
               f"({len(ident)} identifiable parameters)", err=True)
