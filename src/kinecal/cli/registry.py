"""``kinecal registry``: a record per robot serial number (docs/robot-life.md).

``add``, ``list``, ``show``, ``history``, ``set-current``, ``retract``, ``export``,
``report --fleet``, ``verify``; the store, its checks and its history are
`kinecal.registry`'s.
"""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, echo_json
from kinecal.cli._options import base_link_option, choices, tip_link_option
from kinecal.cli._registry_common import (
    check_serial,
    command_text,
    date_option,
    db_input,
    db_option,
    parse_date_option,
    register_result,
    serial_argument,
)
from kinecal.errors import InputError

registry_app = typer.Typer(help="A record per robot serial number: calibrations, checks, "
                           "drift, fleets (docs/robot-life.md).", no_args_is_help=True,
                           add_completion=False, rich_markup_mode=None)
app.add_typer(registry_app, name="registry")

#: what ``registry export`` writes (``kinecal export``'s formats)
EXPORT_FORMATS = ("ur-kinematics", "urdf", "yaml", "ros-tf")


def _open(db: str | None, write: bool = False):
    from kinecal.registry.store import open_registry

    return open_registry(db, write=write)


@registry_app.command("add")
def add(
    serial: str = serial_argument(),
    result: Path = typer.Argument(..., metavar="RESULT.json", help="A calibration result "
                                  "(kinecal calibrate --out, or handeye --out)."),
    report: Path | None = typer.Option(None, "--report", help="The calibration's report, "
                                       "kept with it."),
    model: str | None = typer.Option(None, "--model", help="The model it was calibrated from "
                                     "(default: the bundled model the result names)."),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    data: list[Path] | None = typer.Option(None, "--data", help="An input of the calibration "
                                           "(measurements), hashed into the record "
                                           "(repeatable)."),
    date: str | None = date_option("calibration"),
    operator: str | None = typer.Option(None, "--operator", help="Who calibrated."),
    instrument: str | None = typer.Option(None, "--instrument", help="The instrument used."),
    note: str | None = typer.Option(None, "--note", help="Free text (site, job, reason)."),
    current: bool = typer.Option(True, "--current/--no-current", help="Make it the current "
                                 "calibration (default) or only record it."),
    force: bool = typer.Option(False, "--force", help="Record a result that is registered "
                               "already, once more (needs --reason)."),
    reason: str | None = typer.Option(None, "--reason", help="Why (with --force)."),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the record as JSON."),
) -> None:
    """Register a calibration result for a robot (it becomes current)."""
    from kinecal._files import read_json

    serial = check_serial(serial)
    if force != (reason is not None and bool(reason.strip())):
        raise InputError("--force records a result once more and needs --reason TEXT (and "
                         "--reason applies to --force only)", option="--force")
    for path, option in [(result, "RESULT"), (report, "--report"), *[(d, "--data")
                                                                      for d in data or []]]:
        if path is not None and not path.is_file():
            raise InputError("file not found", file=path, option=option)
    payload = read_json(result)
    ev, _ = register_result(serial, db, payload, result, model=model, base_link=base_link,
                            tip_link=tip_link, report=report,
                            inputs={f"--data {d}": d for d in data or []},
                            record=(instrument, operator, note),
                            date=parse_date_option(date), force_reason=reason if force
                            else None, current=current, command=command_text())
    _say_added(serial, ev, current, json_out)


def _say_added(serial: str, ev: dict, current: bool, json_out: bool) -> None:
    if json_out:
        echo_json({"serial": serial, "id": ev["id"], "kind": ev["kind"],
                   "subject": ev["subject"], "date": ev["date"], "current": current,
                   "summary": ev["summary"]})
        return
    what = f"{ev['subject']} calibration" if ev["subject"] != "arm" else "calibration"
    model = f" of {ev['model_name']}" if ev.get("model_name") else ""
    typer.echo(f"registered {what} {ev['id']}{model} for {serial} ({ev['date']})"
               f"{': current' if current else ''}", err=True)


