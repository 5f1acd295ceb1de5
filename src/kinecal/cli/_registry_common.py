"""Options and steps shared by the registry's commands (``registry``, ``check``,
``calibrate --register``, ``batch --db``): the ``--db`` option, the record options, and
registering a calibration result. No command is registered here."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinecal.errors import InputError

__all__ = ["date_option", "db_input", "db_option", "register_option", "register_result",
           "registering", "serial_argument"]


def db_option() -> Any:
    """The ``--db`` option: the registry (SQLite file or postgresql:// URL)."""
    import typer

    return typer.Option(None, "--db", help="The registry: an SQLite file, or a postgresql:// "
                        "URL (default: $KINECAL_DB, else kinecal.db in the working folder).")


def db_input(db: str | None) -> dict[str, str]:
    """``{"--db": path}`` of an SQLite registry, for `check_paths`'s inputs: an output on
    the registry file is refused (``{}`` for PostgreSQL)."""
    from kinecal.registry.location import locate

    loc = locate(db)
    return {loc.option: loc.target} if loc.backend == "sqlite" else {}


def register_option() -> Any:
    """``calibrate --register SERIAL``: the result recorded in the registry too."""
    import typer

    return typer.Option(None, "--register", metavar="SERIAL", help="Also record the result "
                        "for this robot in the registry (--db; docs/robot-life.md).")


def date_option(what: str) -> Any:
    """The ``--date`` option of a record."""
    import typer

    return typer.Option(None, "--date", help=f"When the {what} was made, ISO 8601 "
                        "(2026-11-28 or 2026-11-28T14:03:12+01:00; UTC without an offset; "
                        "default now, or SOURCE_DATE_EPOCH).")


def serial_argument() -> Any:
    """The SERIAL argument: a robot's serial number."""
    import typer

    return typer.Argument(..., metavar="SERIAL", help="The robot's serial number.")


def check_serial(serial: str) -> str:
    """A serial number: printable, at most 200 characters, no surrounding blanks."""
    text = serial.strip()
    if not text or len(text) > 200 or not text.isprintable():
        raise InputError(f"expected a serial number (1 to 200 printable characters), got "
                         f"{serial!r}", option="SERIAL")
    return text


def parse_date_option(value: str | None):
    """The ``--date`` value as a datetime (None when not given)."""
    if value is None:
        return None
    from kinecal.registry.location import parse_date

    return parse_date(value)


def register_result(serial: str, db: str | None, data: dict, where: str | Path, *,
                    model: str | None, base_link: str | None = None,
                    tip_link: str | None = None, report: Path | None = None,
                    inputs: dict[str, str | Path | None] | None = None,
                    record: tuple = (None, None, None), date: Any = None,
                    force_reason: str | None = None, current: bool = True,
                    on_duplicate: str = "refuse", command: str | None = None
                    ) -> tuple[dict, bool]:
    """Register a calibration result `data` (its file `where`) for `serial`; returns the
    stored event and whether it is new. `inputs`: argument name -> file, hashed into the
    record; `record`: instrument, operator, note."""
    from kinecal.registry.records import calibration_row, file_entry, model_source, result_subject
    from kinecal.registry.store import open_registry

    serial = check_serial(serial)
    subject = result_subject(data, where)
    source = model_source(model, data, base_link, tip_link) if subject == "arm" else None
    from kinecal.io.bundled import input_file

    found = {name: input_file(p) for name, p in (inputs or {}).items() if p is not None}
    entries = [file_entry(name, p) for name, p in found.items()
               if p is not None and Path(p).is_file()]
    if Path(where).is_file():
        entries.append(file_entry("RESULT", where))
    instrument, operator, note = record
    row = calibration_row(serial, data, where, source=source, report=report, inputs=entries,
                          date=date, operator=operator, instrument=instrument, note=note,
                          command=command, force_reason=force_reason)
    with open_registry(db) as reg:
        return reg.add_event(serial, row, current=subject if current else None,
                             reason=force_reason, on_duplicate=on_duplicate)


def registering(args: dict[str, Any], command: Any) -> None:
    """Run `command` (``calibrate``) with `args` but ``register``, writing its result to
    ``--out`` (or a temporary file), then register that result for ``args["register"]``
    in ``args["db"]``, with its inputs, report and record. The registry is opened for
    writing first: a read-only or unusable registry is refused before the calibration."""
    import tempfile

    from kinecal._files import read_json
    from kinecal.registry.store import open_registry

    serial = check_serial(args["register"])
    tips = args.get("tip_link")
    if not isinstance(tips, str | None):  # the repeatable --tip-link of robot systems
        from kinecal.cli.systems import is_system_arg

        if is_system_arg(args["model"], args.get("base_link"), list(tips)):
            raise InputError("the registry keeps one arm's calibrations: a robot system "
                             "(docs/systems.md) is not registered yet", option="--register")
        tips = tips[0] if tips else None
    open_registry(args.get("db")).close()
    line = command_text()
    with tempfile.TemporaryDirectory(prefix="kinecal-register-") as tmp:
        out = args.get("out") or Path(tmp) / "result.json"
        command(**{**args, "register": None, "db": None, "out": out})
        data = read_json(out)
        inputs: dict[str, str | Path | None] = {"MODEL": args.get("model")}
        for k, d in enumerate(args.get("data") or []):
            inputs[f"DATA {k + 1}"] = d
        for k, v in enumerate(args.get("validate") or []):
            inputs[f"--validate {k + 1}"] = v
        ev, _ = register_result(
            serial, args.get("db"), data, out if args.get("out") else "calibrate",
            model=args.get("model"), base_link=args.get("base_link"),
            tip_link=tips, report=args.get("report"), inputs=inputs,
            record=(args.get("instrument"), args.get("operator"), args.get("note")),
            command=line)
    import typer

    typer.echo(f"registered calibration {ev['id']} for {serial} ({ev['date']}): current",
               err=True)


def command_text() -> str | None:
    """The running command line, shell-quoted, a URL's password hidden (None outside the
    CLI)."""
    import shlex

    from kinecal.cli import _common
    from kinecal.registry.location import hide_password

    line = _common.COMMAND_LINE
    return None if line is None else shlex.join(hide_password(str(c)) for c in line)
