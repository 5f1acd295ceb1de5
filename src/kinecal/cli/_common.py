"""Helpers shared by the command modules: output, bundled data paths, the path checks; the
progress bars of `kinecal.cli._progress` (imported here for the command modules)."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinecal._files import atomic_open, check_input_file, probe_writable, written_in_place
from kinecal.cli._progress import progress, progress_columns, quiet_requested, status
from kinecal.errors import InputError

__all__ = [
    "check_paths",
    "echo_json",
    "progress",
    "progress_columns",
    "quiet_requested",
    "report_record",
    "resolve_data_path",
    "status",
    "to_jsonable",
    "warnings_scope",
    "with_warnings",
    "without_times",
    "write_json",
]


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays (nested in dicts/lists) to plain JSON types."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


#: keys of a result dictionary that hold the time a run took
TIME_KEYS = ("seconds", "seconds_mean", "elapsed")


def without_times(obj: Any) -> Any:
    """`obj` (a result dictionary) with every time a run took (`TIME_KEYS`) set to None
    when ``SOURCE_DATE_EPOCH`` is set (`kinecal._reproducible.reproducible`): two runs
    then print and write the same bytes. `obj` itself otherwise."""
    from kinecal._reproducible import reproducible

    if not reproducible():
        return obj

    def strip(o: Any) -> Any:
        if isinstance(o, dict):
            return {k: None if k in TIME_KEYS else strip(v) for k, v in o.items()}
        if isinstance(o, list | tuple):
            return [strip(v) for v in o]
        return o

    return strip(obj)


def echo_json(obj: Any) -> None:
    """Print `obj` as indented JSON on stdout (`without_times`)."""
    sys.stdout.write(json.dumps(to_jsonable(without_times(obj)), indent=2) + "\n")


def write_json(path: str | Path, obj: Any) -> None:
    """Write `obj` as indented JSON to `path` atomically (`without_times`), encoded piece
    by piece into the file rather than as one string."""
    with atomic_open(path, "w") as fh:
        json.dump(to_jsonable(without_times(obj)), fh, indent=2)
        fh.write("\n")


def resolve_data_path(spec: str, option: str = "DATA") -> Path:
    """Resolve a CSV argument: a path, or ``NAME:PART`` for a bundled measurement set."""
    from kinecal.datasets import bundled_csv  # local import: keeps CLI start-up light

    path = Path(spec)
    if path.is_dir():
        raise InputError(f"{spec} is a directory, expected a CSV file", option=option)
    check_input_file(path, "a CSV file")
    if path.exists():
        if not path.is_file():  # a pipe: the readers open a CSV more than once
            raise InputError(f"{spec} is a pipe, not a file: CSV inputs are read more than "
                             "once; save the data to a file first", option=option)
        return path
    if ":" in spec and not path.suffix:
        return bundled_csv(spec)
    raise InputError("file not found", file=spec, option=option)


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return a.samefile(b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def check_paths(
    inputs: dict[str, str | Path | None],
    outputs: dict[str, str | Path | None],
    folders: dict[str, tuple[str | Path | None, list[str]]] | None = None,
    reads: dict[str, Sequence[str]] | None = None,
) -> None:
    """Refuse, before any work, outputs that would overwrite an input or each other.

    Every command that writes files calls this first, before it reads or computes
    anything, with every path it reads and every path it will write. A command added
    later must do the same: it is how kinecal keeps its promise that an input is never
    overwritten (``kinecal calibrate m.yaml d.csv --out d.csv`` is exit 2, and ``d.csv``
    stays byte for byte as it was).

    Parameters
    ----------
    inputs : dict of str to path
        Argument or option name -> what it reads: a path, a bundled model or geometry
        name, or a bundled ``NAME:PART`` measurement set (these resolve to the files in
        the installed package, which are never written either). None: not given.
    outputs : dict of str to path
        Option name -> output file path (None: not requested).
    folders : dict of str to (path, list of str), optional
        Option name -> an output directory (created when missing) and the names of the
        files the command writes into it; each such file is checked like an output.
    reads : dict of str to sequence of str, optional
        Input name (a folder input) -> the suffixes of the files the command reads from
        that folder (``IMAGES_DIR`` -> ``.png``, ``.jpg``, ...), lower case.

    Raises
    ------
    InputError
        An output equal to an input or to another output (the same file under any
        name: symbolic links, ``./``, hard links), an output that is a directory or
        read-only, a file output whose folder does not exist or is not writable, a name
        longer than 255 bytes, or an output directory that is a file. A folder input
        protects the files in it: an output inside it (at any depth, through links too)
        that already exists, or one directly in it with a suffix of `reads` (the command,
        or its next run, would read it as an input), is refused as well. The check is
        cheap: the folder is never listed.
    """
    from kinecal.io.bundled import input_file

    ins = {}
    for name, spec in inputs.items():
        if spec is not None and (path := input_file(spec)) is not None:
            ins[name] = path
    outs: list[tuple[str, Path]] = [(k, Path(v)) for k, v in outputs.items() if v is not None]
    for opt, path in outs:
        _check_no_loop(opt, path)
    made: set[Path] = set()  # output folders: created by the command
    for opt, (folder, names) in (folders or {}).items():
        if folder is None:
            continue
        folder = Path(folder)
        _check_no_loop(opt, folder)
        if folder.exists() and not folder.is_dir():
            raise InputError(f"{folder} is a file, expected a directory", option=opt)
        made.add(folder.resolve())
        outs.extend((opt, folder / n) for n in names)
    in_dirs = {name: Path(os.path.realpath(p)) for name, p in ins.items() if p.is_dir()}
    seen: list[tuple[str, Path]] = []
    for opt, path in outs:
        if (raw := _given_as_folder(opt)) is not None:
            raise InputError(f"{raw} names a folder (it ends in {raw[-1]!r}): expected a file "
                             f"to write, such as {raw}NAME", option=opt)
        if written_in_place(path):  # /dev/stdout, /dev/null, a FIFO: no folder to check
            _check_not_input(opt, path, ins)
            seen.append((opt, path))
            continue
        if len(os.fsencode(path.name)) > 255:
            raise InputError(f"file name too long ({len(os.fsencode(path.name))} bytes, at "
                             "most 255)", option=opt)
        if path.is_dir():
            raise InputError(f"{path} is a directory, expected a file path", option=opt)
        if not path.parent.is_dir() and path.parent.resolve() not in made:
            if path.parent.exists():
                raise InputError(f"cannot write into {path.parent}: it is a file, not a "
                                 "folder", option=opt)
            raise InputError(f"folder {path.parent} does not exist", option=opt)
        folder = path.parent if path.parent.is_dir() else None
        if folder is not None and not os.access(folder, os.W_OK | os.X_OK):
            raise InputError(f"folder {folder} is not writable", option=opt)
        if path.is_file() and not os.access(path, os.W_OK):
            raise InputError(f"{path} is read-only; refusing to replace it", option=opt)
        _check_not_input(opt, path, ins)
        _check_in_folders(opt, path, in_dirs, reads or {})
        for other, prev in seen:
            if _same_file(path, prev):
                what = f"given to {other}" if other != opt else f"written by {opt} twice"
                raise InputError(f"{path} is also {what}: two outputs cannot share a path",
                                 option=opt)
        seen.append((opt, path))
    if seen:  # a malformed SOURCE_DATE_EPOCH is refused before any work, not at the end
        from kinecal._reproducible import source_date_epoch

        source_date_epoch()
    for opt, path in seen:  # last, after the cheap checks: a file is created and removed
        try:
            probe_writable(path)
        except InputError as exc:
            raise InputError(f"{path}: {exc.message}", option=opt) from None


def _check_no_loop(opt: str, path: Path) -> None:
    """Refuse a path through a loop of symbolic links (``ln -s loop loop``): every later
    look-up of it would fail."""
    try:
        os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"{path}: a loop of symbolic links (it points back to itself); "
                             "expected a folder or file path", option=opt) from None
    except ValueError:
        pass


def _check_not_input(opt: str, path: Path, ins: dict[str, Path]) -> None:
    for name, src in ins.items():
        if _same_file(path, src):
            raise InputError(f"{path} is also the input {name}: refusing to overwrite an "
                             "input, choose another output path", option=opt)


def _given_as_folder(option: str) -> str | None:
    """The value of `option` on the command line when it ends in a path separator (``--out
    d/``: typer hands the command ``Path("d")``, which would write a file named ``d``)."""
    args = COMMAND_LINE or []
    seps = tuple(s for s in (os.sep, os.altsep) if s)
    for i, arg in enumerate(args):
        value = None
        if arg == option and i + 1 < len(args):
            value = args[i + 1]
        elif arg.startswith(option + "="):
            value = arg[len(option) + 1:]
        if value and value.endswith(seps):
            return value
    return None


def _check_in_folders(opt: str, path: Path, in_dirs: dict[str, Path],
                      reads: dict[str, Sequence[str]]) -> None:
    """Refuse an output inside a folder input: an existing file there, or a file the
    command reads from that folder (by suffix). See `check_paths`."""
    if not in_dirs:
        return
    real = Path(os.path.realpath(path))  # the file a link points to, inside or not
    for name, folder in in_dirs.items():
        if folder != real.parent and folder not in real.parents:
            continue
        if os.path.lexists(path) or real.exists():
            raise InputError(f"{path} is a file inside the input folder {name} ({folder}): "
                             "refusing to overwrite a file in an input folder; write the "
                             "output outside it", option=opt)
        suffixes = {s.lower() for s in reads.get(name, ())}
        if real.parent == folder and real.suffix.lower() in suffixes:
            raise InputError(f"{path} would be a {real.suffix} file in the input folder {name} "
                             f"({folder}), which the command reads as input: write the output "
                             "outside it", option=opt)


#: the command line of the running command (set by `kinecal.cli.main`), for report records
COMMAND_LINE: list[str] | None = None


def report_record(report: str | Path | None, inputs: dict[str, str | Path | None],
                  instrument: str | None = None, operator: str | None = None,
                  note: str | None = None, suffixes: dict[str, Sequence[str]] | None = None
                  ) -> Any:
    """The record (`kinecal.report.provenance.Provenance`) of a command's ``--report``.

    Called after `check_paths`, before any work: refuses a ``.pdf`` report when the PDF
    renderer is missing and the record options without ``--report``, then hashes every
    input (`inputs`: argument name -> path, bundled name or ``NAME:PART``; a folder: its
    files with `suffixes`). None when no report is asked for.
    """
    if report is None:
        for opt, value in (("--instrument", instrument), ("--operator", operator),
                           ("--note", note)):
            if value is not None:
                raise InputError("applies to --report only (it is recorded in the report)",
                                 option=opt)
        return None
    from kinecal.io.bundled import input_file
    from kinecal.report.document import check_report_path
    from kinecal.report.provenance import collect

    check_report_path(report)
    files: dict[str, str | Path | None] = {}
    for name, spec in inputs.items():
        if spec is None:
            continue
        if Path(spec).exists():
            files[name] = spec
        elif (path := input_file(spec)) is not None:
            files[f"{name} ({spec}, bundled)"] = path
    return collect(files, command=COMMAND_LINE, instrument=instrument, operator=operator,
                   note=note, suffixes=suffixes)


@contextlib.contextmanager
def warnings_scope(strict: bool = False) -> Iterator[list]:
    """Collect a command's plausibility diagnostics and print them on stderr.

    Every `kinecal.diagnostics.warn` raised inside the block (readers, calibrations,
    checks) is collected once, in order; when the block ends, normally or by an error,
    each is printed as one ``kinecal: warning: MESSAGE [CODE]`` line on stderr (``--quiet``
    never silences them). Under `strict` the first warning raises `InputError` instead
    (exit status 2 before any output is written).

    Yields
    ------
    list of Diagnostic
        The diagnostics found so far; put them into JSON output with `with_warnings`.
    """
    from kinecal import diagnostics

    with diagnostics.collect() as found, diagnostics.strict(strict):
        try:
            yield found
        finally:
            for d in found:
                sys.stderr.write(diagnostics.format_warning(d) + "\n")


def with_warnings(obj: dict, found: list) -> dict:
    """`obj` with ``warnings: [{code, message}]``: its own and those in `found`, no repeats."""
    own = list(obj.get("warnings") or [])
    seen = {(w["code"], w["message"]) for w in own}
    for d in found:
        if (d.code, d.message) not in seen:
            own.append(d.to_dict())
            seen.add((d.code, d.message))
    return {**obj, "warnings": own}