@registry_app.command("list")
def list_cmd(
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """Every robot: model, calibrations, checks, current calibration, last check."""
    with _open(db) as reg:
        rows = reg.robots()
    if json_out:
        echo_json({"robots": [{k: v for k, v in r.items() if k != "deviations"}
                              for r in rows]})
        return
    if not rows:
        typer.echo("the registry has no robot yet", err=True)
        return
    typer.echo(f"{'serial':24s} {'model':12s} {'cal.':>4s} {'checks':>6s} "
               f"{'current (id, date)':32s} last check")
    for r in rows:
        cur = f"{r['current']['id']}  {r['current']['date']}" if r["current"] else "-"
        last = r["last_check"]
        last_text = f"{last['date']} {last['verdict']}" if last else "-"
        typer.echo(f"{r['serial']:24s} {r['model'] or '-':12s} {r['calibrations']:>4d} "
                   f"{r['checks']:>6d} {cur:32s} {last_text}")


@registry_app.command("show")
def show(
    serial: str = serial_argument(),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """A robot's record: current calibration, counts, last check, corrections."""
    from kinecal.registry.views import show_text, show_view

    serial = check_serial(serial)
    with _open(db) as reg:
        view = show_view(reg, serial)
    if json_out:
        echo_json(view)
    else:
        typer.echo(show_text(view))


@registry_app.command("history")
def history(
    serial: str = serial_argument(),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the history as JSON."),
    plot: Path | None = typer.Option(None, "--plot", help="Figure of the checks on a time "
                                     "axis (.png, .svg, .pdf)."),
    report: Path | None = typer.Option(None, "--report", help="HTML report of the history."),
    retracted: bool = typer.Option(False, "--retracted", help="Show retracted records too "
                                   "(marked)."),
) -> None:
    """Calibrations and checks in time order, the drift rate per parameter direction and
    the projected date of crossing the limit."""
    from kinecal.registry.drift import drift_summary

    serial = check_serial(serial)
    check_paths(db_input(db), {"--plot": plot, "--report": report})
    with _open(db) as reg:
        hist = reg.history(serial, retracted=retracted)
    drift = drift_summary(hist)
    from kinecal._files import all_or_nothing

    with all_or_nothing():  # the figure and the report both, or neither
        if plot is not None:
            from kinecal.registry.figures import history_figure

            history_figure(hist, drift, plot)
        if report is not None:
            from kinecal.registry.reports import history_report

            history_report(hist, drift, report)
    if json_out:
        echo_json({**hist, "drift": drift})
        return
    from kinecal.registry.views import history_text

    typer.echo(history_text(hist, drift))


@registry_app.command("set-current")
def set_current(
    serial: str = serial_argument(),
    event_id: int = typer.Argument(..., metavar="ID", help="The calibration's id (registry "
                                   "history SERIAL)."),
    reason: str | None = typer.Option(None, "--reason", help="Why (recorded)."),
    operator: str | None = typer.Option(None, "--operator", help="Who."),
    db: str | None = db_option(),
) -> None:
    """Make another of a robot's calibrations current (recorded; nothing is overwritten)."""
    serial = check_serial(serial)
    with _open(db, write=True) as reg:
        ev = reg.set_current(serial, event_id, reason=reason, operator=operator)
    typer.echo(f"calibration {ev['id']} ({ev['date']}) is {serial}'s current "
               f"{ev['subject']} calibration", err=True)


@registry_app.command("retract")
def retract(
    serial: str = serial_argument(),
    event_id: int = typer.Argument(..., metavar="ID", help="The record's id."),
    reason: str = typer.Option(..., "--reason", help="Why (recorded; required)."),
    force: bool = typer.Option(False, "--force", help="Required: a retraction takes a record "
                               "out of the history (it is kept, with the reason)."),
    operator: str | None = typer.Option(None, "--operator", help="Who."),
    db: str | None = db_option(),
) -> None:
    """Take a wrong record out of a robot's history, with the reason (kept, not deleted)."""
    serial = check_serial(serial)
    if not force:
        raise InputError("a retraction takes a record out of the history: give --force (and "
                         "--reason)", option="--force")
    with _open(db, write=True) as reg:
        ev = reg.retract(serial, event_id, reason=reason, operator=operator)
    typer.echo(f"{ev['kind']} {ev['id']} of {serial} ({ev['date']}) retracted: {reason}",
               err=True)


@registry_app.command("export")
def export(
    serial: str = serial_argument(),
    fmt: str = typer.Option(..., "--format", metavar=choices(*EXPORT_FORMATS),
                            help="As kinecal export: ur_description's kinematics, URDF, a "
                            "model file, or (a hand-eye calibration) a ROS static transform."),
    out: Path = typer.Option(..., "--out", help="File to write."),
    calibration: int | None = typer.Option(None, "--calibration", help="Another calibration "
                                           "than the current one (its id)."),
    db: str | None = db_option(),
) -> None:
    """Write a robot's current calibration in another tool's format."""
    serial = check_serial(serial)
    if fmt not in EXPORT_FORMATS:
        raise InputError(f"unknown format {fmt!r}; expected one of "
                         f"{', '.join(EXPORT_FORMATS)}", option="--format")
    check_paths(db_input(db), {"--out": out})
    with _open(db) as reg:
        subject = "handeye" if fmt == "ros-tf" else "arm"
        ev = reg.current(serial, subject) if calibration is None else reg.event(
            calibration, full=True)
        if ev is None or ev["kind"] != "calibration" or ev["subject"] != subject:
            raise InputError(f"{serial} has no {subject} calibration {calibration}",
                             option="--calibration")
    from kinecal.cli._registry_export import export_event

    export_event(ev, fmt, out, f"calibration {ev['id']} of {serial} ({ev['date']})")


@registry_app.command("report")
def report_cmd(
    fleet: Path = typer.Option(..., "--fleet", help="HTML report of every robot: last "
                               "calibration, last check and verdict, worst drifters first."),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Also print the table as JSON."),
) -> None:
    """The fleet: every robot with its last calibration and check, worst drifters first."""
    from kinecal.registry.fleet_view import fleet_rows
    from kinecal.registry.reports import fleet_report

    check_paths(db_input(db), {"--fleet": fleet})
    with _open(db) as reg:
        rows = fleet_rows(reg.robots())
    fleet_report(rows, fleet, where=reg.location.shown)
    if json_out:
        echo_json({"robots": rows})
    typer.echo(f"wrote {fleet} ({len(rows)} robots)", err=True)


@registry_app.command("verify")
def verify(db: str | None = db_option()) -> None:
    """Check the registry's integrity (SQLite's integrity check, the records' keys and
    links); exit 0 when sound."""
    from kinecal.registry.verify import verify_registry

    with _open(db) as reg:
        problems, counts = verify_registry(reg)
    text = ", ".join(f"{n} {k}" for k, n in counts.items())
    if problems:
        for p in problems:
            typer.echo(f"kinecal: error: {p}", err=True)
        raise typer.Exit(1)
    typer.echo(f"{reg.location.shown}: sound ({text})")


@registry_app.command("check-fleet")
def check_fleet_cmd(
    checks: Path = typer.Argument(..., metavar="CHECKS.csv", help="One row per robot: serial, "
                                  "data (files joined by ';', relative to CHECKS.csv), "
                                  "optional date and sigma."),
    executor: str = typer.Option("local", "--executor", metavar="[local|dask]",
                                 help="A local process pool or a Dask cluster."),
    scheduler: str | None = typer.Option(None, "--scheduler", help="Dask scheduler address "
                                         "(tcp://host:port; default a local cluster)."),
    workers: int | None = typer.Option(None, "--workers", help="Worker processes (a local "
                                       "pool or a local Dask cluster)."),
    limit: float | None = typer.Option(None, "--limit", help="As kinecal check --limit."),
    alpha: float = typer.Option(1e-4, "--alpha", help="As kinecal check --alpha."),
    db: str | None = db_option(),
    json_out: bool = typer.Option(False, "--json", help="Print every robot's outcome."),
) -> None:
    """Check many robots at once (one transaction per robot; a PostgreSQL registry for a
    fleet): counts per verdict; exit 0 when every check was recorded, 1 otherwise."""
    import contextlib
    import dataclasses

    from kinecal.batch.executors import dask_executor, local_executor
    from kinecal.registry.fleet import check_fleet
    from kinecal.registry.location import locate
    from kinecal.registry.store import open_registry

    if executor not in ("local", "dask"):
        raise InputError(f"expected local or dask, got {executor!r}", option="--executor")
    if scheduler is not None and executor != "dask":
        raise InputError("--scheduler needs --executor dask", option="--scheduler")
    items = _fleet_list(checks, limit, alpha)
    target = locate(db).target
    open_registry(target).close()  # refused here, before any worker starts
    with contextlib.ExitStack() as stack:
        ex = stack.enter_context(dask_executor(scheduler, workers) if executor == "dask"
                                 else local_executor(workers))
        outcomes = check_fleet(target, items, executor=ex)
    counts: dict[str, int] = {}
    for o in outcomes:
        key = o.verdict or "failed"
        counts[key] = counts.get(key, 0) + 1
    if json_out:
        echo_json({"outcomes": [dataclasses.asdict(o) for o in outcomes], "counts": counts})
    for o in outcomes:
        if o.error:
            typer.echo(f"kinecal: error: {o.serial}: {o.error}", err=True)
    typer.echo(f"{len(outcomes)} robots: " + ", ".join(f"{n} {k}" for k, n in
                                                      sorted(counts.items())), err=True)
    if "failed" in counts:
        raise typer.Exit(1)


def _fleet_list(path: Path, limit: float | None, alpha: float) -> list:
    """The rows of CHECKS.csv as `kinecal.registry.fleet.FleetCheck`."""
    import csv

    from kinecal.registry.fleet import FleetCheck
    from kinecal.registry.location import parse_date

    if not path.is_file():
        raise InputError("file not found", file=path)
    items = []
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    for k, row in enumerate(rows, 1):
        if not row.get("serial") or not row.get("data"):
            raise InputError("expected columns serial and data", file=path, row=k)
        files = [path.parent / f.strip() for f in row["data"].split(";") if f.strip()]
        for f in files:
            if not f.is_file():
                raise InputError(f"data file {f} not found", file=path, row=k)
        sigma = row.get("sigma") or None
        try:
            sigma = None if sigma is None else float(sigma)
        except ValueError:
            raise InputError(f"sigma {sigma!r} is not a number", file=path, row=k) from None
        items.append(FleetCheck(
            check_serial(row["serial"]), tuple(str(f) for f in files),
            date=parse_date(row["date"], "date") if row.get("date") else None,
            sigma=None if sigma is None else (sigma,) * len(files), limit=limit,
            alpha=alpha))
    return items
